"""The `mbdk` command: `mbdk report`, `mbdk methods`, `mbdk problems`, `mbdk solve`."""
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
        elif args.cmd == "solve":
            from .ode import solve_ode
            r = solve_ode(args.problem, args.method, h=args.h, t_end=args.t_end)
            print(f"t = {r.t[-1]:.10g}  y = {r.y[-1].tolist()}  steps = {r.stats.steps}  "
                  f"cpu = {r.cpu_time:.3g} s  status = {r.status.name}")
    except (MbdkError, FileNotFoundError) as exc:
        print(f"mbdk: {exc}", file=sys.stderr)
        return 2
    return 0
