"""Every built-in scene in motion: a short run of each, replayed from its own samples.

Each built-in scene (mbdk.scenes("all"): planar and spatial) runs for a few seconds and its
samples are drawn as an animation (mbdk.animation): planar scenes in their plane, spatial ones
in an orthographic view the reader turns by dragging; bodies as lines from their centres to
their joints' points, joints as dots, ground points as squares. Nothing is interpolated: a frame is a sample, shown
at its time. The runs are dopri54 at rtol 1e-8 sampled every t_end / 200, except the
redundant parallelogram, which only the index-3 family runs (its joints' rows are dependent:
the ODE formulations refuse it by name) and runs by trapezoidal_index3 at h = 1e-2. The table
says what each run cost and how large its animation is.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import mbdk
from mbdk.analysis.tables import write_table
from mbdk.animation import animation_html, player_script

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import main, progress  # noqa: E402

#: seconds of motion per scene: a swing or two of the pendulums, a few turns of the top
T_END = 3.0
SAMPLES = 200
#: scenes the ODE formulations refuse (dependent joint rows): run by the index-3 family
INDEX3 = {"parallelogram_redundant": ("trapezoidal_index3", {"h": 1e-2})}


def run(out: Path, quick: bool = False) -> dict:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rows, parts = [], []
    for name in mbdk.scenes("all"):
        progress(f"animation: {name}")
        sc = mbdk.scene(name)
        method, kw = INDEX3.get(name, ("dopri54", {"rtol": 1e-8, "atol": 1e-10,
                                                   "dt_out": T_END / SAMPLES}))
        t0 = time.perf_counter()
        r = mbdk.simulate(sc, method, t_end=T_END, **kw)
        fragment = animation_html(r, sc, title=f"{name} ({sc.kind}): {method}, "
                                  f"{len(r.t)} samples")
        rows.append({"scene": name, "kind": sc.kind, "method": method, "t_end": T_END,
                     "samples": len(r.t), "status": r.status.name,
                     "cpu_ms": 1e3 * r.cpu_time,
                     "wall_ms": 1e3 * (time.perf_counter() - t0),
                     "page_kB": len(fragment.encode()) / 1e3})
        parts.append(fragment)
    redundant = redundant_line()
    table = write_table(rows, list(rows[0]), out, "scene_motion",
                        "The runs animated", "cpu_ms: the solving thread's CPU time; wall_ms: "
                        "the run and its drawing's data; page_kB: the animation's HTML "
                        "(its samples' points at five significant digits).")
    spatial = sum(r["kind"] == "spatial" for r in rows)
    found = [f"{len(rows)} built-in scenes animated from their own samples ({spatial} spatial, "
             f"turned by dragging); play, pause, a time slider, loop"]
    return {"title": "Every built-in scene in motion (animations)", "tables": [table],
            "figures": [], "findings": found, "hard_cases": {"redundant joints": redundant},
            # the player after the animations: it starts those already on the page
            "html": ["<div style='display:flex;flex-wrap:wrap;gap:8px'>" + "".join(parts)
                     + "</div>" + player_script()]}


def redundant_line() -> str:
    """What the redundant parallelogram meets: an ODE formulation refuses it by name, the
    index-3 family runs it (its animation above) and holds its joints."""
    sc = mbdk.scene("parallelogram_redundant")
    try:
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01, formulation="projection")
        refused = "rk4/projection runs it"
    except mbdk.MbdkError as err:
        refused = f"rk4/projection refused by name ({type(err).__name__})"
    method, kw = INDEX3["parallelogram_redundant"]
    r = mbdk.simulate(sc, method, t_end=T_END, outputs=("residuals",), **kw)
    return (f"parallelogram_redundant: {refused}; {method} runs it, max |Phi| "
            f"{float(r.residuals[:, 0].max()):.1e} over {T_END:g} s")


if __name__ == "__main__":
    sys.exit(main(run, "scene_motion"))
