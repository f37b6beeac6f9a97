"""Bad input from every door: a fixed-seed generator of broken scenes and bad arguments, and what
each one gets. The promise under test: a named error (an mbdk.MbdkError, which says what to
change) or a sound result, never a crash, a hang, a generic Python exception or a silent
non-finite number.

1. scenes: the built-in scene files, each mutated in one place (a field set to None, a string,
   a negative, zero, nan, inf, 1e308, a list, a table, a huge integer; a field removed or
   added; a body reference dangling or empty; names duplicated; a table where a list belongs;
   the file's bytes made non-UTF-8 or nested a thousand deep), loaded from TOML text and, if
   loaded, run for a few steps with rk4 (reduced) and trapezoidal_index3.
2. scene objects: a loaded Scene whose body, joint or force field is changed afterwards in
   Python (a mass of -1, an inertia of nan, a point of None, a stiffness that is a string),
   then simulated.
3. arguments: simulate() and solve_ode() with one argument replaced by a bad value (h, t_end,
   t0, every, method, formulation, outputs, watch, solver, params, y0, max_iter, tolerances).

Every outcome is classified: success (finite), named (an MbdkError), generic (any other
exception: a defect), nonfinite (success with inf or NaN: a defect). tests/test_fuzz.py runs a
subset (fixed seed) and fails on any defect; this study runs the whole set and tables the
outcomes.
"""
from __future__ import annotations

import copy
import math
import random
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import main, progress  # noqa: E402

import mbdk  # noqa: E402
from mbdk.analysis.tables import write_table  # noqa: E402

BAD_VALUES = [None, "abc", "", -1.0, 0.0, -0.0, math.nan, math.inf, -math.inf, 1e308, -1e308,
              1e-320, [], [1.0], [1.0, 2.0, 3.0], {}, {"a": 1}, True, 10 ** 30, -(10 ** 30),
              "ground", "\u00e9\u00e8", [None, None], ["x", "y"]]
SCENES = ["double_pendulum", "four_bar", "trolley_crane", "spring_damper_bar",
          "parallelogram_redundant", "three_link_pendulum", "physical_pendulum", "spring_bar",
          "heavy_top", "free_body", "spatial_double_pendulum", "pla_gears", "particle_in_ring"]


def _scene_dict(name: str) -> dict:
    return tomllib.loads(Path(mbdk.scene(name).source).read_text())


def _toml_value(v) -> str:
    if v is None:
        return None
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        items = [_toml_value(x) for x in v]
        return "[" + ", ".join("0" if x is None else x for x in items) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(d: dict) -> str:
    """A scene dict as TOML text (the subset the scene files use)."""
    lines = []
    for key in ("scene",):
        if isinstance(d.get(key), dict):
            lines.append(f"[{key}]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in d[key].items() if v is not None]
    for key in ("body", "joint", "force", "wear"):
        items = d.get(key)
        if isinstance(items, list):
            for item in items:
                lines.append(f"[[{key}]]")
                if isinstance(item, dict):
                    lines += [f"{k} = {_toml_value(v)}" for k, v in item.items()
                              if _toml_value(v) is not None]
        elif items is not None:
            lines.append(f"{key} = {_toml_value(items)}")
    return "\n".join(lines) + "\n"


def bad_scenes(seed: int, n: int):
    """n (label, toml bytes) cases, each a built-in scene broken in one place."""
    rng = random.Random(seed)
    out = []
    while len(out) < n:
        name = rng.choice(SCENES)
        d = _scene_dict(name)
        kind = rng.choice(["value", "value", "value", "remove", "add", "reference", "duplicate",
                           "shape", "table", "bytes", "nesting"])
        label = f"{name}: {kind}"
        if kind == "bytes":
            text = to_toml(d).encode()
            i = rng.randrange(len(text))
            out.append((label + " (0xff at byte %d)" % i, text[:i] + b"\xff\xfe" + text[i:]))
            continue
        if kind == "nesting":
            depth = rng.choice([100, 1000, 5000])
            out.append((label + f" ({depth} deep)", ("x = " + "[" * depth + "]" * depth + "\n"
                                                     + to_toml(d)).encode()))
            continue
        section = rng.choice([s for s in ("body", "joint", "force", "wear") if d.get(s)])
        item = rng.choice(d[section])
        fld = rng.choice(list(item))
        if kind == "value":
            v = rng.choice(BAD_VALUES)
            item[fld] = v
            label += f" {section}.{fld} = {v!r}"
        elif kind == "remove":
            del item[fld]
            label += f" {section}.{fld} removed"
        elif kind == "add":
            item[rng.choice(["colour", "masss", "x_deg", "kind"])] = rng.choice(BAD_VALUES[:6])
            label += f" {section}: a field added"
        elif kind == "reference":
            for key in ("body", "body1", "body2"):
                if key in item:
                    item[key] = rng.choice(["", "nobody", "ground", " ", "Bar1"])
                    label += f" {section}.{key} = {item[key]!r}"
                    break
        elif kind == "duplicate":
            d[section].append(copy.deepcopy(item))
            label += f" {section} duplicated"
        elif kind == "shape":
            if section == "body":
                item.pop("inertia", None)
                item["shape"] = rng.choice([{"type": "bar", "length": 1e200},
                                            {"type": "bar", "length": -1.0},
                                            {"type": "disc"}, {"type": "cube", "side": 1.0},
                                            {"type": "rectangle", "width": math.inf,
                                             "height": 1.0}])
                label += f" body.shape = {item['shape']!r}"
        elif kind == "table":
            d[section] = rng.choice([{}, "x", 3])
            label += f" {section} is {d[section]!r}"
        out.append((label, to_toml(d).encode()))
    return out


def bad_objects(seed: int, n: int):
    """n (label, callable) cases: a loaded scene's object field changed, then a short run."""
    rng = random.Random(seed)
    out = []
    while len(out) < n:
        name = rng.choice(SCENES)
        sc = mbdk.scene(name)
        group = rng.choice(["bodies", "joints", "forces", "wear"])
        items = getattr(sc, group, [])
        if not items:
            continue
        item = rng.choice(items)
        fld = rng.choice([f for f in vars(item) if f != "name"])
        v = rng.choice(BAD_VALUES + [(1.0, math.nan), (None, 1.0), -5.0])
        setattr(item, fld, v)
        method = rng.choice(["rk4", "trapezoidal_index3", "bdf2"])
        out.append((f"{name}: {group}.{fld} = {v!r}, {method}",
                    lambda sc=sc, method=method: mbdk.simulate(sc, method, h=1e-3,
                                                               t_end=0.004)))
    return out


def bad_arguments(seed: int, n: int):
    """n (label, callable) cases: one argument of a valid call replaced."""
    rng = random.Random(seed)
    sim = dict(method="rk4", h=1e-3, t_end=0.01)
    ode = dict(problem="pendulum", method="rk4", h=1e-3, t_end=0.01)
    fields_sim = {
        "h": [0.0, -1e-3, math.nan, math.inf, "0.1", None, 1e-14, 1e300, [1e-3], True],
        "t_end": [0.0, -1.0, math.nan, math.inf, "1", None, 1e300, 1e-14],
        "t0": [math.nan, math.inf, "0", None, 1e300],
        "every": [0, -1, 1.5, "1", None, 10 ** 30, math.nan],
        "method": ["rk5", "", None, 3, "RK4", "trapezoidal"],
        "formulation": ["x", "", None, 1, "index3"],
        "outputs": ["energy", ["a", "b"], 3, None, [None]],
        "watch": [1, "yes", {"energy": -1}, {"every": 0}, {"x": 1}, {"position": math.nan}],
        "solver": ["lu", None, 2],
        "max_iter": [0, -1, 1.5, "5", 10 ** 12],
        "newton_rtol": [-1.0, math.nan, "1e-6"],
        "alpha": [-1.0, math.nan, math.inf, "1"],
        "penalty": [(1.0,), (0.0, 1.0, 1.0), "x", (math.nan, 1, 1)],
        "projection_tol": [0.0, -1.0, math.nan],
        "dt_out": [0.0, -1.0, math.nan],
    }
    fields_ode = {
        "h": [0.0, -1e-3, math.nan, "0.1", None, 1e-13],
        "t_end": [0.0, math.nan, None],
        "y0": [[1.0], [math.nan, 0.0], "ab", [[1.0, 2.0]], None, [1e308, 1e308]],
        "params": [{"g": math.nan}, {"zz": 1.0}, "x", {"l": -1.0}, {"l": 0.0}],
        "every": [0, 2.5, None],
        "method": ["nope", None],
    }
    out = []
    while len(out) < n:
        if rng.random() < 0.7:
            fld = rng.choice(list(fields_sim))
            v = rng.choice(fields_sim[fld])
            kw = dict(sim)
            if fld in ("max_iter", "dt_out"):
                kw["method"] = "trapezoidal_index3"
                if fld == "dt_out":
                    kw["adaptive"] = True
            kw[fld] = v
            scene = rng.choice(["double_pendulum", "four_bar", "trolley_crane"])
            out.append((f"simulate({scene}, {fld}={v!r})",
                        lambda scene=scene, kw=kw: mbdk.simulate(mbdk.scene(scene), **kw)))
        else:
            fld = rng.choice(list(fields_ode))
            v = rng.choice(fields_ode[fld])
            kw = dict(ode)
            kw[fld] = v
            rest = {k: x for k, x in kw.items() if k not in ("problem", "method")}
            out.append((f"solve_ode({fld}={v!r})",
                        lambda kw=kw, rest=rest: mbdk.solve_ode(kw["problem"], kw["method"],
                                                                **rest)))
    return out


def _finite(r) -> bool:
    arrays = [getattr(r, name, None) for name in ("y", "q", "v", "w", "energy")]
    return all(a is None or callable(a) or np.all(np.isfinite(np.asarray(a, float)))
               for a in arrays)


def classify(fn) -> tuple[str, str]:
    """('success' | 'named' | 'generic' | 'nonfinite', detail)."""
    try:
        r = fn()
    except mbdk.MbdkError as exc:
        return "named", type(exc).__name__
    except (KeyboardInterrupt, SystemExit):
        raise
    except BaseException as exc:  # a defect: not a named error
        return "generic", f"{type(exc).__name__}: {str(exc)[:200]}"
    if isinstance(r, list):
        return ("success", "") if all(_finite(x) for x in r) else ("nonfinite", "")
    return ("success", "") if _finite(r) else ("nonfinite", "")


def run_scene_case(data: bytes, tmp: Path):
    """Load the bytes as a scene file; if loaded, a few steps of rk4 and of trapezoidal_index3."""
    path = tmp / "case.toml"
    path.write_bytes(data)

    def go():
        sc = mbdk.load_scene(path)
        # a spatial scene's second method: an error-controlled one (trapezoidal_index3 is the
        # planar model's)
        second = ("dopri54", {"rtol": 1e-6, "atol": 1e-8}) if isinstance(
            sc, mbdk.SpatialScene) else ("trapezoidal_index3", {"h": 1e-3})
        return [mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.005),
                mbdk.simulate(sc, second[0], t_end=0.005, **second[1])]
    return classify(go)


def fuzz(tmp: Path, n_scenes: int, n_args: int, seed: int = 20261125):
    rows = []
    for label, data in bad_scenes(seed, n_scenes):
        t0 = time.perf_counter()
        outcome, detail = run_scene_case(data, tmp)
        rows.append({"door": "scene file", "case": label, "outcome": outcome, "detail": detail,
                     "seconds": time.perf_counter() - t0})
    for label, fn in bad_objects(seed + 2, n_scenes // 2):
        t0 = time.perf_counter()
        outcome, detail = classify(fn)
        rows.append({"door": "scene objects", "case": label, "outcome": outcome,
                     "detail": detail, "seconds": time.perf_counter() - t0})
    for label, fn in bad_arguments(seed + 1, n_args):
        t0 = time.perf_counter()
        outcome, detail = classify(fn)
        rows.append({"door": "arguments", "case": label, "outcome": outcome, "detail": detail,
                     "seconds": time.perf_counter() - t0})
    return rows


def run(out: Path, quick: bool = False) -> dict:
    import tempfile
    out = Path(out)
    n_s, n_a = (150, 80) if quick else (600, 300)
    progress(f"fuzz: {n_s} broken scenes, {n_a} bad arguments")
    with tempfile.TemporaryDirectory() as tmp:
        rows = fuzz(Path(tmp), n_s, n_a)
    summary = []
    for door in ("scene file", "scene objects", "arguments"):
        sub = [r for r in rows if r["door"] == door]
        summary.append({"door": door, "cases": len(sub),
                        **{k: sum(r["outcome"] == k for r in sub)
                           for k in ("success", "named", "generic", "nonfinite")},
                        "slowest_s": max(r["seconds"] for r in sub)})
    t1 = write_table(summary, ["door", "cases", "success", "named", "generic", "nonfinite",
                               "slowest_s"], out, "fuzz_summary",
                     "Bad input from three doors: outcomes (fixed seed)",
                     "generic (an exception that is not an mbdk.MbdkError) and nonfinite (a "
                     "success with inf or NaN) are defects; named errors say what to change. "
                     "slowest_s bounds a hang: every case runs a few steps.")
    defects = [r for r in rows if r["outcome"] in ("generic", "nonfinite")]
    t2 = write_table(defects or [{"door": "-", "case": "none", "outcome": "-", "detail": "-",
                                  "seconds": 0.0}],
                     ["door", "case", "outcome", "detail", "seconds"], out, "fuzz_defects",
                     "Cases that got a generic exception or a non-finite success",
                     "Each is a defect to fix; the test suite runs a subset and fails on any.")
    return {"title": "Fuzzing: broken scenes and bad arguments", "tables": [t1, t2],
            "figures": []}


if __name__ == "__main__":
    raise SystemExit(main(run, "fuzz"))
