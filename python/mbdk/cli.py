"""The `mbdk` command: `mbdk report`, `mbdk methods`, `mbdk problems`, `mbdk solve`,
`mbdk scene NAME|FILE [--symbolic]`."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path


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
    sc = sub.add_parser("scene", help="print a scene's report: coordinates, constraint rows, "
                        "degrees of freedom, redundant joints, each joint's class, the index")
    sc.add_argument("scene", help="a built-in scene's name or a scene file (TOML)")
    sc.add_argument("--symbolic", action="store_true",
                    help="also derive its equations with SymPy and compare with the kernel")
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
        elif args.cmd == "scene":
            from .scene import load_scene, scene as builtin
            from .scene_report import scene_report
            path = Path(args.scene)
            if path.suffix == ".toml" or path.exists():
                from .spatial import is_spatial, spatial_scene_from_dict
                import tomllib
                try:
                    data = tomllib.loads(path.read_text())
                except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
                    data = None     # load_scene names the problem
                sc = (spatial_scene_from_dict(data, str(path)) if data and is_spatial(data)
                      else load_scene(path))
            else:
                sc = builtin(args.scene)
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
        elif args.cmd == "solve":
            from .ode import solve_ode
            r = solve_ode(args.problem, args.method, h=args.h, t_end=args.t_end)
            print(f"t = {r.t[-1]:.10g}  y = {r.y[-1].tolist()}  steps = {r.stats.steps}  "
                  f"cpu = {r.cpu_time:.3g} s  status = {r.status.name}")
    except (MbdkError, FileNotFoundError) as exc:
        print(f"mbdk: {exc}", file=sys.stderr)
        return 2
    return 0
