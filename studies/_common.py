"""Shared command line of the study scripts: --quick, --out."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def main(run, default_name: str) -> int:
    ap = argparse.ArgumentParser(description=(run.__module__ and sys.modules[run.__module__].__doc__
                                              or "").split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer and coarser runs (seconds)")
    ap.add_argument("--out", type=Path, default=Path("studies/out") / default_name,
                    help="output folder for CSV, Markdown and PNG")
    args = ap.parse_args()
    t0 = time.perf_counter()
    summary = run(args.out, args.quick)
    print(f"{default_name}: {len(summary.get('tables', []))} tables, "
          f"{len(summary.get('figures', []))} figures in {args.out} "
          f"({time.perf_counter() - t0:.1f} s)")
    return 0


def progress(msg: str) -> None:
    """A study's step, on standard error (above the report's bar where there is one)."""
    from mbdk._compiled import print_line
    print_line(f"  .. {msg}", file=sys.stderr)


def study_workers() -> int:
    """Local Dask worker processes for a study's sweep: MBDK_STUDY_WORKERS (0: serially in this
    process), default 2 where dask.distributed is installed, else 0. Every engine gives the
    same bits (mbdk.sweep); the CPU times are each run's own thread's."""
    import os
    v = os.environ.get("MBDK_STUDY_WORKERS")
    if v is not None:
        try:
            n = int(v)
        except ValueError:
            raise SystemExit(f"MBDK_STUDY_WORKERS = {v!r}: give a whole number >= 0") from None
        if n < 0:
            raise SystemExit(f"MBDK_STUDY_WORKERS = {v!r}: give a whole number >= 0")
        return n
    import importlib.util
    return 2 if importlib.util.find_spec("distributed") is not None else 0
