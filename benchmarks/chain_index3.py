#!/usr/bin/env python
"""trapezoidal_index3 on long chains (issue 40): Newton iterations per step and CPU per step
against the number of bars, the book's scheme (formulation "index3") beside the augmented
Lagrangian. Planar: mbdk.benchmarks.bar_chain(N, 30 degrees), the Newton matrix analytic and
sparse above 12 rows (kernel/src/dae/mbdk_index3_matrix.f90). Spatial (--spatial):
mbdk.benchmarks.spatial_chain(N), spherical joints released from a zigzag out of its plane,
the model's sparse matrix by colored differences (kernel/src/spatial/mbdk_spatial_i3.f90).

h = 1e-3 to t_end (0.2 s; --quick 0.05 s), one run each: whether it reaches t_end (else where
and by which error), Newton iterations per step, matrices factorised, the solving thread's CPU
per step (the run's own cpu_time: set-up and output included, negligible at these lengths), the
wall time and the peak resident memory of this process so far.

usage: python benchmarks/chain_index3.py [--sizes 10,100,...] [--quick] [--spatial]
"""
import argparse
import resource
import time
import warnings

import mbdk
from mbdk.benchmarks import bar_chain, spatial_chain


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10,100,1000,3000,10000")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--spatial", action="store_true", help="spatial bars on spherical joints")
    args = ap.parse_args()
    t_end = 0.05 if args.quick else 0.2
    sizes = [int(x) for x in args.sizes.split(",")]
    what = ("spatial chains released from a zigzag" if args.spatial else
            "bar chains from 30 degrees")
    print(f"mbdk {mbdk.__version__}: {what}, h = 1e-3, t_end = {t_end} s")
    print(f"{'N':>6} {'formulation':<22} {'reached':>8} {'it/step':>8} {'LU':>6} "
          f"{'CPU us/step':>12} {'wall s':>8} {'peak MB':>8}  error")
    warnings.simplefilter("ignore", mbdk.AccuracyWarning)
    for n in sizes:
        sc = spatial_chain(n) if args.spatial else bar_chain(n, 30.0)
        for form in ("index3", "augmented_lagrangian"):
            w0 = time.perf_counter()
            r = mbdk.simulate(sc, "trapezoidal_index3", h=1e-3, t_end=t_end, formulation=form,
                              outputs=(), raise_on_failure=False)
            wall = time.perf_counter() - w0
            steps = max(r.stats.steps, 1)
            err = "" if r.success else r.manifest.get("error", r.status.name)
            peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
            print(f"{n:>6} {form:<22} {r.t[-1]:>8.3f} {r.stats.newton_iterations / steps:>8.2f} "
                  f"{r.stats.nlu:>6} {1e6 * r.cpu_time / steps:>12.1f} {wall:>8.2f} "
                  f"{peak:>8.0f}  {err}", flush=True)


if __name__ == "__main__":
    main()
