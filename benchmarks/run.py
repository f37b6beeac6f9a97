"""Benchmark harness (a measurement, not a test: nothing here fails on time): mbdk's cost per
step against the size of the mechanism and against its peers, in one run on one machine.

What it measures, each as the solving thread's CPU time per step (the best of three runs) and
the wall time beside it:
  - open chains of N bars (mbdk.benchmarks.bar_chain, N = 2 .. 1024): mbdk's rk4 on the
    reduced formulation and trapezoidal_index3 (augmented Lagrangian), each on the path
    solver="auto" takes (dense up to 12 constraint rows, sparse AMD + LDL above), and the dense
    Schur path up to N = 256 for the crossing; Exudyn's generalized-alpha index-3 solver with
    its dense and its sparse (Eigen) linear solver on the same chain, when exudyn is installed
    (`pip install exudyn`; benchmarks/exudyn_chain.py);
  - the growth exponent p of cost ~ N^p, a least-squares fit over N = 8 .. 1024;
  - closed loops (the IFToMM A02 chain of n four-bar loops, mbdk.benchmarks.a02_chain) per step;
  - what one body costs per rk4 step (reduced formulation, h = 1e-4): the planar four-bar, the
    planar chain of 1024 bars, the heavy top, the spatial double pendulum, Bricard's linkage
    (IFToMM A04), the flyball governor (A05) and the spatial chain of 1024 bars, each as a
    ratio to a body of the four-bar and of the planar chain;
  - the minimal-coordinate double pendulum's rk4 step in the kernel against a plain scalar C
    loop doing the same arithmetic, compiled and timed in this run (studies/benchmark_rk4.py's
    yardstick), SciPy's solve_ivp RK45 on it, and the kernel's bdf against SUNDIALS CVODE
    driven from C with a C right-hand side (studies/cvode_yardstick.c), both to 1e-6;
  - mbdk's generalized_alpha against Exudyn's generalized-alpha index-3 solver on the same
    scenes, steps and rho_inf, agreement and cost per step (benchmarks/exudyn_alpha.py, when
    exudyn is installed).

Writes benchmarks/out/ (or --out): size.csv/.md, loops.csv/.md, per_body.csv/.md,
peers.csv/.md, size.png, exudyn_alpha*.csv/.md
(with Exudyn) and manifest.json (machine, versions, settings). `python benchmarks/run.py [--quick]`.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "studies"))

import mbdk  # noqa: E402
from mbdk.benchmarks import a02_chain, bar_chain, spatial_chain  # noqa: E402

H = 1e-4


def progress(msg: str) -> None:
    print(f"  .. {msg}", file=sys.stderr, flush=True)


def mbdk_step(scene, method: str, formulation: str, steps: int, solver: str = "auto",
              repeats: int = 3, coordinates: str = "absolute") -> dict:
    """Per-step thread CPU and wall time of a fixed-step run of `steps` steps (best of
    `repeats`), with no outputs sampled but the last state."""
    best = None
    for _ in range(repeats):
        r = mbdk.simulate(scene, method, formulation=formulation, h=H, t_end=steps * H,
                          every=steps, outputs=(), solver=solver,
                          **({"coordinates": coordinates} if coordinates != "absolute" else {}))
        cur = (r.cpu_time / steps, r.wall_time / steps)
        best = cur if best is None or cur[0] < best[0] else best
    return {"cpu": best[0], "wall": best[1], "path": r.manifest.get("linear_solve", "")}


def growth(ns, ts, n_min=8) -> float | None:
    pts = [(n, t) for n, t in zip(ns, ts) if n >= n_min and t]
    if len(pts) < 3:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def machine() -> dict:
    cpu = platform.processor()
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(),
            "platform": platform.platform(), "numpy": np.__version__}


def run(out: Path, quick: bool) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    ns = [2, 8, 32, 128, 512] if quick else [2, 4, 8, 16, 32, 64, 128, 256, 512, 1024]
    try:
        import exudyn_chain
        exu_version = exudyn_chain.available()
    except ImportError:
        exu_version = None
    rows = []
    for n in ns:
        sc = bar_chain(n)
        steps = max(20, min(2000, 40000 // n))
        row = {"N": n, "rows": 2 * n}
        for key, method, form in (("rk4", "rk4", "reduced"),
                                  ("index3", "trapezoidal_index3", "augmented_lagrangian")):
            progress(f"chain N = {n}: mbdk {key}")
            m = mbdk_step(sc, method, form, steps)
            row[f"mbdk {key} us"] = 1e6 * m["cpu"]
            row[f"mbdk {key} wall us"] = 1e6 * m["wall"]
            row[f"{key} path"] = m["path"].split(":")[0]
            if n <= 256:
                d = mbdk_step(sc, method, form, max(10, steps // 4), solver="schur", repeats=1)
                row[f"mbdk {key} dense us"] = 1e6 * d["cpu"]
        if exu_version:
            for solver in ("sparse", "dense"):
                if solver == "dense" and n > 256:
                    continue
                progress(f"chain N = {n}: Exudyn {solver}")
                e = exudyn_chain.chain_step_time(n, solver=solver, h=H,
                                                 steps=max(20, min(400, 8000 // n)))
                row[f"Exudyn {solver} us"] = 1e6 * e["per_step_cpu"]
        rows.append(row)
    agree = None
    if exu_version:
        # the same model in both: the free end of a 4-bar chain at t = 0.2 s (2000 steps)
        e = exudyn_chain.chain_step_time(4, solver="sparse", h=H, steps=2000)
        r = mbdk.simulate(bar_chain(4), "trapezoidal_index3", h=H, t_end=2000 * H, every=2000,
                          outputs=())
        x, y, th = r.q[-1][9:12]
        tip = np.array([x + 0.5 * np.cos(th), y + 0.5 * np.sin(th)])
        agree = float(np.max(np.abs(tip - np.asarray(e["tip"]))))
    cols = ["N", "rows", "mbdk rk4 us", "mbdk rk4 wall us", "rk4 path", "mbdk rk4 dense us",
            "mbdk index3 us", "mbdk index3 wall us", "index3 path", "mbdk index3 dense us"]
    if exu_version:
        cols += ["Exudyn sparse us", "Exudyn dense us"]
    exps = {c: growth([r["N"] for r in rows], [r.get(c) for r in rows])
            for c in ("mbdk rk4 us", "mbdk index3 us", "Exudyn sparse us")}
    write(rows, cols, out / "size", "Cost per step against the number of bars N (open chain, "
          f"h = {H:g}; thread CPU in us)",
          "growth exponents p (cost ~ N^p, N = 8..{}): ".format(ns[-1]) + ", ".join(
              f"{k.replace(' us', '')} {v:.2f}" for k, v in exps.items() if v is not None)
          + ("" if agree is None else f". mbdk and Exudyn agree on the free end of a 4-bar "
             f"chain at t = 0.2 s (h = {H:g}) to {agree:.1e} m"))

    # closed loops: the A02 chain of n four-bar loops, before its first singular crossing
    loops = []
    for n in ([1, 4, 16, 64] if quick else [1, 4, 16, 64, 256]):
        sc = a02_chain(n)
        progress(f"A02 loops n = {n}")
        row = {"loops": n, "rows": 2 * (2 * n + 1) + 2 * n}
        for key, method, form in (("rk4", "rk4", "reduced"),
                                  ("index3", "trapezoidal_index3", "augmented_lagrangian")):
            m = mbdk_step(sc, method, form, 50)
            row[f"mbdk {key} us"] = 1e6 * m["cpu"]
            row[f"{key} path"] = m["path"].split(":")[0]
        loops.append(row)
    write(loops, ["loops", "rows", "mbdk rk4 us", "rk4 path", "mbdk index3 us", "index3 path"],
          out / "loops", "Closed loops: IFToMM A02, cost per step (thread CPU, us)", "")

    per_body(out, quick)

    # the minimal rk4 loop against a plain C loop and SciPy, double pendulum P1
    import benchmark_rk4 as b4
    peers = []
    n_fast = 200_000 if quick else 1_000_000
    c_step = median_ratio = None
    with tempfile.TemporaryDirectory() as tmp:
        exe = b4.build_c(Path(tmp))
        if exe is not None:
            k_step, c_step, median_ratio, _, _ = b4.kernel_against_c(exe, n_fast, 1e-5)
            k_step, c_step = k_step / n_fast, c_step / n_fast
        else:
            k_step = b4.best_of(b4.kernel, n_fast, 1e-5)[0] / n_fast
    peers.append({"what": "rk4 step, double pendulum, minimal coordinates"
                          + (" (least of 7 runs taken in turn with the C loop; median ratio of "
                             f"the rounds {median_ratio:.2f})" if median_ratio else
                             " (no C compiler: no C loop)"),
                  "mbdk us": 1e6 * k_step, "peer": "plain scalar C loop (cc -O3)",
                  "peer us": 1e6 * c_step if c_step else None,
                  "ratio": k_step / c_step if c_step else None})
    try:
        from scipy.integrate import solve_ivp
        y0 = np.array(b4.Y0)
        t0 = time.thread_time()
        sol = solve_ivp(lambda t, y: b4.f_numpy(y), (0.0, 1.0), y0, method="RK45",
                        rtol=1e-8, atol=1e-10)
        dt = time.thread_time() - t0
        peers.append({"what": "adaptive RK45 step, double pendulum (rtol 1e-8)",
                      "mbdk us": None, "peer": "SciPy solve_ivp RK45 (Python right-hand side)",
                      "peer us": 1e6 * dt / max(1, sol.t.size - 1), "ratio": None})
        r = mbdk.solve_ode("double_pendulum", "dopri54", t_end=1.0, y0=y0, params=b4.P,
                           rtol=1e-8, atol=1e-10)
        peers[-1]["mbdk us"] = 1e6 * r.cpu_time / max(1, r.stats.steps)
        peers[-1]["ratio"] = peers[-1]["mbdk us"] / peers[-1]["peer us"]
    except Exception as exc:   # a missing SciPy leaves the row out, named
        progress(f"SciPy row left out: {exc}")
    peers.append(cvode_row(quick))
    for r in rows:
        if r["N"] == 64 and "Exudyn sparse us" in r:
            peers.append({"what": "index-3 step, chain of 64 bars", "mbdk us": r["mbdk index3 us"],
                          "peer": f"Exudyn {exu_version} generalized-alpha, sparse",
                          "peer us": r["Exudyn sparse us"],
                          "ratio": r["mbdk index3 us"] / r["Exudyn sparse us"]})
    write(peers, ["what", "mbdk us", "peer", "peer us", "ratio"], out / "peers",
          "mbdk against its peers (CPU time in us, per step or per whole solve as the row "
          "says; ratio = mbdk / peer)", "")
    plot(rows, out / "size.png")
    if exu_version:
        # the generalized-alpha scheme side by side: same scenes, steps and rho_inf
        import exudyn_alpha
        exudyn_alpha.run(out, quick)
    from mbdk.ode import build_info
    manifest = {"machine": machine(), "mbdk": build_info(), "exudyn": exu_version,
                "h": H, "growth_exponents": exps, "date": time.strftime("%Y-%m-%d"),
                "tip_agreement_m": agree,
                "timing": "thread CPU (CLOCK_THREAD_CPUTIME_ID) of the solve, best of 3"}
    (out / "manifest.json").write_text(json.dumps(manifest, indent=2))
    return manifest


def per_body(out: Path, quick: bool) -> list:
    """What one body costs per rk4 step (reduced formulation, the path solver="auto" takes),
    planar and spatial, measured one after the other in this run; ratios to a body of the
    planar four-bar (the scene with the planar model's closed-form 2 x 2 blocks) and of the
    planar chain of the same size as the spatial one. The compiled heavy top (minimal
    coordinates) closes the table: a spatial body without the constrained solve."""
    n_chain = 256 if quick else 1024
    scenes = [("four_bar", "planar", mbdk.scene("four_bar")),
              (f"bar chain N = {n_chain}", "planar", bar_chain(n_chain)),
              ("heavy_top", "spatial", mbdk.scene("heavy_top")),
              ("spatial_double_pendulum", "spatial", mbdk.scene("spatial_double_pendulum")),
              ("bricard (A04)", "spatial", mbdk.scene("bricard")),
              ("flyball_governor (A05)", "spatial", mbdk.scene("flyball_governor")),
              (f"spatial chain N = {n_chain}", "spatial", spatial_chain(n_chain))]
    rows = []
    # the small spatial scenes again in joint coordinates (kernel/src/spatial/
    # mbdk_joint_coords.f90): a long chain stays on the absolute model's sparse path
    scenes += [(f"{name}, joint coordinates", "spatial (joint)", sc)
               for name, model, sc in scenes if model == "spatial" and
               not name.startswith("spatial chain")]
    for name, model, sc in scenes:
        progress(f"per body: {name}")
        nb = len(sc.bodies)
        m = mbdk_step(sc, "rk4", "reduced", max(20, min(2000, 20000 // nb)),
                      repeats=3 if quick else 5,
                      coordinates="joint" if model == "spatial (joint)" else "absolute")
        rows.append({"scene": name, "model": model, "bodies": nb, "rows": sc.rows,
                     "us/step": 1e6 * m["cpu"], "us/body": 1e6 * m["cpu"] / nb,
                     "path": m["path"].split(":")[0].split(" (")[0]})
    # the same top in minimal coordinates: the compiled problem (Euler's equations about the
    # fixed point, the quaternion's kinematics; no constraint rows), as far from the scene's
    # absolute coordinates as a joint-coordinate formulation would take a spatial body
    progress("per body: heavy_top, compiled")
    steps = 20000
    best = min(mbdk.solve_ode("heavy_top", "rk4", h=H, t_end=steps * H, every=steps)
               .stats.cpu_time for _ in range(3 if quick else 5)) / steps
    rows.append({"scene": "heavy_top, compiled (minimal coordinates)", "model": "compiled",
                 "bodies": 1, "rows": 0, "us/step": 1e6 * best, "us/body": 1e6 * best,
                 "path": "Euler's equations"})
    four_bar, chain = rows[0]["us/body"], rows[1]["us/body"]
    for r in rows:
        r["/ four-bar body"] = r["us/body"] / four_bar
        r["/ planar chain body"] = r["us/body"] / chain
    write(rows, ["scene", "model", "bodies", "rows", "us/step", "us/body", "/ four-bar body",
                 "/ planar chain body", "path"], out / "per_body",
          f"What a body costs per rk4 step (reduced formulation, h = {H:g}; thread CPU in us, "
          "best of the runs)",
          "The four-bar's evaluation is the planar model's closed form (2 x 2 blocks, a few "
          "hundred instructions); a small closed spatial loop's is dense (its S of 20-30 rows "
          "and its Cholesky; on a loop that can near a rank loss, the geometry's second "
          "factorisation for the near-singular test only where S's pivots leave it open). The "
          "compiled heavy top is the scene's top in minimal coordinates (Euler's equations about "
          "its fixed point): what a spatial body costs without the absolute coordinates' "
          "constraint solve. The rows in joint coordinates integrate the joints' turns and "
          "slides (the governor's tree: four; Bricard's: five, its joint F cut and kept as "
          "rows; the heavy top's and the double pendulum's spherical joints: a quaternion "
          "each).")
    return rows


def cvode_row(quick: bool) -> dict:
    """The double pendulum P1 to 1e-6 in the angles at t = 10 s: the kernel's bdf against
    SUNDIALS CVODE (BDF) driven from a plain C program with a C right-hand side
    (studies/cvode_yardstick.c, built here), each at the loosest rtol on a grid of 10^(-k/4)
    that reaches the target; CPU time of the whole solve, the least of repeated runs."""
    import error_control as ec
    ref = mbdk.solve_ode("double_pendulum", "dopri54", t_end=10.0, rtol=1e-13, atol=1e-15)
    y_ref = ref.y[-1, :2]
    reps = 5 if quick else 50

    def loosest(solve):
        for k in range(16, 45):
            tol = 10.0 ** (-k / 4)
            y = solve(tol)
            if np.max(np.abs(y - y_ref)) <= 1e-6:
                return tol
        return None
    tol_k = loosest(lambda tol: mbdk.solve_ode("double_pendulum", "bdf", t_end=10.0, rtol=tol,
                                               atol=tol * 1e-2).y[-1, :2])
    k_cpu = (ec._least_cpu("bdf", reps, t_end=10.0, rtol=tol_k, atol=tol_k * 1e-2)[1]
             if tol_k else None)
    row = {"what": "error-controlled BDF, double pendulum to 1e-6 at t = 10 s (whole solve)",
           "mbdk us": 1e6 * k_cpu if k_cpu else None,
           "peer": "SUNDIALS CVODE from C, C right-hand side", "peer us": None, "ratio": None}
    p = mbdk.problems()["double_pendulum"]
    with tempfile.TemporaryDirectory() as tmp:
        exe, why = ec._yardstick(Path(tmp))
        if exe is None:
            progress(f"CVODE row left out: {why}")
            return row

        def c_run(tol, count):
            args = [str(exe), repr(tol), repr(tol * 1e-2), "10.0", str(count),
                    *(repr(float(p.params[k])) for k in ("m1", "m2", "l1", "l2", "g")),
                    *(repr(float(v)) for v in p.y0)]
            out = subprocess.run(args, check=True, capture_output=True, text=True).stdout.split()
            return float(out[0]), np.array([float(v) for v in out[3:5]])
        tol_c = loosest(lambda tol: c_run(tol, 1)[1])
        if tol_c:
            row["peer us"] = 1e6 * c_run(tol_c, reps)[0]     # the least of reps solves
            if k_cpu:
                row["ratio"] = row["mbdk us"] / row["peer us"]
    return row


def write(rows, cols, stem: Path, title: str, notes: str) -> None:
    def fmt(v):
        if v is None:
            return ""
        if isinstance(v, float):
            return f"{v:.3g}"
        return str(v)
    with open(stem.with_suffix(".csv"), "w") as fh:
        fh.write(",".join(cols) + "\n")
        for r in rows:
            fh.write(",".join(fmt(r.get(c)) for c in cols) + "\n")
    md = [f"### {title}", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    md += ["| " + " | ".join(fmt(r.get(c)) for c in cols) + " |" for r in rows]
    if notes:
        md += ["", notes]
    stem.with_suffix(".md").write_text("\n".join(md) + "\n")
    print("\n".join(md) + "\n")


def plot(rows, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    ns = [r["N"] for r in rows]
    for col, style in (("mbdk rk4 us", "o-"), ("mbdk index3 us", "s-"),
                       ("mbdk rk4 dense us", "o:"), ("mbdk index3 dense us", "s:"),
                       ("Exudyn sparse us", "^-"), ("Exudyn dense us", "^:")):
        pts = [(n, r[col]) for n, r in zip(ns, rows) if r.get(col)]
        if pts:
            ax.loglog(*zip(*pts), style, label=col.replace(" us", ""))
    ax.loglog(ns, [ns[0] and rows[0]["mbdk rk4 us"] * n / ns[0] for n in ns], "k--", lw=0.8,
              label="~ N")
    ax.set_xlabel("bars N")
    ax.set_ylabel("thread CPU per step [us]")
    ax.set_title("Open chain: cost per step against size")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer sizes and shorter runs")
    ap.add_argument("--out", type=Path, default=HERE / "out")
    args = ap.parse_args()
    t0 = time.perf_counter()
    run(args.out, args.quick)
    print(f"benchmarks: written to {args.out} ({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
