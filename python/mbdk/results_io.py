"""A scene run's samples and manifest in a file, and back: .npz (numpy), .csv (the manifest in
the leading comment lines) or .h5 / .hdf5 (h5py, where it is installed).

>>> import mbdk.results_io
>>> r = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-3, t_end=10)
>>> mbdk.results_io.save_result(r, "run.npz")     # doctest: +ELLIPSIS
PosixPath('run.npz')
>>> r2 = mbdk.results_io.load_result("run.npz")    # a SceneResult again: r2.t, r2.q, ...
>>> bool((r2.q == r.q).all()), r2.manifest["method"]
(True, 'rk4')

What is written: t; the coordinates q and the velocities v (of a spatial body the centre's
velocity and the body-frame angular velocity) with their column names; where the run computed
them, the accelerations, the multipliers, the joints' reactions, the energy and its parts, the
work W of dampers, loads and drivers as the run integrated it at every step (not a quadrature
over the samples), the energy balance E - E0 - W, the residuals (residual_names says which),
the wear elements' volumes, each contact's penetration, its rate, normal and friction force,
and the Newton iterations per sample; the status, the statistics,
the names of bodies, joints and wear elements, and the manifest (version, method,
formulation, step or tolerances, compiler flags). load_result gives back the SceneResult. A file is written under a temporary name beside the target and renamed
when complete, so a failed or interrupted write leaves no partial file with the target's name.
"""
from __future__ import annotations

import csv
import json
import os
import zipfile
from dataclasses import asdict
from pathlib import Path

import numpy as np

from .errors import InvalidInputError, Status, status_message
from .result import CONTACT_FIELDS, SceneResult, Stats

FORMATS = {".npz": "npz", ".csv": "csv", ".h5": "h5", ".hdf5": "h5"}
#: the CSV columns of SceneResult.residuals, by SceneResult.residual_names
_RESIDUAL_COLUMNS = {"position": "residual_position", "velocity": "residual_velocity",
                     "acceleration": "residual_acceleration", "quaternion_norm": "quaternion_norm"}
#: a reaction's three columns (Fx, Fy and the moment on the joint's body1)
_REACTION = ("Fx", "Fy", "M")


def _format(path: Path) -> str:
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise InvalidInputError(f"{path}: unknown result format {path.suffix!r}; give a file "
                                f"ending in {', '.join(FORMATS)}")
    return fmt


def check_writable(path, suffixes: tuple | None = None) -> Path:
    """The output path, checked before a run: a known format (a result file's, or one of
    suffixes: an animation's page), and a folder that exists and can be written (named errors
    otherwise)."""
    path = Path(path)
    if suffixes is None:
        fmt = _format(path)
    elif path.suffix.lower() in suffixes:
        fmt = path.suffix.lower()
    else:
        raise InvalidInputError(f"{path}: give a file ending in {', '.join(suffixes)}")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InvalidInputError(f"{path}: the folder {str(folder)!r} does not exist")
    if not os.access(folder, os.W_OK):
        raise InvalidInputError(f"{path}: the folder {str(folder)!r} cannot be written")
    if path.is_dir():
        raise InvalidInputError(f"{path}: is a folder; give a file name")
    if fmt == "h5":
        _h5py()
    return path


def _h5py():
    try:
        # h5py is optional: only .h5 results need it
        import h5py
    except ImportError:
        raise InvalidInputError("HDF5 results need h5py: pip install h5py (or write .npz or "
                                ".csv)") from None
    return h5py


def _array(x):
    return None if x is None else np.asarray(x)


def result_arrays(r) -> dict:
    """The arrays save_result writes, one row per sample (None where the run did not compute
    them), and "meta": what else rebuilds the result (names, kind, status, statistics)."""
    parts = dict(r.energy_parts or {})
    balance = None
    if r.energy is not None and "work" in parts:
        balance = r.energy_balance()
    wear_names = list(r.wear)
    contact_names = list(r.contacts)
    meta = {"status": r.status.name, "message": r.message, "kind": r.kind,
            "rotation": r.rotation, "rotations": r.rotations, "bodies": list(r.bodies),
            "joints": list(r.joints), "q_names": r.q_names, "velocity_names": r.v_names,
            "wear_names": wear_names, "contact_names": contact_names,
            "energy_part_names": list(parts),
            "residual_names": [_RESIDUAL_COLUMNS[n] for n in r.residual_names],
            "stats": asdict(r.stats), "drift": r.drift, "assembly": r.assembly,
            "visits": r.visits}
    arrays = {"t": np.asarray(r.t), "q": np.asarray(r.q), "velocities": np.asarray(r.v),
              "accelerations": _array(r.a), "multipliers": _array(r.multipliers),
              "reactions": _array(r.reactions), "energy": _array(r.energy),
              "energy_balance": balance, "residuals": _array(r.residuals),
              "iterations": _array(r.iterations),
              "wear": (np.column_stack([np.asarray(r.wear[k]) for k in wear_names])
                       if wear_names else None),
              # CONTACT_FIELDS' four columns per contact, in the contacts' order
              "contacts": (np.column_stack([np.asarray(r.contacts[k][f]) for k in contact_names
                                            for f in CONTACT_FIELDS])
                           if contact_names else None)}
    for k, v in parts.items():
        arrays[f"energy_{k}"] = np.asarray(v)
    arrays["work"] = arrays.get("energy_work")
    arrays.pop("energy_work", None)
    return {"arrays": {k: v for k, v in arrays.items() if v is not None}, "meta": meta,
            "manifest": r.manifest}


def write_atomic(path: Path, write) -> None:
    """write(tmp) to a temporary name beside path, then the rename: whatever stops the write
    (a full disk, Ctrl-C) removes the temporary file and leaves no file named path. An OSError
    is raised again naming path, not the temporary name."""
    tmp = path.with_name(f".{path.name}.part")
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass
        if isinstance(exc, OSError) and exc.errno is not None:
            raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc
        raise


def _csv_columns(arrays: dict, meta: dict) -> tuple[list, list]:
    """(column names, blocks of columns) of the CSV layout: t, q, v, then every output with
    a prefix that names it (a:, reaction:, energy:, wear:) so that the reader can sort them."""
    cols, blocks = ["t"], [arrays["t"][:, None]]
    cols += meta["q_names"] + meta["velocity_names"]
    blocks += [arrays["q"], arrays["velocities"]]
    named = {"accelerations": [f"a:{n}" for n in meta["velocity_names"]],
             "residuals": meta["residual_names"],
             "wear": [f"wear:{n}" for n in meta["wear_names"]],
             "contacts": [f"contact:{n}.{f}" for n in meta["contact_names"]
                          for f in CONTACT_FIELDS]}
    for name, a in arrays.items():
        if name in ("t", "q", "velocities") or a.size == 0 and a.ndim > 1:
            continue
        if name == "reactions":
            cols += [f"reaction:{j}.{c}" for j in meta["joints"] for c in _REACTION]
            blocks.append(a.reshape(len(a), -1))
        elif name == "multipliers":
            cols += [f"lambda{k + 1}" for k in range(a.shape[1])]
            blocks.append(a)
        elif a.ndim == 2:
            cols += named[name][:a.shape[1]]
            blocks.append(a)
        else:
            cols.append(name)
            blocks.append(a[:, None].astype(float))
    return cols, blocks


def save_result(r, path) -> Path:
    """Writes the run r (a SceneResult) to path, by its suffix: every output it has (q, v, a,
    the multipliers, the joints' reactions, the energy and its parts, W, the balance, the
    residuals, the wear volumes, the Newton iterations), its statistics, status and manifest."""
    path = check_writable(path)
    a = result_arrays(r)
    arrays, meta = a["arrays"], a["meta"]
    manifest = json.dumps(a["manifest"], default=str)
    meta_text = json.dumps(meta, default=str)
    fmt = _format(path)
    if fmt == "npz":
        def write(tmp):
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays, q_names=np.array(meta["q_names"]),
                         velocity_names=np.array(meta["velocity_names"]),
                         status=np.array(meta["status"]), manifest=np.array(manifest),
                         meta=np.array(meta_text))
    elif fmt == "h5":
        h5py = _h5py()

        def write(tmp):
            with h5py.File(tmp, "w") as fh:
                for k, v in arrays.items():
                    fh.create_dataset(k, data=v)
                fh.attrs["q_names"] = json.dumps(meta["q_names"])
                fh.attrs["velocity_names"] = json.dumps(meta["velocity_names"])
                fh.attrs["status"] = meta["status"]
                fh.attrs["manifest"] = manifest
                fh.attrs["meta"] = meta_text
    else:
        def write(tmp):
            cols, blocks = _csv_columns(arrays, meta)
            data = np.hstack(blocks)
            with open(tmp, "w", newline="") as fh:
                fh.write(f"# status: {meta['status']}\n# manifest: {manifest}\n"
                         f"# meta: {meta_text}\n"
                         f"# columns: t, {len(meta['q_names'])} coordinates, "
                         f"{len(meta['velocity_names'])} velocities, then the outputs\n")
                w = csv.writer(fh)
                w.writerow(cols)
                for row in data:
                    w.writerow([repr(float(x)) for x in row])
    write_atomic(path, write)
    return path


def _read_csv(path: Path) -> tuple[dict, dict]:
    """(arrays, header) of a CSV result: the header lines by key (status, manifest, meta,
    columns), the columns sorted back into save_result's arrays by their names."""
    header = {}
    with open(path, newline="") as fh:
        pos = fh.tell()
        line = fh.readline()
        while line.startswith("# "):
            key, _, value = line[2:].partition(": ")
            header[key] = value.strip()
            pos = fh.tell()
            line = fh.readline()
        fh.seek(pos)
        rows = list(csv.reader(fh))
    layout = header["columns"].split()
    nq, nv = int(layout[1]), int(layout[3])
    cols, data = rows[0], np.array(rows[1:], dtype=float).reshape(-1, len(rows[0]))
    arrays = {"t": data[:, 0], "q": data[:, 1:1 + nq], "velocities": data[:, 1 + nq:1 + nq + nv]}
    header["q_names"], header["velocity_names"] = cols[1:1 + nq], cols[1 + nq:1 + nq + nv]
    groups: dict = {}
    for k, c in enumerate(cols[1 + nq + nv:], start=1 + nq + nv):
        if c.startswith("a:"):
            groups.setdefault("accelerations", []).append(data[:, k])
        elif c.startswith("reaction:"):
            groups.setdefault("reactions", []).append(data[:, k])
        elif c.startswith("wear:"):
            groups.setdefault("wear", []).append(data[:, k])
        elif c.startswith("contact:"):
            groups.setdefault("contacts", []).append(data[:, k])
        elif c.startswith("lambda"):
            groups.setdefault("multipliers", []).append(data[:, k])
        elif c in _RESIDUAL_COLUMNS.values():
            groups.setdefault("residuals", []).append(data[:, k])
        else:
            arrays[c] = data[:, k]
    for name, columns in groups.items():
        arrays[name] = np.stack(columns, axis=1)
    if "reactions" in arrays:
        arrays["reactions"] = arrays["reactions"].reshape(len(data), -1, 3)
    if "iterations" in arrays:
        arrays["iterations"] = arrays["iterations"].astype(int)
    return arrays, header


def load_result(path) -> SceneResult:
    """The run save_result wrote, as the SceneResult a run returns (a file written before the
    result files held their metadata gives what it has: its outputs, status and manifest)."""
    path = Path(path)
    fmt = _format(path)
    if not path.is_file():
        raise InvalidInputError(f"{path}: no such result file")
    if path.stat().st_size == 0:
        raise _not_a_result(path, "an empty file")
    try:
        if fmt == "npz":
            if not zipfile.is_zipfile(path):
                raise _not_a_result(path, "not a zip archive, or a truncated one")
            with np.load(path, allow_pickle=False) as z:
                missing = [k for k in _REQUIRED if k not in z.files]
                if missing:
                    raise _not_a_result(path, f"no {missing[0]!r} array; it holds "
                                        f"{', '.join(z.files) or 'nothing'}")
                arrays = {k: z[k] for k in z.files}
            header = {k: str(arrays.pop(k)) for k in ("status", "manifest", "meta")
                      if k in arrays}
            header["q_names"] = [str(x) for x in arrays.pop("q_names")]
            header["velocity_names"] = [str(x) for x in arrays.pop("velocity_names")]
        elif fmt == "h5":
            with _h5py().File(path, "r") as fh:
                arrays = {k: fh[k][()] for k in fh}
                header = {k: str(fh.attrs[k]) for k in ("status", "manifest", "meta")
                          if k in fh.attrs}
                header["q_names"] = json.loads(fh.attrs["q_names"])
                header["velocity_names"] = json.loads(fh.attrs["velocity_names"])
        else:
            arrays, header = _read_csv(path)
        manifest = json.loads(header["manifest"])
        meta = json.loads(header["meta"]) if "meta" in header else {}
        status = header["status"]
    except InvalidInputError:
        raise
    except zipfile.BadZipFile as exc:
        raise _not_a_result(path, f"a damaged zip archive: {exc}") from None
    except EOFError:
        raise _not_a_result(path, "a truncated file") from None
    except (OSError, ValueError, KeyError, IndexError, TypeError, json.JSONDecodeError) as exc:
        raise _not_a_result(path, f"{type(exc).__name__}: {exc}") from None
    _check_layout(path, arrays, header, manifest)
    return _result(path, arrays, header, meta, manifest, status)


def _result(path, arrays: dict, header: dict, meta: dict, manifest: dict,
            status: str) -> SceneResult:
    q_names = header["q_names"]
    if status not in Status.__members__:
        raise _not_a_result(path, f"its status {status!r} is not one of mbdk's")
    spatial = any(n.endswith(".z") for n in q_names)
    bodies = meta.get("bodies") or list(dict.fromkeys(n.rsplit(".", 1)[0] for n in q_names))
    parts = {k[len("energy_"):]: v for k, v in arrays.items()
             if k.startswith("energy_") and k != "energy_balance"}
    if "work" in arrays:
        parts["work"] = arrays["work"]
    wear_names = meta.get("wear_names", [])
    wear = ({n: arrays["wear"][:, k] for k, n in enumerate(wear_names)}
            if "wear" in arrays else {})
    names = meta.get("contact_names", [])
    nf = len(CONTACT_FIELDS)
    contacts = ({n: {f: arrays["contacts"][:, nf * k + i] for i, f in enumerate(CONTACT_FIELDS)}
                 for k, n in enumerate(names)} if "contacts" in arrays else {})
    stats = Stats(**{k: v for k, v in meta.get("stats", {}).items()
                     if k in Stats.__dataclass_fields__})
    return SceneResult(
        t=arrays["t"], q=arrays["q"], v=arrays["velocities"], a=arrays.get("accelerations"),
        multipliers=arrays.get("multipliers"), reactions=arrays.get("reactions"),
        energy=arrays.get("energy"), energy_parts=parts or None,
        residuals=arrays.get("residuals"), stats=stats, status=Status[status],
        message=meta.get("message") or status_message(Status[status]), manifest=manifest,
        visits=meta.get("visits") or {}, assembly=meta.get("assembly") or {},
        joints=meta.get("joints") or [], bodies=bodies, iterations=arrays.get("iterations"),
        drift=meta.get("drift"), wear=wear, contacts=contacts,
        kind=meta.get("kind") or ("spatial" if spatial else "planar"),
        rotation=meta.get("rotation") or (("quaternion" if any(n.endswith(".p0")
                                                               for n in q_names)
                                           else "euler313") if spatial else None),
        rotations=meta.get("rotations"))


#: what every result file holds (save_result)
_REQUIRED = ("t", "q", "velocities", "q_names", "velocity_names", "status", "manifest")


def _not_a_result(path, why: str) -> InvalidInputError:
    return InvalidInputError(f"{path}: not an mbdk result file ({why}); give a file that "
                             "`mbdk run` or mbdk.results_io.save_result wrote")


def _check_layout(path, arrays: dict, header: dict, manifest) -> None:
    """The arrays' shapes agree with each other, as save_result writes them: a file that
    reads but does not (edited, or another program's) is named rather than plotted wrong."""
    def bad(why):
        return _not_a_result(path, why)
    for k in ("t", "q", "velocities"):
        if arrays.get(k) is None:
            raise bad(f"no {k!r}")
    t = arrays["t"]
    if not (isinstance(t, np.ndarray) and t.ndim == 1 and t.size
            and np.issubdtype(t.dtype, np.floating)):
        raise bad(f"'t' is not a non-empty list of times (shape {np.shape(t)})")
    n = t.size
    for k, names in (("q", "q_names"), ("velocities", "velocity_names")):
        a = arrays[k]
        if not (isinstance(a, np.ndarray) and a.ndim == 2 and a.shape == (n, len(header[names]))):
            raise bad(f"{k!r} has shape {np.shape(a)}, not ({n}, {len(header[names])}): a row "
                      f"per time and a column per name of {names!r}")
        if not np.issubdtype(a.dtype, np.number):
            raise bad(f"{k!r} holds {a.dtype}, not numbers")
    ndims = {"accelerations": 2, "multipliers": 2, "reactions": 3, "residuals": 2, "wear": 2,
             "contacts": 2, "iterations": 1}
    for k, a in arrays.items():
        if k in ("t", "q", "velocities"):
            continue
        ndim = ndims.get(k, 1)
        if not (isinstance(a, np.ndarray) and a.ndim == ndim and a.shape[0] == n
                and np.issubdtype(a.dtype, np.number)):
            raise bad(f"{k!r} has shape {np.shape(a)}: not {ndim}-D numbers, a row per time")
    if not isinstance(manifest, dict):
        raise bad("its manifest is not a table")


def plot_result(path, out=None) -> Path:
    """A PNG of a saved run: the coordinates, the energy balance, the residuals and the wear
    volumes against t, each where the run has it (out: default the result's name with .png)."""
    r = load_result(path)
    out = Path(out) if out is not None else Path(path).with_suffix(".png")
    if out.suffix.lower() != ".png":
        raise InvalidInputError(f"{out}: plots are PNG files; give a name ending in .png")
    check_folder = out.parent if str(out.parent) else Path(".")
    if not check_folder.is_dir() or not os.access(check_folder, os.W_OK):
        raise InvalidInputError(f"{out}: the folder {str(check_folder)!r} cannot be written")
    # matplotlib: optional (the studies' extra), slow to import, only plots need it
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # after use("Agg"): plots without a screen
    balance = (r.energy_balance() if r.energy is not None and r.energy_parts
               and "work" in r.energy_parts else None)
    panels = 1 + (balance is not None) + (r.residuals is not None) + bool(r.wear) + \
        bool(r.contacts)
    fig, axes = plt.subplots(panels, 1, figsize=(8, 2.6 * panels + 0.6), sharex=True,
                             squeeze=False)
    axes = axes[:, 0]
    t = r.t
    ax = axes[0]
    for k, name in enumerate(r.q_names):
        ax.plot(t, r.q[:, k], label=name, lw=1)
    ax.set_ylabel("coordinates")
    if len(r.q_names) <= 12:
        ax.legend(fontsize=7, ncol=3)
    i = 1
    if balance is not None:
        # W: the work of dampers, loads and drivers as the run integrated it, at every step
        axes[i].plot(t, balance, lw=1)
        axes[i].set_ylabel("E - E0 - W [J]")
        i += 1
    if r.residuals is not None:
        res = np.abs(np.asarray(r.residuals, float))
        names = (("|Phi|", "|C w + Phi_t|", "||p| - 1|") if r.kind == "spatial" else
                 ("|Phi|", "|D v + Phi_t|", "|D a - gamma|"))
        for k, name in enumerate(names[:res.shape[1]]):
            if np.any(res[:, k] > 0):     # exact zeros (the assembled start) are left out
                axes[i].semilogy(t, np.where(res[:, k] > 0, res[:, k], np.nan), label=name,
                                 lw=1)
        axes[i].set_ylabel("residuals")
        axes[i].legend(fontsize=7)
        i += 1
    if r.contacts:
        for name, c in r.contacts.items():
            axes[i].plot(t, c["normal_force"], label=f"{name} normal", lw=1)
            if np.any(c["friction_force"]):
                axes[i].plot(t, c["friction_force"], label=f"{name} friction", lw=1, ls="--")
        axes[i].set_ylabel("contact forces [N]")
        axes[i].legend(fontsize=7)
        i += 1
    if r.wear:
        for name, w in r.wear.items():
            axes[i].plot(t, w, label=name, lw=1)
        axes[i].set_ylabel("worn volume [m^3]")
        axes[i].legend(fontsize=7)
    axes[-1].set_xlabel("t [s]")
    m = r.manifest
    fig.suptitle(f"{m.get('scene', '')}: {m.get('method', '')}/{m.get('formulation', '')} "
                 f"({r.status.name})", fontsize=10)
    fig.tight_layout()

    def write(tmp):
        fig.savefig(tmp, dpi=110, format="png")
    write_atomic(out, write)
    plt.close(fig)
    return out
