#!/usr/bin/env python
"""bdf and ida on the DAE itself (bdf's i3 and si2 forms as GSTIFF's, ida's index1 and ggl) on
long chains (issue 40): what a run costs against the number of bars, the sparse Newton matrix
(the body graph's pattern and colored differences: bdf's by a sparse L D U,
kernel/src/dae/mbdk_mechanism_dae.f90; ida's by SUNDIALS' KLU, kernel/src/sundials/mbdk_ida.f90)
beside the dense one of the same scene where it still fits (planar: solver="schur", whose rows
are dense; --dense-max bars).
Planar: mbdk.benchmarks.bar_chain(N, 30 degrees); spatial (--spatial): spatial_chain(N),
spherical joints released from a zigzag out of its plane (the spatial model has no dense
choice on a chain: no dense column).

rtol 1e-6, atol 1e-8 to t_end (0.01 s), one run each: whether it reaches t_end (else where and
by which error), the error of the bars' coordinates at t_end against the same path at rtol
1e-8, atol 1e-8 (max over the coordinates, m and rad; "(ref stops)" where that run stopped by
ERR_TOO_MUCH_ACCURACY, as it does on the longest planar chains, whose coordinates of 10^3 m and
more put the Newton update's roundoff floor above a thousandth of so tight an error test),
steps, Newton iterations, Newton
matrices factorised, evaluations of G per Jacobian, the solving thread's CPU for the run (its
own cpu_time), the dense path's CPU and the ratio, and the peak resident memory of this process
so far.

usage: python benchmarks/chain_dae.py [--sizes 10,100,...] [--spatial] [--dense-max 256]
                                     [--methods bdf,ida]
"""
import argparse
import resource
import warnings

import numpy as np

import mbdk
from mbdk.benchmarks import bar_chain, spatial_chain


FORMS = {"bdf": ("si2", "i3"), "ida": ("index1", "ggl")}


def run(sc, method, form, rtol, atol, t_end, **kw):
    return mbdk.simulate(sc, method, formulation=form, rtol=rtol, atol=atol, t_end=t_end,
                         dt_out=t_end, raise_on_failure=False, **kw)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10,100,1000,3000,10000")
    ap.add_argument("--spatial", action="store_true", help="spatial bars on spherical joints")
    ap.add_argument("--dense-max", type=int, default=256,
                    help="the largest planar chain run on the dense path too")
    ap.add_argument("--t-end", type=float, default=0.01)
    ap.add_argument("--methods", default="bdf,ida")
    args = ap.parse_args()
    methods = args.methods.split(",")
    sizes = [int(x) for x in args.sizes.split(",")]
    what = ("spatial chains released from a zigzag" if args.spatial else
            "bar chains from 30 degrees")
    print(f"mbdk {mbdk.__version__}: {'/'.join(methods)} on the DAE, {what}, rtol 1e-6, "
          f"atol 1e-8, t_end = {args.t_end} s")
    print(f"{'N':>6} {'method':<7}{'form':<7} {'reached':>8} {'error':>11} {'steps':>6} "
          f"{'Newton':>7} "
          f"{'LU':>4} {'G/Jac':>6} {'CPU s':>9} {'dense CPU s':>12} {'ratio':>7} "
          f"{'peak MB':>8}  failure")
    warnings.simplefilter("ignore", mbdk.AccuracyWarning)
    for n in sizes:
        sc = spatial_chain(n) if args.spatial else bar_chain(n, 30.0)
        for method, form in [(m, f) for m in methods for f in FORMS[m]]:
            r = run(sc, method, form, 1e-6, 1e-8, args.t_end)
            ref = run(sc, method, form, 1e-8, 1e-8, args.t_end)
            err = "" if not r.success else (f"{np.abs(r.q[-1] - ref.q[-1]).max():.1e}"
                                            if ref.success else "(ref stops)")
            dense = ""
            ratio = ""
            if not args.spatial and n <= args.dense_max:
                d = run(sc, method, form, 1e-6, 1e-8, args.t_end, solver="schur")
                dense = f"{d.cpu_time:.4f}"
                ratio = f"{r.cpu_time / d.cpu_time:.4f}" if d.success else ""
            st = r.stats
            per_jac = (st.nfev - st.newton_iterations) / max(st.njev, 1)
            peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
            fail = "" if r.success else r.manifest.get("error", r.status.name)
            print(f"{n:>6} {method:<7}{form:<7} {r.t[-1]:>8.4f} {err:>11} {st.steps:>6} "
                  f"{st.newton_iterations:>7} {st.nlu:>4} {per_jac:>6.1f} {r.cpu_time:>9.4f} "
                  f"{dense:>12} {ratio:>7} {peak:>8.0f}  {fail}", flush=True)


if __name__ == "__main__":
    main()
