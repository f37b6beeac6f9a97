"""Per-step cost of Exudyn on a planar chain of N rigid bars on revolute joints.

Reference numbers for the benchmark table that compares our kernel's per-step
cost against Exudyn (https://github.com/jgerstmayr/EXUDYN, tested with 1.13.6).

Model (identical to ours): N uniform bars, length 1 m, mass 1 kg, centroidal
inertia 1/12 kg m^2, horizontal and at rest at t = 0, bar i's centre at
(i + 0.5, 0). Bar 0's left end is hinged to the ground at the origin; bar i's
left end (-0.5, 0) is hinged to bar i-1's right end (+0.5, 0). Gravity
(0, -9.81). Each bar is an ObjectRigidBody2D (coordinates x, y, angle), each
hinge an ObjectJointRevolute2D between MarkerBodyPosition markers.

Solver: Exudyn's implicit generalized-alpha with index-3 constraints
(useIndex2Constraints = False, useNewmark = False, spectralRadius 0.8), fixed
step h (adaptiveStep = False), default Newton settings (modified Newton,
relative tolerance 1e-8), single thread, with either the dense (EXUdense) or
the sparse (EigenSparse) linear solver. Files, sensors, solver console
output and rendering are all off (Exudyn still prints an advisory warning
on each dense solve with more than 1000 unknowns, i.e. N = 512).

What is timed: only the exu.SolveDynamic call for `steps` steps, with
time.thread_time() (CPU) and time.perf_counter() (wall). That call also
includes Exudyn's per-solve set-up (initial accelerations, system matrix
allocation), amortised over `steps`. Exudyn's modified Newton factorizes the
Jacobian only a few times per run (1-5 for 200 steps here, about 3 Newton
iterations per step), so for large N with the dense solver the per-step
number is mostly those few O(n^3) factorizations spread over the steps.
The solve is repeated 3 times from the same initial state and the minimum is
reported. Model building and Assemble are reported separately as setup_wall.

Run as a script to print the table; needs numpy and exudyn only.
"""
import time

try:
    import exudyn as exu
    from exudyn.itemInterface import (
        LoadMassProportional, MarkerBodyMass, MarkerBodyPosition,
        NodeRigidBody2D, ObjectGround, ObjectJointRevolute2D,
        ObjectRigidBody2D,
    )
except ImportError:
    exu = None

GRAVITY = (0.0, -9.81, 0.0)
REPEATS = 3

_SOLVERS = {"dense": "EXUdense", "sparse": "EigenSparse"}


def available():
    """Exudyn's version string, or None when exudyn cannot be imported."""
    return None if exu is None else exu.__version__


def _build_chain(n):
    """Build and assemble the N-bar chain; return (SystemContainer, mbs, last body)."""
    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    ground = mbs.AddObject(ObjectGround())
    prev_marker = mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground, localPosition=[0.0, 0.0, 0.0]))
    body = None
    for i in range(n):
        node = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[i + 0.5, 0.0, 0.0],
                                           initialCoordinates=[0.0, 0.0, 0.0],
                                           initialVelocities=[0.0, 0.0, 0.0]))
        body = mbs.AddObject(ObjectRigidBody2D(nodeNumber=node, mass=1.0, inertia=1.0 / 12.0))
        left = mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[-0.5, 0.0, 0.0]))
        mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[prev_marker, left]))
        prev_marker = mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[0.5, 0.0, 0.0]))
        com = mbs.AddMarker(MarkerBodyMass(bodyNumber=body))
        mbs.AddLoad(LoadMassProportional(markerNumber=com, loadVector=list(GRAVITY)))
    mbs.Assemble()
    return sc, mbs, body


def _settings(solver, h, steps):
    s = exu.SimulationSettings()
    ti = s.timeIntegration
    ti.numberOfSteps = steps
    ti.endTime = steps * h
    ti.adaptiveStep = False  # fixed step h; a Newton failure then raises instead of shrinking h
    ti.verboseMode = 0
    ti.verboseModeFile = 0
    ti.stepInformation = 0
    ga = ti.generalizedAlpha
    ga.useIndex2Constraints = False
    ga.useNewmark = False
    ga.spectralRadius = 0.8
    s.linearSolver.solverType = getattr(exu.LinearSolverType, _SOLVERS[solver])
    s.solution.file.write = False
    s.solution.sensors.active = False
    s.solution.sensors.writePeriod = 1e30
    s.solution.restart.write = False
    s.show.computationTime = False
    s.show.statistics = False
    s.show.globalTimers = False
    s.parallel.numberOfThreads = 1
    return s


def chain_step_time(n, solver="sparse", h=1e-4, steps=200):
    """Time Exudyn's generalized-alpha on the N-bar chain.

    Returns {"per_step_cpu", "per_step_wall"} in seconds per step (minimum
    over 3 solves), "steps", "tip" = (x, y) of the last bar's free end at
    t = steps*h, and "setup_wall" = seconds to build and Assemble the model.
    """
    if exu is None:
        raise RuntimeError("exudyn is not installed")
    if solver not in _SOLVERS:
        raise ValueError(f"solver must be one of {sorted(_SOLVERS)}")
    t0 = time.perf_counter()
    _sc, mbs, last = _build_chain(n)
    setup_wall = time.perf_counter() - t0
    settings = _settings(solver, h, steps)

    best_cpu = best_wall = float("inf")
    for _ in range(REPEATS):
        # SolveDynamic starts every run from the initial coordinates given in
        # the nodes (updateInitialValues=False), so the model needs no reset.
        c0, w0 = time.thread_time(), time.perf_counter()
        exu.SolveDynamic(mbs, settings, storeSolver=False)
        w1, c1 = time.perf_counter(), time.thread_time()
        best_cpu, best_wall = min(best_cpu, c1 - c0), min(best_wall, w1 - w0)

    tip = mbs.GetObjectOutputBody(last, exu.OutputVariableType.Position,
                                  localPosition=[0.5, 0.0, 0.0],
                                  configuration=exu.ConfigurationType.Current)
    return {"per_step_cpu": best_cpu / steps, "per_step_wall": best_wall / steps,
            "steps": steps, "tip": (float(tip[0]), float(tip[1])), "setup_wall": setup_wall}


if __name__ == "__main__":
    version = available()
    if version is None:
        raise SystemExit("exudyn is not installed")
    h, steps = 1e-4, 200
    print(f"Exudyn {version}: generalized-alpha index 3, h = {h:g}, {steps} steps; "
          "per-step CPU / wall in microseconds")
    print(f"{'N':>5} {'solver':>7} {'cpu_us':>10} {'wall_us':>10} {'setup_s':>8}   tip (x, y)")
    for n in (2, 8, 32, 128, 512):
        for solver in ("dense", "sparse"):
            r = chain_step_time(n, solver, h, steps)
            print(f"{n:>5} {solver:>7} {r['per_step_cpu'] * 1e6:>10.1f} {r['per_step_wall'] * 1e6:>10.1f} "
                  f"{r['setup_wall']:>8.3f}   ({r['tip'][0]:.9f}, {r['tip'][1]:.9f})")
