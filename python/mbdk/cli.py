"""The `mbdk` command: `mbdk report`, `mbdk methods`, `mbdk problems`, `mbdk solve`,
`mbdk scene|check NAME|FILE [--symbolic]`, `mbdk run SCENE ... --out FILE`, `mbdk plot FILE`.

    mbdk run my_scene.toml --method rk4 --h 1e-3 --t-end 10 --out run.npz
    mbdk plot run.npz                     # run.png: coordinates, energy balance, residuals

Errors print the named message (no traceback; --traceback shows it) and exit with status 2;
a run that fails writes no result file."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .errors import MbdkError as MbdkErrorBase


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="mbdk", description="mbdk: compiled multibody-dynamics "
                                 "kernel and its integrator studies")
    sub = ap.add_subparsers(dest="cmd", required=True)
    rp = sub.add_parser("report", help="run every study and write one HTML report")
    rp.add_argument("--out", type=Path, default=Path("report"))
    rp.add_argument("--quick", action="store_true", help="coarser, faster runs")
    rp.add_argument("--studies", type=Path, default=None, help="the studies/ folder")
    rp.add_argument("--only", nargs="*", default=None, help="run only these studies")
    sub.add_parser("methods", help="list the methods")
    sub.add_parser("problems", help="list the compiled problems")
    sp = sub.add_parser("solve", help="solve a compiled problem and print the last sample")
    sp.add_argument("problem")
    sp.add_argument("method")
    sp.add_argument("--h", type=float, required=True)
    sp.add_argument("--t-end", type=float, required=True)
    sc = sub.add_parser("scene", aliases=["check"],
                        help="check a scene and print its report: coordinates, constraint rows, "
                        "degrees of freedom, redundant joints, each joint's class, the index")
    sc.add_argument("scene", help="a built-in scene's name or a scene file (TOML)")
    sc.add_argument("--symbolic", action="store_true",
                    help="also derive its equations with SymPy and compare with the kernel")
    run = sub.add_parser("run", help="run a scene and save its samples with the manifest")
    run.add_argument("scene", help="a built-in scene's name or a scene file (TOML)")
    run.add_argument("--method", required=True, help="a method of mbdk methods")
    run.add_argument("--formulation", default=None)
    run.add_argument("--h", type=float, default=None, help="the step (fixed-step methods)")
    run.add_argument("--rtol", type=float, default=None, help="error-controlled methods")
    run.add_argument("--atol", type=float, default=None)
    run.add_argument("--dt-out", type=float, default=None,
                     help="the samples' spacing (error-controlled methods)")
    run.add_argument("--t-end", type=float, required=True)
    run.add_argument("--t0", type=float, default=0.0)
    run.add_argument("--every", type=int, default=1, help="keep every k-th step (fixed step)")
    run.add_argument("--out", type=Path, required=True,
                     help="the result file: .npz, .csv or .h5 (h5py)")
    sw = sub.add_parser("sweep", help="run a grid of runs on Dask and write its table (CSV)")
    sw.add_argument("grid", type=Path,
                    help="a TOML file with a [sweep] table or [[sweep]] tables (mbdk.sweep)")
    sw.add_argument("--workers", type=int, default=2,
                    help="local worker processes (0: serially in this process)")
    sw.add_argument("--scheduler", default=None,
                    help="the address of an existing Dask scheduler, tcp://host:port")
    sw.add_argument("--out", type=Path, required=True, help="the table (CSV)")
    pl = sub.add_parser("plot", help="plot a saved result (PNG)")
    pl.add_argument("result", type=Path)
    pl.add_argument("--out", type=Path, default=None, help="the PNG (default: beside the result)")
    for p in (rp, sp, sc, run, pl, sw):
        p.add_argument("--traceback", action="store_true", help="show the traceback of errors")
    args = ap.parse_args(argv)

    from . import MbdkError
    try:
        if args.cmd == "report":
            from .report import build_report
            build_report(args.out, quick=args.quick, studies=args.studies, only=args.only)
        elif args.cmd == "methods":
            from .methods import methods
            for m in methods().values():
                print(f"{m.name:16s} order {m.order}  {'implicit' if m.implicit else 'explicit'}"
                      f"  {m.stability}  [{m.reference}]")
        elif args.cmd == "problems":
            from .problems import problems
            for p in problems().values():
                print(f"{p.name:18s} n={p.n or 'len(y0)'}  {p.equation}  params {p.params}  "
                      f"[{p.reference}]")
        elif args.cmd in ("scene", "check"):
            from .scene import scene_or_file
            from .scene_report import scene_report
            sc = scene_or_file(args.scene)
            print(scene_report(sc))
            if args.symbolic:
                from .symbolic import cross_check
                r = cross_check(sc)
                print("symbolic cross-check (SymPy, max relative difference at 5 random "
                      "states): " + ", ".join(f"{k} {r[k]:.1e}" for k in
                                              ("phi", "D", "gamma", "phit", "f", "a", "lam")
                                              if r[k] is not None)
                      + (" (f from the kernel: contacts)" if r["f_from_kernel"] else "")
                      + f"; derivation {r['derive_s']:.2f} s CPU")
        elif args.cmd == "run":
            _run(args)
        elif args.cmd == "sweep":
            from .results_io import check_writable
            from .sweep import load_grid, sweep
            if args.out.suffix.lower() != ".csv":
                from .errors import InvalidInputError
                raise InvalidInputError(f"{args.out}: a sweep's table is a CSV file; give a name "
                                "ending in .csv")
            check_writable(args.out)
            table = sweep(load_grid(args.grid), workers=args.workers, scheduler=args.scheduler)
            table.to_csv(args.out)
            failed = sum(r["status"] != "SUCCESS" for r in table.rows)
            print(f"{len(table.rows)} runs on {table.engine} in {table.wall_time:.3g} s "
                  f"({failed} failed); wrote {args.out}")
        elif args.cmd == "plot":
            from .results_io import plot_result
            print(f"wrote {plot_result(args.result, args.out)}")
        elif args.cmd == "solve":
            from .ode import solve_ode
            r = solve_ode(args.problem, args.method, h=args.h, t_end=args.t_end)
            print(f"t = {r.t[-1]:.10g}  y = {r.y[-1].tolist()}  steps = {r.stats.steps}  "
                  f"cpu = {r.cpu_time:.3g} s  status = {r.status.name}")
    except (MbdkError, FileNotFoundError) as exc:
        if getattr(args, "traceback", False):
            raise
        print(f"mbdk: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    return 0


def _run(args) -> None:
    """mbdk run: the scene run, a summary on one screen, the result file (written only when
    the run succeeded)."""
    import numpy as np

    from .results_io import check_writable, save_result
    from .scene import scene_or_file
    from .simulate import simulate
    out = check_writable(args.out)
    sc = scene_or_file(args.scene)
    kw = {k: v for k, v in (("h", args.h), ("rtol", args.rtol), ("atol", args.atol),
                            ("dt_out", args.dt_out), ("formulation", args.formulation))
          if v is not None}
    if args.every != 1:
        kw["every"] = args.every
    r = simulate(sc, args.method, t_end=args.t_end, t0=args.t0, **kw)
    m = r.manifest
    control = (f"h = {args.h:g}" if args.h else
               f"rtol = {m.get('rtol', args.rtol)}, atol = {m.get('atol', args.atol)}")
    print(f"scene {sc.name!r}: {args.method}/{m.get('formulation', '')}, {control}, "
          f"t = {r.t[0]:g} .. {r.t[-1]:g}")
    print(f"status {r.status.name}; {r.stats.steps} steps; CPU {1e3 * r.cpu_time:.3g} ms "
          f"(the solving thread), wall {1e3 * r.stats.wall_time:.3g} ms")
    if r.residuals is not None and len(r.residuals):
        res = np.max(np.abs(r.residuals), axis=0)
        print(f"residuals (max over the samples): |Phi| {res[0]:.2e}, |Phi'| {res[1]:.2e}")
    if getattr(r, "energy", None) is not None:
        try:
            bal = float(np.max(np.abs(r.energy_balance())))
            print(f"energy balance: max |E - E0 - W| {bal:.2e} J (E0 = {r.energy[0]:.6g} J)")
        except MbdkErrorBase:
            pass
    save_result(r, out)
    print(f"wrote {out} ({len(r.t)} samples, with the manifest)")
