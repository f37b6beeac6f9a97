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
3. arguments: simulate() (planar and spatial scenes), solve_ode() and ODESolver with one
   argument replaced by a bad value (h, t_end, t0, every, method, formulation, outputs, watch,
   solver, startup, params, y0, max_iter, rtol, atol in both forms, h_min, h_max, dt_out,
   max_steps): huge integers (10^400), huge and denormal floats, lists and dicts where a name
   belongs, strings where a number belongs, bounds that would need 10^9 steps or more sample
   memory than the machine has.
4. scene paths: a device (/dev/zero, /dev/urandom, /dev/null), a directory, a named pipe, a
   missing file, an object that is no path: each must be refused at once, not read for ever.
5. functions: the stability and registry functions (stability_region, spectral_radius,
   oscillator_response, real_interval, methods, scenes, ...) with each argument of a wrong type
   or value.

Every value a scene field gets is drawn from BAD_VALUES: None, strings, signs, zero, NaN and
inf, 1e308 and 1e-320 (denormal), 1e200 and 1e-300 (their squares overflow or underflow),
integers of 30 and 400 digits and one of 5000 digits (beyond what Python converts), lists and
tables.

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

class Digits(int):
    """An integer written with n digits in a TOML file (beyond Python's int-to-text limit of
    4300 digits, so that it is written here, not through str)."""

    def __new__(cls, n: int):
        obj = super().__new__(cls, 9)
        obj.n = n
        return obj

    def __repr__(self):
        return f"<{self.n}-digit integer>"


BAD_VALUES = [None, "abc", "", -1.0, 0.0, -0.0, math.nan, math.inf, -math.inf, 1e308, -1e308,
              1e-320, [], [1.0], [1.0, 2.0, 3.0], {}, {"a": 1}, True, 10 ** 30, -(10 ** 30),
              "ground", "\u00e9\u00e8", [None, None], ["x", "y"], 10 ** 400, -(10 ** 400),
              Digits(5000), 1e200, 1e-300, 5e-324, [1e300, 0.0], [10 ** 400, 0.0],
              [1e-300, 1e-300]]
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
    if isinstance(v, Digits):
        return "9" * v.n
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
        "h": [0.0, -1e-3, math.nan, math.inf, "0.1", None, 1e-14, 1e300, [1e-3], True,
              10 ** 400, 5e-324],
        "t_end": [0.0, -1.0, math.nan, math.inf, "1", None, 1e300, 1e-14, 10 ** 400],
        "t0": [math.nan, math.inf, "0", None, 1e300, 10 ** 400],
        "every": [0, -1, 1.5, "1", None, 10 ** 30, math.nan, 10 ** 400],
        "method": ["rk5", "", None, 3, "RK4", "trapezoidal", ["rk4"], {"rk4": 1}],
        "formulation": ["x", "", None, 1, "index3", ["reduced"], {"reduced": 1}, ("x",)],
        "outputs": ["energy", ["a", "b"], 3, None, [None], [["a"]], [{"a": 1}]],
        "watch": [1, "yes", {"energy": -1}, {"every": 0}, {"x": 1}, {"position": math.nan},
                  {"energy": 10 ** 400}, ["energy"]],
        "solver": ["lu", None, 2, ["auto"], {"auto": 1}],
        "startup": ["x", None, ["rk4"], {"rk4": 1}],
        "max_iter": [0, -1, 1.5, "5", 10 ** 12, 10 ** 400],
        "newton_rtol": [-1.0, math.nan, "1e-6", 10 ** 400],
        "alpha": [-1.0, math.nan, math.inf, "1", 10 ** 400],
        "penalty": [(1.0,), (0.0, 1.0, 1.0), "x", (math.nan, 1, 1), (10 ** 400, 1, 1)],
        "projection_tol": [0.0, -1.0, math.nan, 10 ** 400],
        "dt_out": [0.0, -1.0, math.nan, 10 ** 400, 1e-300],
        "rtol": [10 ** 400, -1.0, 1e-300, "x", [1e-6], math.nan],
        "atol": [[-1.0, 1e-9], [1e-8] * 13, 10 ** 400, "x", {"a": 1}, math.nan, 0.0],
        "h_max": [1e-300, 1e-11, 10 ** 400, -1.0, "x"],   # 1e-11: 1e9 steps in 0.01 s
        "h_min": [10 ** 400, 1e3, -1.0, "x"],
        "max_steps": [10 ** 400, -1, 1.5, "x"],
    }
    #: options of the error-controlled methods (and, for dt_out, h_min, h_max, of
    #: trapezoidal_index3's adaptive mode, taken in either)
    adaptive_only = ("rtol", "atol", "h_max", "h_min", "max_steps")
    fields_ode = {
        "h": [0.0, -1e-3, math.nan, "0.1", None, 1e-13],
        "t_end": [0.0, math.nan, None],
        "y0": [[1.0], [math.nan, 0.0], "ab", [[1.0, 2.0]], None, [1e308, 1e308]],
        "params": [{"g": math.nan}, {"zz": 1.0}, "x", {"l": -1.0}, {"l": 0.0},
                   {"g": 10 ** 400}, {("g",): 1.0}],
        "every": [0, 2.5, None, 10 ** 400],
        "method": ["nope", None, ["rk4"], {"rk4": 1}],
        "startup": [["rk4"], {"rk4": 1}, None],
        "t0": [10 ** 400, "0"],
    }
    fields_adaptive_ode = {
        "rtol": [10 ** 400, -1.0, "x", [1e-6]],
        "atol": [[-1.0, 1e-9], [1e-8, 1e-8, 1e-8], 10 ** 400, "x", [math.nan, 1e-8]],
        "h_max": [1e-300, 1e-9, 10 ** 400],
        "h_min": [2.0, 10 ** 400],
        "dt_out": [1e-300, 10 ** 400],
        "max_steps": [10 ** 400, -5],
        "max_order": [10 ** 400, 99],
    }
    out = [
        # sample arrays beyond any machine's memory (2e9 samples of the double pendulum and
        # its outputs: hundreds of GiB), refused before they are allocated
        ("simulate(double_pendulum, h=1e-9, t_end=2.0): 2e9 samples",
         lambda: mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-9, t_end=2.0)),
        ("simulate(heavy_top, h=1e-9, t_end=2.0): 2e9 samples",
         lambda: mbdk.simulate(mbdk.scene("heavy_top"), "rk4", h=1e-9, t_end=2.0)),
        ("solve_ode(double_pendulum, h=1e-9, t_end=2.0): 2e9 samples",
         lambda: mbdk.solve_ode("double_pendulum", "rk4", h=1e-9, t_end=2.0)),
    ]
    # the arguments issue 36 found getting through, each once whatever the draw
    for scene, kw in [("double_pendulum", dict(method="dopri54", t_end=1.0, h_max=1e-300)),
                      ("heavy_top", dict(method="bdf", t_end=1.0, h_max=1e-9)),
                      ("heavy_top", dict(method="dopri54", t_end=0.01, atol=[-1.0, 1e-9])),
                      ("double_pendulum", dict(method="dopri54", t_end=0.01, rtol=10 ** 400)),
                      ("four_bar", dict(method="rk4", h=1e-3, t_end=0.01,
                                        formulation=["reduced"])),
                      ("heavy_top", dict(method="rk4", h=1e-3, t_end=0.01,
                                         formulation=["reduced"])),
                      ("four_bar", dict(method={"rk4": 1}, h=1e-3, t_end=0.01)),
                      ("four_bar", dict(method="rk4", h=1e-3, t_end=0.01, solver=["auto"])),
                      ("four_bar", dict(method="bdf2", h=1e-3, t_end=0.01, startup={"x": 1}))]:
        shown = ", ".join(f"{k}={v!r:.60}" for k, v in kw.items() if k != "method")
        out.append((f"simulate({scene}, {kw['method']!r}, {shown})",
                    lambda scene=scene, kw=kw: mbdk.simulate(mbdk.scene(scene), **kw)))
    while len(out) < n:
        r = rng.random()
        if r < 0.55:
            fld = rng.choice(list(fields_sim))
            v = rng.choice(fields_sim[fld])
            kw = dict(sim)
            scene = rng.choice(["double_pendulum", "four_bar", "trolley_crane", "heavy_top",
                                "spatial_double_pendulum"])
            if fld in ("max_iter", "dt_out") and scene not in ("heavy_top",
                                                               "spatial_double_pendulum"):
                kw["method"] = "trapezoidal_index3"
                if fld == "dt_out":
                    kw["adaptive"] = True
            if fld in adaptive_only or (fld == "dt_out" and kw["method"] == "rk4"):
                kw = {"method": rng.choice(["dopri54", "bdf"]), "t_end": 0.01}
            if fld == "startup":
                kw["method"] = "bdf2"
            kw[fld] = v
            out.append((f"simulate({scene}, {kw['method']}, {fld}={v!r:.60})",
                        lambda scene=scene, kw=kw: mbdk.simulate(mbdk.scene(scene), **kw)))
        elif r < 0.7:
            fld = rng.choice(list(fields_adaptive_ode))
            v = rng.choice(fields_adaptive_ode[fld])
            kw = {"t_end": 1.0, fld: v}
            method = rng.choice(["dopri54", "bdf", "cvode_bdf"])
            solver = rng.choice(["solve_ode", "ODESolver"])
            if solver == "ODESolver":
                fn = (lambda kw=kw, method=method:
                      mbdk.ODESolver("pendulum", method, **kw).solve())
            else:
                fn = lambda kw=kw, method=method: mbdk.solve_ode("pendulum", method, **kw)
            out.append((f"{solver}(pendulum, {method}, {fld}={v!r:.60})", fn))
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
    arrays = [getattr(r, name, None) for name in ("y", "q", "v", "energy")]
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
        second = (("dopri54", {"rtol": 1e-6, "atol": 1e-8}) if sc.kind == "spatial" else
                  ("trapezoidal_index3", {"h": 1e-3}))
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
    if n_args:
        for door, cases in (("scene paths", bad_paths(tmp)), ("functions", bad_functions())):
            for label, fn in cases:
                t0 = time.perf_counter()
                outcome, detail = classify(fn)
                rows.append({"door": door, "case": label, "outcome": outcome, "detail": detail,
                             "seconds": time.perf_counter() - t0})
    return rows


def bad_paths(tmp: Path):
    """(label, callable) cases: load_scene on paths that are no scene file. A device or a pipe
    would be read for ever (or block) if opened: each must be refused at once."""
    import os
    from mbdk.scene_file import scene_or_file
    pipe = tmp / "pipe.toml"
    if not pipe.exists():
        os.mkfifo(pipe)
    out = []
    for p in ["/dev/zero", "/dev/urandom", "/dev/null", str(tmp), str(pipe),
              str(tmp / "missing.toml"), "", 3, None, ["a.toml"], b"\xff.toml"]:
        out.append((f"load_scene({p!r})", lambda p=p: mbdk.load_scene(p)))
        if isinstance(p, str) and p.startswith("/dev/"):
            out.append((f"scene_or_file({p!r})",
                        lambda p=p: scene_or_file(p)))
    return out


#: what a name-like argument gets instead of a name
NOT_NAMES = [["rk4"], {"a": 1}, ("x",), {"rk4"}, 3, None, 1.5, b"rk4", 10 ** 400]
#: what a number argument gets instead of a number
NOT_NUMBERS = ["1", None, [1.0], {"a": 1}, 10 ** 400, math.nan, -math.inf, 1e300, 1e-300]


def bad_functions():
    """(label, callable) cases: the stability and registry functions with one argument of a
    wrong type or value (every one, deterministic)."""
    from mbdk import stability as st
    calls = {
        "stability_region(method)": lambda v: st.stability_region(v, n=5),
        "stability_region(re)": lambda v: st.stability_region("rk4", re=v, n=5),
        "stability_region(im)": lambda v: st.stability_region("rk4", im=v, n=5),
        "stability_region(n)": lambda v: st.stability_region("rk4", n=v),
        "spectral_radius(z)": lambda v: st.spectral_radius("rk4", v),
        "amplification_factor(z)": lambda v: st.amplification_factor("heun", v),
        "real_interval(reach)": lambda v: st.real_interval("heun", v),
        "a_alpha(r_min)": lambda v: st.a_alpha("bdf2", v),
        "oscillator_response(h_over_T)": lambda v: st.oscillator_response("rk4", v),
        "oscillator_response(zeta)": lambda v: st.oscillator_response("rk4", [0.1], v),
        "oscillator_map(h_omega)": lambda v: st.oscillator_map("rk4", v, [0.1]),
        "oscillator_limit(zeta)": lambda v: st.oscillator_limit("rk4", v),
        "step_matrices(a)": lambda v: st.step_matrices("rk4", v, 0.1),
        "step_matrices(h)": lambda v: st.step_matrices("rk4", np.eye(2), v),
        "linear_step_limits(jac)": lambda v: st.linear_step_limits("rk4", v),
        "linear_step_limits(t_span)": lambda v: st.linear_step_limits("rk4", -np.eye(2),
                                                                      t_span=v),
        "largest_stable_step(t_span)": lambda v: st.largest_stable_step("pendulum", "rk4",
                                                                        t_span=v),
        "equilibrium(y0)": lambda v: st.equilibrium("pendulum", y0=v),
        "history_length(method)": lambda v: st.history_length(v),
        "methods(solves)": lambda v: mbdk.methods(v),
        "methods(step)": lambda v: mbdk.methods(step=v),
        "scenes(kind)": lambda v: mbdk.scenes(v),
        "scene(name)": lambda v: mbdk.scene(v),
    }
    out = []
    for name, fn in calls.items():
        values = NOT_NAMES if name.endswith(("(method)", "(solves)", "(step)", "(kind)",
                                             "(name)")) else NOT_NUMBERS
        for v in values:
            out.append((f"{name} = {v!r:.40}", lambda fn=fn, v=v: fn(v)))
    return out


DOORS = ("scene file", "scene objects", "arguments", "scene paths", "functions")


def run(out: Path, quick: bool = False) -> dict:
    import tempfile
    out = Path(out)
    n_s, n_a = (150, 80) if quick else (600, 300)
    progress(f"fuzz: {n_s} broken scenes, {n_a} bad arguments")
    with tempfile.TemporaryDirectory() as tmp:
        rows = fuzz(Path(tmp), n_s, n_a)
    summary = []
    for door in DOORS:
        sub = [r for r in rows if r["door"] == door]
        summary.append({"door": door, "cases": len(sub),
                        **{k: sum(r["outcome"] == k for r in sub)
                           for k in ("success", "named", "generic", "nonfinite")},
                        "slowest_s": max(r["seconds"] for r in sub)})
    t1 = write_table(summary, ["door", "cases", "success", "named", "generic", "nonfinite",
                               "slowest_s"], out, "fuzz_summary",
                     "Bad input from five doors: outcomes (fixed seed)",
                     "generic (an exception that is not an mbdk.MbdkError) and nonfinite (a "
                     "success with inf or NaN) are defects; named errors say what to change. "
                     "slowest_s bounds a hang: every case runs a few steps.")
    defects = [r for r in rows if r["outcome"] in ("generic", "nonfinite")]
    t2 = write_table(defects or [{"door": "-", "case": "none", "outcome": "-", "detail": "-",
                                  "seconds": 0.0}],
                     ["door", "case", "outcome", "detail", "seconds"], out, "fuzz_defects",
                     "Cases that got a generic exception or a non-finite success",
                     "Each is a defect to fix; the test suite runs a subset and fails on any.")
    named = sum(r["named"] for r in summary)
    found = (f"{len(rows)} bad inputs from {len(DOORS)} doors: {named} named errors, "
             f"{len(defects)} defect{'s' if len(defects) != 1 else ''} (generic exception or "
             "non-finite success)")
    return {"title": "Fuzzing: broken scenes and bad arguments", "tables": [t1, t2],
            "figures": [], "findings": [found]}


if __name__ == "__main__":
    raise SystemExit(main(run, "fuzz"))
