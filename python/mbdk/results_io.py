"""A scene run's samples and manifest in a file, and back: .npz (numpy), .csv (the manifest in
the leading comment lines) or .h5 / .hdf5 (h5py, where it is installed).

    >>> r = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-3, t_end=10)
    >>> mbdk.results_io.save_result(r, "run.npz")
    >>> d = mbdk.results_io.load_result("run.npz")     # d["t"], d["q"], d["manifest"], ...

What is written: t; the coordinates q and the velocities v (of a spatial body the centre's
velocity and the body-frame angular velocity) with their column names; where the run computed
them, the energy, the work W of dampers, loads and drivers as the run integrated it at every
step (not a quadrature over the samples), the energy balance E - E0 - W and the residuals
(residual_names says which); the multipliers; the status and the manifest (version, method, formulation, step or tolerances,
compiler flags). A file is written under a temporary name beside the target and renamed
when complete, so a failed or interrupted write leaves no partial file with the target's name.
"""
from __future__ import annotations

import csv
import json
import os
import zipfile
from pathlib import Path

import numpy as np

from .errors import InvalidInputError, NotApplicableError

FORMATS = {".npz": "npz", ".csv": "csv", ".h5": "h5", ".hdf5": "h5"}
_PLANAR = ("x", "y", "angle")
#: the CSV columns of SceneResult.residuals, by SceneResult.residual_names
_RESIDUAL_COLUMNS = {"position": "residual_position", "velocity": "residual_velocity",
                     "acceleration": "residual_acceleration", "quaternion_norm": "quaternion_norm"}


def _format(path: Path) -> str:
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise InvalidInputError(f"{path}: unknown result format {path.suffix!r}; give a file "
                                f"ending in {', '.join(FORMATS)}")
    return fmt


def check_writable(path) -> Path:
    """The output path, checked before a run: a known format, and a folder that exists and
    can be written (named errors otherwise)."""
    path = Path(path)
    fmt = _format(path)
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


def _columns(r) -> tuple[list, list]:
    """The names of q's and of the velocities' columns."""
    bodies = list(r.bodies or [])
    if r.kind == "spatial":
        nqb = r.q.shape[1] // max(len(bodies), 1)
        rot = (["p0", "p1", "p2", "p3"] if nqb == 7 else ["a1", "a2", "a3"])
        qn = [f"{b}.{c}" for b in bodies for c in ("x", "y", "z", *rot)]
        vn = [f"{b}.{c}" for b in bodies for c in ("vx", "vy", "vz", "Wx", "Wy", "Wz")]
        return qn, vn
    qn = [f"{b}.{c}" for b in bodies for c in _PLANAR]
    vn = [f"{b}.d{c}" for b in bodies for c in _PLANAR]
    if len(qn) != r.q.shape[1]:
        qn = [f"q{k}" for k in range(r.q.shape[1])]
        vn = [f"v{k}" for k in range(r.q.shape[1])]
    return qn, vn


def result_arrays(r) -> dict:
    """The arrays and names save_result writes (None where the run did not compute them)."""
    qn, vn = _columns(r)
    energy = r.energy
    balance = work = None
    if energy is not None:
        try:
            balance = r.energy_balance()
            work = np.asarray(r.energy_parts["work"])
        except NotApplicableError:       # an output the run was not asked for
            balance = None
    return {"t": np.asarray(r.t), "q": np.asarray(r.q), "velocities": np.asarray(r.v),
            "q_names": qn, "velocity_names": vn,
            "energy": None if energy is None else np.asarray(energy),
            "work": work, "energy_balance": balance,
            "residuals": None if r.residuals is None else np.asarray(r.residuals),
            "residual_names": [_RESIDUAL_COLUMNS[n] for n in r.residual_names],
            "multipliers": None if r.multipliers is None else np.asarray(r.multipliers),
            "status": r.status.name, "manifest": r.manifest}


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


def save_result(r, path) -> Path:
    """Writes the run r (a SceneResult) to path, by its suffix."""
    path = check_writable(path)
    a = result_arrays(r)
    manifest = json.dumps(a["manifest"], default=str)
    fmt = _format(path)
    if fmt == "npz":
        def write(tmp):
            arrays = {k: v for k, v in a.items() if isinstance(v, np.ndarray)}
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays, q_names=np.array(a["q_names"]),
                         velocity_names=np.array(a["velocity_names"]),
                         status=np.array(a["status"]), manifest=np.array(manifest))
    elif fmt == "h5":
        h5py = _h5py()

        def write(tmp):
            with h5py.File(tmp, "w") as fh:
                for k, v in a.items():
                    if isinstance(v, np.ndarray):
                        fh.create_dataset(k, data=v)
                fh.attrs["q_names"] = json.dumps(a["q_names"])
                fh.attrs["velocity_names"] = json.dumps(a["velocity_names"])
                fh.attrs["status"] = a["status"]
                fh.attrs["manifest"] = manifest
    else:
        def write(tmp):
            cols, blocks = ["t"], [a["t"][:, None]]
            cols += a["q_names"] + a["velocity_names"]
            blocks += [a["q"], a["velocities"]]
            for name in ("energy", "work", "energy_balance"):
                if a[name] is not None:
                    cols.append(name)
                    blocks.append(a[name][:, None])
            if a["residuals"] is not None:
                res = a["residuals"]
                cols += a["residual_names"][:res.shape[1]]
                blocks.append(res)
            if a["multipliers"] is not None and a["multipliers"].size:
                cols += [f"lambda{k + 1}" for k in range(a["multipliers"].shape[1])]
                blocks.append(a["multipliers"])
            data = np.hstack(blocks)
            with open(tmp, "w", newline="") as fh:
                fh.write(f"# status: {a['status']}\n# manifest: {manifest}\n"
                         f"# columns: t, {len(a['q_names'])} coordinates, "
                         f"{len(a['velocity_names'])} velocities, then the outputs\n")
                w = csv.writer(fh)
                w.writerow(cols)
                for row in data:
                    w.writerow([repr(float(x)) for x in row])
    write_atomic(path, write)
    return path


def load_result(path) -> dict:
    """What save_result wrote: t, q, velocities, q_names, velocity_names, energy, work,
    energy_balance, residuals, multipliers (None where absent), status, manifest."""
    path = Path(path)
    fmt = _format(path)
    if not path.is_file():
        raise InvalidInputError(f"{path}: no such result file")
    if path.stat().st_size == 0:
        raise _not_a_result(path, "an empty file")
    out = {k: None for k in ("energy", "work", "energy_balance", "residuals", "multipliers")}
    try:
        if fmt == "npz":
            if not zipfile.is_zipfile(path):
                raise _not_a_result(path, "not a zip archive, or a truncated one")
            with np.load(path, allow_pickle=False) as z:
                missing = [k for k in _REQUIRED if k not in z.files]
                if missing:
                    raise _not_a_result(path, f"no {missing[0]!r} array; it holds "
                                        f"{', '.join(z.files) or 'nothing'}")
                for k in z.files:
                    out[k] = z[k]
            out["q_names"] = [str(x) for x in out["q_names"]]
            out["velocity_names"] = [str(x) for x in out["velocity_names"]]
            out["status"] = str(out["status"])
            out["manifest"] = json.loads(str(out["manifest"]))
        elif fmt == "h5":
            with _h5py().File(path, "r") as fh:
                for k in fh:
                    out[k] = fh[k][()]
                out["q_names"] = json.loads(fh.attrs["q_names"])
                out["velocity_names"] = json.loads(fh.attrs["velocity_names"])
                out["status"] = str(fh.attrs["status"])
                out["manifest"] = json.loads(fh.attrs["manifest"])
        else:
            with open(path, newline="") as fh:
                status = fh.readline().partition(": ")[2].strip()
                manifest = json.loads(fh.readline().partition(": ")[2])
                layout = fh.readline().split()
                nq, nv = int(layout[3]), int(layout[5])
                rows = list(csv.reader(fh))
            cols, data = rows[0], np.array(rows[1:], dtype=float).reshape(-1, len(rows[0]))
            out.update(t=data[:, 0], q=data[:, 1:1 + nq], velocities=data[:, 1 + nq:1 + nq + nv],
                       q_names=cols[1:1 + nq], velocity_names=cols[1 + nq:1 + nq + nv],
                       status=status, manifest=manifest)
            rest = {c: data[:, k] for k, c in enumerate(cols) if k >= 1 + nq + nv}
            for name in ("energy", "work", "energy_balance"):
                out[name] = rest.get(name)
            res = [rest[c] for c in ("residual_position", "residual_velocity",
                                     "residual_acceleration", "quaternion_norm") if c in rest]
            out["residuals"] = np.stack(res, axis=1) if res else None
            lam = [rest[c] for c in rest if c.startswith("lambda")]
            out["multipliers"] = np.stack(lam, axis=1) if lam else None
    except InvalidInputError:
        raise
    except zipfile.BadZipFile as exc:
        raise _not_a_result(path, f"a damaged zip archive: {exc}") from None
    except EOFError:
        raise _not_a_result(path, "a truncated file") from None
    except (OSError, ValueError, KeyError, IndexError, TypeError, json.JSONDecodeError) as exc:
        raise _not_a_result(path, f"{type(exc).__name__}: {exc}") from None
    _check_layout(path, out)
    return out


#: what every result file holds (save_result)
_REQUIRED = ("t", "q", "velocities", "q_names", "velocity_names", "status", "manifest")


def _not_a_result(path, why: str) -> InvalidInputError:
    return InvalidInputError(f"{path}: not an mbdk result file ({why}); give a file that "
                             "`mbdk run` or mbdk.results_io.save_result wrote")


def _check_layout(path, d: dict) -> None:
    """The arrays' shapes agree with each other, as save_result writes them: a file that
    reads but does not (edited, or another program's) is named rather than plotted wrong."""
    def bad(why):
        return _not_a_result(path, why)
    for k in _REQUIRED:
        if d.get(k) is None:
            raise bad(f"no {k!r}")
    t = d["t"]
    if not (isinstance(t, np.ndarray) and t.ndim == 1 and t.size
            and np.issubdtype(t.dtype, np.floating)):
        raise bad(f"'t' is not a non-empty list of times (shape {np.shape(t)})")
    n = t.size
    for k, names in (("q", "q_names"), ("velocities", "velocity_names")):
        a = d[k]
        if not (isinstance(a, np.ndarray) and a.ndim == 2 and a.shape == (n, len(d[names]))):
            raise bad(f"{k!r} has shape {np.shape(a)}, not ({n}, {len(d[names])}): a row per "
                      f"time and a column per name of {names!r}")
        if not np.issubdtype(a.dtype, np.number):
            raise bad(f"{k!r} holds {a.dtype}, not numbers")
    for k, ndim in (("energy", 1), ("work", 1), ("energy_balance", 1), ("residuals", 2),
                    ("multipliers", 2)):
        a = d.get(k)
        if a is not None and not (isinstance(a, np.ndarray) and a.ndim == ndim
                                  and a.shape[0] == n and np.issubdtype(a.dtype, np.number)):
            raise bad(f"{k!r} has shape {np.shape(a)}: not {ndim}-D numbers, a row per time")
    if not isinstance(d["manifest"], dict):
        raise bad("its manifest is not a table")


def plot_result(path, out=None) -> Path:
    """A PNG of a saved run: the coordinates, the energy balance and the residuals against t
    (out: default the result's name with .png)."""
    data = load_result(path)
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
    panels = 1 + (data["energy_balance"] is not None) + (data["residuals"] is not None)
    fig, axes = plt.subplots(panels, 1, figsize=(8, 2.6 * panels + 0.6), sharex=True,
                             squeeze=False)
    axes = axes[:, 0]
    t = data["t"]
    ax = axes[0]
    for k, name in enumerate(data["q_names"]):
        ax.plot(t, data["q"][:, k], label=name, lw=1)
    ax.set_ylabel("coordinates")
    if len(data["q_names"]) <= 12:
        ax.legend(fontsize=7, ncol=3)
    i = 1
    if data["energy_balance"] is not None:
        # W: the work of dampers, loads and drivers as the run integrated it, at every step
        axes[i].plot(t, data["energy_balance"], lw=1)
        axes[i].set_ylabel("E - E0 - W [J]")
        i += 1
    m = data["manifest"]
    if data["residuals"] is not None:
        res = np.abs(np.asarray(data["residuals"], float))
        names = (("|Phi|", "|C w + Phi_t|", "||p| - 1|") if m.get("kind") == "spatial" else
                 ("|Phi|", "|D v + Phi_t|", "|D a - gamma|"))
        for k, name in enumerate(names[:res.shape[1]]):
            if np.any(res[:, k] > 0):     # exact zeros (the assembled start) are left out
                axes[i].semilogy(t, np.where(res[:, k] > 0, res[:, k], np.nan), label=name,
                                 lw=1)
        axes[i].set_ylabel("residuals")
        axes[i].legend(fontsize=7)
    axes[-1].set_xlabel("t [s]")
    fig.suptitle(f"{m.get('scene', '')}: {m.get('method', '')}/{m.get('formulation', '')} "
                 f"({data['status']})", fontsize=10)
    fig.tight_layout()

    def write(tmp):
        fig.savefig(tmp, dpi=110, format="png")
    write_atomic(out, write)
    plt.close(fig)
    return out
