#!/usr/bin/env python
"""Per-step cost of a spatial chain against its size (issue 40): mbdk.benchmarks.spatial_chain(N),
N bars on spherical joints (3 N rows) released from a zigzag, from N = 2 up.

mbdk: rk4 on the reduced formulation, h = 1e-4, the solving thread's CPU time per step (two run
lengths differenced, so that set-up and output cancel), best of three. Above
MBDK_SPATIAL_SPARSE_ROWS rows (12: N >= 5) its constrained solve goes by compact rows and the
sparse LDL^T of S = C M^-1 C^T (the manifest names the path); below, by the dense Cholesky.

Exudyn (where --exudyn-python names a Python with exudyn installed; 1.13.6 measured): the same
chain (NodeRigidBodyEP, ObjectRigidBody, ObjectJointSpherical, gravity by
LoadMassProportional), run in the same invocation, one size after the other, by its implicit
generalized-alpha (spectral radius 0.8, index-3 constraints, fixed step, EigenSparse, one
thread), its CPU time per step differenced the same way. Exudyn's explicit solvers take no
joints (its documentation, ExplicitSolvers.rst), so rk4 against it compares each code's
cheapest way to step the same mechanism at this step size, not the same method: that ratio
says what a step costs, not which integrator is better. The same method is the next column:
mbdk's generalized_alpha at rho_inf = 0.8 in the book's index-3 form (formulation "index3",
as Exudyn's useIndex2Constraints = False), its Newton matrix above 12 rows the model's sparse
one (kernel/src/spatial/mbdk_spatial_i3.f90), Newton iterations per step in the last column.

usage: python benchmarks/spatial_chain.py [--sizes 2,4,8,...] [--exudyn-python PATH] [--quick]
"""
import argparse
import json
import math
import subprocess
import sys
import warnings

import mbdk
from mbdk.benchmarks import spatial_chain

H = 1e-4

EXUDYN = r'''
import json, sys, time
import numpy as np
import exudyn as exu
from exudyn.itemInterface import *
n, steps, h = int(sys.argv[1]), [int(s) for s in sys.argv[2].split(",")], float(sys.argv[3])
bend = 0.3
def build():
    SC = exu.SystemContainer(); mbs = SC.AddSystem()
    ground = mbs.AddObject(ObjectGround())
    prev = mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground, localPosition=[0, 0, 0]))
    p = np.zeros(3); ex = np.array([1.0, 0, 0])
    J = np.diag([1e-6 / 12, 1 / 12, 1 / 12])   # the bar shape of mbdk: 1 m, 1 kg, axial 1e-6 of the rest
    for i in range(n):
        a = bend if i % 2 else -bend
        d = np.array([np.cos(a), 0.5 * np.sin(a), 0.5 * np.sin(a)]); d /= np.linalg.norm(d)
        half = (ex + d) / np.linalg.norm(ex + d)
        ep = [float(half @ ex), *np.cross(ex, half)]
        node = mbs.AddNode(NodeRigidBodyEP(referenceCoordinates=list(p + 0.5 * d) + ep))
        body = mbs.AddObject(ObjectRigidBody(physicsMass=1.0, physicsInertia=[J[0, 0], J[1, 1], J[2, 2], 0, 0, 0],
                                             nodeNumber=node))
        left = mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[-0.5, 0, 0]))
        mbs.AddObject(ObjectJointSpherical(markerNumbers=[prev, left]))
        prev = mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[0.5, 0, 0]))
        com = mbs.AddMarker(MarkerBodyMass(bodyNumber=body))
        mbs.AddLoad(LoadMassProportional(markerNumber=com, loadVector=[0, -9.81, 0]))
        p = p + d
    mbs.Assemble()
    return SC, mbs
def run(k):
    SC, mbs = build()
    s = exu.SimulationSettings()
    ti = s.timeIntegration
    # the settings of benchmarks/exudyn_chain.py (the planar chains' run)
    ti.numberOfSteps = k; ti.endTime = k * h; ti.adaptiveStep = False
    ti.verboseMode = 0; ti.verboseModeFile = 0; ti.stepInformation = 0
    ti.generalizedAlpha.spectralRadius = 0.8
    ti.generalizedAlpha.useIndex2Constraints = False; ti.generalizedAlpha.useNewmark = False
    s.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    s.solution.file.write = False
    s.solution.sensors.active = False
    s.solution.sensors.writePeriod = 1e30
    s.solution.restart.write = False
    s.show.computationTime = False; s.show.statistics = False; s.show.globalTimers = False
    s.parallel.numberOfThreads = 1
    t = time.thread_time()
    mbs.SolveDynamic(s)
    return time.thread_time() - t
best = {k: min(run(k) for _ in range(3)) for k in steps}
k1, k2 = steps
print(json.dumps({"us_per_step": (best[k2] - best[k1]) / (k2 - k1) * 1e6, "version": exu.__version__}))
'''


def mbdk_step_cost(n: int, steps: tuple, method: str = "rk4") -> tuple[float, str, float]:
    """mbdk's CPU seconds per step on the chain of n bars by rk4 (reduced formulation) or
    generalized_alpha (rho_inf 0.8, index3), its linear solve's path, and Newton iterations per
    step (0 for rk4)."""
    sc = spatial_chain(n)
    kw = (dict(formulation="reduced") if method == "rk4" else
          dict(formulation="index3", rho_inf=0.8))
    best, path, iters = {}, "", 0.0
    for k in steps:
        runs = []
        for _ in range(3):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = mbdk.simulate(sc, method, h=H, t_end=k * H, every=k, outputs=(), watch=False,
                                  **kw)
            runs.append(r.stats.cpu_time)
            path = r.manifest["linear_solve"]
            iters = r.stats.newton_iterations / max(r.stats.steps, 1)
        best[k] = min(runs)
    k1, k2 = steps
    return (best[k2] - best[k1]) / (k2 - k1), path, iters


def exudyn_step_cost(python: str, n: int, steps: tuple) -> float | None:
    run = subprocess.run([python, "-c", EXUDYN, str(n), ",".join(map(str, steps)), repr(H)],
                         capture_output=True, text=True, timeout=3600)
    if run.returncode:
        print(f"  exudyn failed at N = {n}: {run.stderr.strip().splitlines()[-1:]}",
              file=sys.stderr)
        return None
    return json.loads(run.stdout.strip().splitlines()[-1])["us_per_step"] * 1e-6


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default=None, help="N values, comma-separated")
    ap.add_argument("--exudyn-python", default=None, help="a Python with exudyn installed")
    ap.add_argument("--quick", action="store_true", help="N up to 128")
    args = ap.parse_args(argv)
    sizes = ([int(x) for x in args.sizes.split(",")] if args.sizes else
             [2, 4, 8, 16, 32, 64, 128] + ([] if args.quick else [256, 512, 1024, 4096, 10000]))
    print(f"{'N':>6} {'rows':>6} {'mbdk rk4 us/step':>17} {'growth':>7} "
          f"{'exudyn GA us/step':>18} {'rk4/exudyn':>11} {'mbdk GA us/step':>16} "
          f"{'growth':>7} {'GA/exudyn':>10} {'it/step':>8}  path")
    prev = prev_ga = None
    dash = chr(45)
    for n in sizes:
        steps = (20, 60) if n >= 256 else (100, 300)
        cost, path, _ = mbdk_step_cost(n, steps)
        ga, _, iters = mbdk_step_cost(n, steps, "generalized_alpha")
        growth = (f"{math.log(cost / prev[1]) / math.log(n / prev[0]):7.2f}" if prev else
                  f"{'':>7}")
        growth_ga = (f"{math.log(ga / prev_ga[1]) / math.log(n / prev_ga[0]):7.2f}"
                     if prev_ga else f"{'':>7}")
        prev, prev_ga = (n, cost), (n, ga)
        exu = exudyn_step_cost(args.exudyn_python, n, steps) if args.exudyn_python else None
        print(f"{n:6d} {3 * n:6d} {cost * 1e6:17.1f} {growth} "
              f"{(f'{exu * 1e6:18.1f}' if exu else f'{dash:>18}')} "
              f"{(f'{cost / exu:11.2f}' if exu else f'{dash:>11}')} "
              f"{ga * 1e6:16.1f} {growth_ga} "
              f"{(f'{ga / exu:10.2f}' if exu else f'{dash:>10}')} {iters:8.2f}  "
              f"{'sparse' if 'sparse' in path else 'dense'}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
