#!/usr/bin/env python
"""Side by side: mbdk's generalized_alpha and Exudyn's generalized-alpha index-3 solver on the
same scenes, steps and rho_inf, in one run on one machine (a measurement, not a test: nothing
here fails on time).

Needs exudyn (`pip install exudyn`; an optional peer, never a dependency of mbdk): without it
the script says so and writes nothing.

What is compared. Each scene is mbdk's own (the double pendulum P1 and the four-bar of
python/mbdk/scenes/, the IFToMM A02 loop through its flat poses (mbdk.benchmarks.a02_chain(1)),
Bricard's linkage and the stiff flyball governor of scenes/spatial/), built in Exudyn from the
same Scene object and from mbdk's assembled initial state (the run checks that both start in
the same state to 1e-12): a planar body as ObjectRigidBody2D on NodeRigidBody2D, revolute
joints as ObjectJointRevolute2D; a spatial body as ObjectRigidBody on NodeRigidBodyRotVecLG (a
rotation vector updated on the rotation group, Exudyn's Lie-group node, as mbdk turns a body
by R exp(dtheta)), its frame mbdk's body frame and its reference point the centre of mass;
revolute and prismatic joints by CreateRevoluteJoint / CreatePrismaticJoint, spring-dampers by
CreateSpringDamper, gravity on every body. The state compared at t_end, per body: the centre
(3), the rotation matrix (9), the centre's velocity (3) and the body-frame angular velocity (3).

Both run the generalized-alpha scheme of Chung and Hulbert (1993) in the form of Arnold and
Bruls (2007) (Exudyn's CSolverImplicitSecondOrder.cpp follows their Algorithm 1) on the index-3
DAE at a fixed step, with alpha_m = (2 rho - 1)/(rho + 1), alpha_f = rho/(rho + 1),
gamma = 1/2 - alpha_m + alpha_f, beta = (1 - alpha_m + alpha_f)^2/4 from rho_inf (Exudyn:
PreInitializeSolverSpecific; this run reads Exudyn's own printout of the four and stops if
they differ from mbdk.alpha_family's), the pseudo-accelerations started at the consistent
initial accelerations (no start-up correction on either side), Newton on the scaled system.
mbdk runs two formulations: "index3" (Exudyn's scheme: positions on Phi = 0, v and a from the
scheme's relations, no projections; it refuses Bricard's redundant joint by name) and
"augmented_lagrangian" (its default: the augmented Lagrangian with projections of v and a).
Exudyn: useIndex2Constraints = False (its index-2 option exists for useNewmark only),
useNewmark = False, computeInitialAccelerations = True, adaptiveStep = False, its default
modified Newton with relative/absolute residual tolerance 1e-10/1e-12 (mbdk: its defaults,
newton_rtol/atol 1e-10/1e-12 on the update), the dense linear solver (EigenDense, with
ignoreSingularJacobian where the scene's joint rows are redundant: Bricard), one thread, no
files or sensors. A run that fails (Exudyn raises SolverError when Newton fails at a fixed h)
is a row with the time it reached.

Reference: A02's exact motion (mbdk.benchmarks.a02_crank), else mbdk's dopri54 on the reduced
formulation at rtol 1e-12, atol 1e-14 (neither side's scheme; its accuracy estimated by its
difference from bdf at rtol 1e-12). Agreement: |mbdk - Exudyn| against the larger of the two
errors. Below 1e-2 both computed the same discrete solution; otherwise they agree to each
method's accuracy, each with its own error of that size (the ratio cannot exceed 2: the
triangle inequality through the reference). The errors are the methods' own where they are
well above the reference's accuracy, which the verdict checks (10x).

Cost: the solving thread's CPU time of one whole run (mbdk: r.stats.cpu_time, the kernel call;
Exudyn: time.thread_time() around exu.SolveDynamic; the set-up of the solver and the initial
accelerations included on both sides), the least of --repeats runs (default 3), per step;
wall time beside. A third table: what the Newton test leaves in the index-3 form's velocities
at a small h (mbdk at its default and at tighter tolerances, beside Exudyn).

usage: python benchmarks/exudyn_alpha.py [--quick] [--out DIR]
writes DIR/exudyn_alpha{,_parameters,_newton}.csv and .md (default benchmarks/out/)
"""
from __future__ import annotations

import argparse
import contextlib
import csv
import io
import re
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import mbdk
from mbdk import alpha_family
from mbdk.benchmarks import a02_chain, a02_crank

try:
    import exudyn as exu
    from exudyn.itemInterface import (LoadMassProportional, MarkerBodyMass, MarkerBodyPosition,
                                      NodeRigidBody2D, ObjectGround, ObjectJointRevolute2D,
                                      ObjectRigidBody2D)
    from exudyn.utilities import RigidBodyInertia
except ImportError:
    exu = None

HERE = Path(__file__).resolve().parent
RHOS = (1.0, 0.8, 0.5, 0.0)
#: case: (t_end, steps h); quick: one h on a shorter interval. a02_n1: the IFToMM A02 loop
#: through its flat poses (C loses a rank there), against its exact motion
CASES = {"double_pendulum": (2.0, (4e-3, 1e-3, 2.5e-4)),
         "four_bar": (2.0, (4e-3, 1e-3, 2.5e-4)),
         "a02_n1": (2.0, (4e-3, 1e-3, 2.5e-4)),
         "bricard": (2.0, (2e-3, 5e-4)),
         "flyball_governor": (1.0, (1e-3, 2.5e-4))}
QUICK = {"double_pendulum": (0.5, (1e-3,)), "flyball_governor": (0.1, (1e-3,))}
NEWTON_RTOL, NEWTON_ATOL = 1e-10, 1e-12


def available():
    """Exudyn's version string, or None when exudyn cannot be imported."""
    return None if exu is None else exu.__version__


def progress(msg: str) -> None:
    print(f"  .. {msg}", file=sys.stderr, flush=True)


def mbdk_state(r, sample: int = -1) -> np.ndarray:
    """The compared state at a sample: per body the centre, the rotation matrix (row by row),
    the centre's velocity and the body-frame angular velocity."""
    parts = []
    for k, b in enumerate(r.bodies):
        vel = r.v[sample, 6 * k:6 * k + 3] if r.kind == "spatial" else \
            np.append(r.v[sample, 3 * k:3 * k + 2], 0.0)
        parts += [r.position(b)[sample], r.orientation(b)[sample].ravel(), vel,
                  r.omega_body(b)[sample]]
    return np.concatenate(parts)


class ExudynScene:
    """An mbdk scene in Exudyn, started from mbdk's assembled initial state r0 (a SceneResult
    whose first sample is t0). Element kinds beyond those of the four scenes raise
    NotImplementedError by name."""

    def __init__(self, scene, r0):
        self.name = scene.name
        self.spatial = scene.kind == "spatial"
        self.redundant = False
        self.sc = exu.SystemContainer()
        mbs = self.mbs = self.sc.AddSystem()
        self.ground = mbs.AddObject(ObjectGround())
        self.bodies = {}
        gravity = [f for f in scene.forces if f.type == "gravity"]
        g = np.zeros(3)
        if gravity:
            gg = gravity[0].g if not self.spatial else gravity[0].reals
            g[:len(gg)] = gg
        for b in scene.bodies:
            pos, rot = r0.position(b.name)[0], r0.orientation(b.name)[0]
            k = r0.bodies.index(b.name)
            if self.spatial:
                vel, om = r0.v[0, 6 * k:6 * k + 3], r0.omega_body(b.name)[0]
                self.bodies[b.name] = mbs.CreateRigidBody(
                    inertia=RigidBodyInertia(mass=b.mass, inertiaTensor=np.asarray(b.inertia)),
                    referencePosition=list(pos), referenceRotationMatrix=rot,
                    initialVelocity=list(vel), initialAngularVelocity=list(rot @ om),
                    gravity=list(g), nodeType=exu.NodeType.RotationRotationVector)
            else:
                q, v = r0.q[0, 3 * k:3 * k + 3], r0.v[0, 3 * k:3 * k + 3]
                node = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=list(q),
                                                   initialVelocities=list(v)))
                obj = mbs.AddObject(ObjectRigidBody2D(nodeNumber=node, mass=b.mass,
                                                      inertia=b.inertia))
                self.bodies[b.name] = obj
                if gravity:
                    mbs.AddLoad(LoadMassProportional(
                        markerNumber=mbs.AddMarker(MarkerBodyMass(bodyNumber=obj)),
                        loadVector=list(g)))
        for j in scene.joints:
            self._joint(j, r0)
        for f in scene.forces:
            if f.type == "gravity":
                continue
            if not (self.spatial and f.type == "spring_damper"):
                raise NotImplementedError(f"{scene.name}: force {f.name!r} of type {f.type!r} "
                                          "has no Exudyn counterpart here")
            p1, p2 = np.array(f.reals[0:3]), np.array(f.reals[3:6])
            k, c, l0 = f.reals[6:9]
            mbs.CreateSpringDamper(itemNumbers=[self._body(f.body1), self._body(f.body2)],
                                   localPosition0=list(p1), localPosition1=list(p2),
                                   stiffness=k, damping=c, referenceLength=l0)
        mbs.Assemble()
        report = mbdk.scene_report(scene)
        self.redundant = report.rank < report.rows

    def _body(self, name):
        return self.ground if name == "ground" else self.bodies[name]

    def _joint(self, j, r0):
        mbs = self.mbs
        if not self.spatial:
            if j.type != "revolute":
                raise NotImplementedError(f"{self.name}: joint {j.name!r} of type {j.type!r} "
                                          "has no Exudyn counterpart here")
            m1 = mbs.AddMarker(MarkerBodyPosition(bodyNumber=self.bodies[j.body1],
                                                  localPosition=[*j.point1, 0.0]))
            m2 = mbs.AddMarker(MarkerBodyPosition(bodyNumber=self._body(j.body2),
                                                  localPosition=[*j.point2, 0.0]))
            mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[m2, m1]))
            return
        rot = r0.orientation(j.body1)[0]
        at = r0.position(j.body1)[0] + rot @ np.asarray(j.point1)
        axis = rot @ np.asarray(j.axis1)
        make = {"revolute": mbs.CreateRevoluteJoint, "prismatic": mbs.CreatePrismaticJoint}
        if j.type not in make:
            raise NotImplementedError(f"{self.name}: joint {j.name!r} of type {j.type!r} has "
                                      "no Exudyn counterpart here")
        make[j.type](itemNumbers=[self._body(j.body2), self.bodies[j.body1]],
                     position=list(at), axis=list(axis), useGlobalFrame=True)

    def settings(self, rho: float, h: float, steps: int, verbose: int = 0):
        s = exu.SimulationSettings()
        ti = s.timeIntegration
        ti.numberOfSteps = steps
        ti.endTime = steps * h
        ti.adaptiveStep = False        # fixed h; a Newton failure then raises
        ti.verboseMode = verbose
        ti.verboseModeFile = 0
        ti.stepInformation = 0
        ga = ti.generalizedAlpha
        ga.spectralRadius = rho
        ga.useIndex2Constraints = False
        ga.useNewmark = False
        ga.computeInitialAccelerations = True
        ti.newton.relativeTolerance = NEWTON_RTOL
        ti.newton.absoluteTolerance = NEWTON_ATOL
        s.linearSolver.solverType = exu.LinearSolverType.EigenDense
        # Bricard's 30 joint rows have rank 29: Exudyn's dense solver passes the redundant
        # row only when told to ignore the singular pivot
        s.linearSolver.ignoreSingularJacobian = self.redundant
        s.solution.file.write = False
        s.solution.sensors.active = False
        s.solution.sensors.writePeriod = 1e30
        s.solution.restart.write = False
        s.show.computationTime = False
        s.show.statistics = False
        s.show.globalTimers = False
        s.parallel.numberOfThreads = 1
        return s

    def parameters(self, rho: float) -> dict:
        """Exudyn's alpha_m, alpha_f, beta, gamma as its solver prints them (verbose 2)."""
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            exu.SolveDynamic(self.mbs, self.settings(rho, 1e-4, 1, verbose=2),
                             storeSolver=False)
        line = next((ln for ln in buf.getvalue().splitlines() if "alphaM=" in ln), "")
        got = dict(re.findall(r"(alphaM|alphaF|beta|gamma)=([-+0-9.eE]+)", line))
        return {"alpha_m": float(got["alphaM"]), "alpha_f": float(got["alphaF"]),
                "beta": float(got["beta"]), "gamma": float(got["gamma"])}

    def state(self) -> np.ndarray:
        cur = exu.ConfigurationType.Current
        ov = exu.OutputVariableType
        parts = []
        for obj in self.bodies.values():
            get = lambda var: np.asarray(self.mbs.GetObjectOutputBody(  # noqa: E731
                obj, var, localPosition=[0.0, 0.0, 0.0], configuration=cur), float)
            parts += [get(ov.Position), get(ov.RotationMatrix).ravel(), get(ov.Velocity),
                      get(ov.AngularVelocityLocal)]
        return np.concatenate(parts)

    def run(self, rho: float, h: float, steps: int, repeats: int) -> dict:
        """The least thread CPU and wall time of `repeats` whole solves, per step, and the
        state at the end. SolveDynamic starts each solve from the nodes' initial values."""
        s = self.settings(rho, h, steps)
        cpu = wall = float("inf")
        for _ in range(repeats):
            c0, w0 = time.thread_time(), time.perf_counter()
            exu.SolveDynamic(self.mbs, s, storeSolver=False)
            w1, c1 = time.perf_counter(), time.thread_time()
            cpu, wall = min(cpu, c1 - c0), min(wall, w1 - w0)
        return {"cpu": cpu / steps, "wall": wall / steps, "state": self.state()}


def mbdk_run(scene, formulation: str, rho: float, h: float, t_end: float,
             repeats: int) -> dict:
    steps = round(t_end / h)
    best = None
    for _ in range(repeats):
        with warnings.catch_warnings():
            # the index3 form's multipliers are flagged; the compared state is not
            warnings.simplefilter("ignore", mbdk.errors.AccuracyWarning)
            r = mbdk.simulate(scene, "generalized_alpha", rho_inf=rho, formulation=formulation,
                              h=h, t_end=t_end, every=steps, outputs=())
        if best is None or r.cpu_time < best[0]:
            best = (r.cpu_time, r.wall_time)
    return {"cpu": best[0] / steps, "wall": best[1] / steps, "state": mbdk_state(r)}


def case_scene(name: str):
    return a02_chain(int(name[len("a02_n"):])) if name.startswith("a02_n") else mbdk.scene(name)


def reference(name: str, scene, t_end: float) -> tuple[np.ndarray, str, float]:
    """(the state at t_end, what it is, its accuracy): A02's exact motion
    (mbdk.benchmarks.a02_crank: cranks at theta about their ground hinges, couplers translating
    with the crank tips; accuracy taken as 0), else mbdk's dopri54 on the reduced formulation
    at rtol 1e-12, its accuracy estimated by its difference from bdf at rtol 1e-12."""
    if name.startswith("a02_n"):
        n = int(name[len("a02_n"):])
        th, om = (float(x[0]) for x in a02_crank(n, [t_end]))
        c, s = np.cos(th), np.sin(th)
        rot = lambda a: np.array([[np.cos(a), -np.sin(a), 0.0],  # noqa: E731
                                  [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]]).ravel()
        parts = []
        for i in range(n + 1):       # crank i, hinged at (i, 0), its centre at half length
            parts += [[i + 0.5 * c, 0.5 * s, 0.0], rot(th), [-0.5 * om * s, 0.5 * om * c, 0.0],
                      [0.0, 0.0, om]]
        for i in range(n):           # coupler i, between the tips of cranks i and i + 1
            parts += [[i + 0.5 + c, s, 0.0], rot(0.0), [-om * s, om * c, 0.0], [0.0, 0.0, 0.0]]
        return np.concatenate([np.asarray(p, float) for p in parts]), "exact", 0.0
    r = mbdk.simulate(scene, "dopri54", rtol=1e-12, atol=1e-14, t_end=t_end, outputs=())
    check = mbdk.simulate(scene, "bdf", rtol=1e-12, atol=1e-14, t_end=t_end, outputs=())
    return mbdk_state(r), "dopri54 rtol 1e-12", \
        float(np.max(np.abs(mbdk_state(r) - mbdk_state(check))))


def one_line(exc) -> str:
    return " ".join(str(exc).split())


def verdict(diff: float, err: float, ref_accuracy: float) -> str:
    """diff <= 2 err always (the triangle inequality through the reference); the errors are
    the methods' own only well above the reference's accuracy."""
    if err < 10.0 * ref_accuracy:
        return "errors within 10x the reference's accuracy"
    if diff < 1e-2 * err:
        return "same discrete solution"
    return "to each method's accuracy"


def run(out: Path, quick: bool, repeats: int = 3) -> list[dict]:
    out.mkdir(parents=True, exist_ok=True)
    cases = QUICK if quick else CASES
    rows, params = [], []
    for name, (t_end, hs) in cases.items():
        scene = case_scene(name)
        progress(f"{name}: reference")
        ref, ref_kind, ref_acc = reference(name, scene, t_end)
        r0 = mbdk.simulate(scene, "generalized_alpha", h=hs[0], t_end=hs[0], outputs=())
        ex = ExudynScene(scene, r0)
        if not np.allclose(ex.state(), mbdk_state(r0, 0), rtol=0, atol=1e-12):
            raise SystemExit(f"{name}: Exudyn's model does not start in mbdk's initial state")
        forms = ("augmented_lagrangian",) if ex.redundant else ("index3", "augmented_lagrangian")
        for rho in RHOS:
            mine = alpha_family.parameters("generalized_alpha", rho_inf=rho).as_options()
            theirs = ex.parameters(rho)
            worst = max(abs(theirs[k] - mine[k]) / max(abs(mine[k]), 1e-3) for k in mine)
            if worst > 1e-5:      # Exudyn prints six digits
                raise SystemExit(f"rho_inf = {rho}: Exudyn's parameters {theirs} are not "
                                 f"mbdk's {mine}: the comparison would not be like for like")
            if rho not in [p["rho_inf"] for p in params]:
                params.append({"rho_inf": rho, **{f"{k} mbdk": v for k, v in mine.items()},
                               **{f"{k} Exudyn": v for k, v in theirs.items()}})
            for h in hs:
                steps = round(t_end / h)
                progress(f"{name}: rho_inf = {rho:g}, h = {h:g}")
                try:
                    e = ex.run(rho, h, steps, repeats)
                except Exception as exc:   # Exudyn raises on a Newton failure at fixed h
                    e = {"failed": f"{type(exc).__name__} ({one_line(exc)}) at t = "
                                   f"{ex.mbs.systemData.GetTime():.4g} s"}
                for form in forms:
                    try:
                        m = mbdk_run(scene, form, rho, h, t_end, repeats)
                    except mbdk.errors.MbdkError as exc:
                        m = {"failed": f"{type(exc).__name__} ({one_line(exc)[:120]})"}
                    row = {"scene": name, "t_end": t_end, "rho_inf": rho, "h": h,
                           "steps": steps, "mbdk formulation": form, "reference": ref_kind,
                           "reference accuracy": ref_acc}
                    err = {who: float(np.max(np.abs(x["state"] - ref)))
                           for who, x in (("mbdk", m), ("Exudyn", e)) if "state" in x}
                    row.update({f"err {who}": v for who, v in err.items()})
                    if len(err) == 2:
                        diff = float(np.max(np.abs(m["state"] - e["state"])))
                        worst = max(err.values())
                        row.update({"|mbdk - Exudyn|": diff,
                                    "err Exudyn / err mbdk": err["Exudyn"] / err["mbdk"],
                                    "diff / max err": diff / worst,
                                    "agreement": verdict(diff, worst, ref_acc)})
                    row["note"] = "; ".join(f"{who} stopped: {x['failed']}" for who, x in
                                            (("mbdk", m), ("Exudyn", e)) if "failed" in x)
                    for who, x in (("mbdk", m), ("Exudyn", e)):
                        if "cpu" in x:
                            row[f"{who} cpu us/step"] = 1e6 * x["cpu"]
                            row[f"{who} wall us/step"] = 1e6 * x["wall"]
                    if "cpu" in m and "cpu" in e:
                        row["cpu ratio mbdk/Exudyn"] = m["cpu"] / e["cpu"]
                    rows.append(row)
    cols = ["scene", "t_end", "rho_inf", "h", "steps", "mbdk formulation", "reference",
            "reference accuracy", "|mbdk - Exudyn|", "err mbdk", "err Exudyn", "err Exudyn / err mbdk",
            "diff / max err", "agreement", "mbdk cpu us/step",
            "Exudyn cpu us/step", "cpu ratio mbdk/Exudyn", "mbdk wall us/step",
            "Exudyn wall us/step", "note"]
    write(rows, cols, out / "exudyn_alpha",
          f"mbdk generalized_alpha against Exudyn {available()} generalized-alpha (index 3), "
          "same scenes, steps and rho_inf",
          "State at t_end per body: centre, rotation matrix, centre velocity, body-frame angular "
          "velocity; err: max |state - reference| (A02: its exact motion; else mbdk's dopri54 "
          "at rtol 1e-12). diff / max err "
          "< 0.01: the same discrete solution; <= 2: agreement to each method's accuracy. CPU: "
          f"the solving thread's, least of {repeats} whole runs, per step (ratio > 1: mbdk "
          "slower). mbdk's index3 form is Exudyn's scheme (no projections); "
          "augmented_lagrangian is mbdk's default.")
    if not quick:
        newton = newton_tolerance(repeats)
        write(newton, list(newton[0]), out / "exudyn_alpha_newton",
              "What the Newton test leaves in the index-3 form's velocities: the four-bar, "
              f"rho_inf = {NEWTON_CASE[1]:g}, h = {NEWTON_CASE[2]:g}, {NEWTON_CASE[3]:g} s",
              "The index-3 form takes v+ and a+ from the scheme's relations, gamma/(beta h) and "
              "(1 - alpha_m)/(beta h^2 (1 - alpha_f)) times the Newton error of q+: a test on "
              "the update (mbdk: atol + rtol |q|) leaves more of it than one on the residual "
              "relative to the step's first (Exudyn), and at small h it shows.")
    write(params, list(params[0]), out / "exudyn_alpha_parameters",
          "The four parameters from rho_inf: mbdk.alpha_family and Exudyn's own printout",
          "Exudyn prints six significant digits.")
    return rows


#: scene, rho_inf, h, t_end of the Newton-tolerance table
NEWTON_CASE = ("four_bar", 0.8, 2.5e-4, 2.0)


def newton_tolerance(repeats: int) -> list[dict]:
    """mbdk's index3 form at its default Newton tolerances and at tighter ones, beside Exudyn's
    run, on one case: the error in the state and the cost per step."""
    name, rho, h, t_end = NEWTON_CASE
    scene = case_scene(name)
    ref, _, _ = reference(name, scene, t_end)
    steps = round(t_end / h)
    r0 = mbdk.simulate(scene, "generalized_alpha", h=h, t_end=h, outputs=())
    rows = []
    for rtol, atol in ((None, None), (1e-12, 1e-14)):
        best = None
        for _ in range(repeats):
            r = mbdk.simulate(scene, "generalized_alpha", rho_inf=rho, formulation="index3",
                              h=h, t_end=t_end, every=steps, outputs=(), newton_rtol=rtol,
                              newton_atol=atol)
            best = r.cpu_time if best is None else min(best, r.cpu_time)
        rows.append({"run": "mbdk index3, newton_rtol/atol "
                            + ("1e-10/1e-12 (default)" if rtol is None else f"{rtol:g}/{atol:g}"),
                     "max |state - reference|": float(np.max(np.abs(mbdk_state(r) - ref))),
                     "cpu us/step": 1e6 * best / steps})
    e = ExudynScene(scene, r0).run(rho, h, steps, repeats)
    rows.append({"run": f"Exudyn, Newton relative/absolute {NEWTON_RTOL:g}/{NEWTON_ATOL:g} "
                        "(residual)",
                 "max |state - reference|": float(np.max(np.abs(e["state"] - ref))),
                 "cpu us/step": 1e6 * e["cpu"]})
    return rows


def write(rows, cols, stem: Path, title: str, notes: str) -> None:
    def fmt(v):
        if v is None:
            return ""
        if isinstance(v, float):
            return f"{v:.3g}"
        return str(v)
    with open(stem.with_suffix(".csv"), "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for r in rows:
            w.writerow([repr(r[c]) if isinstance(r.get(c), float) else fmt(r.get(c))
                        for c in cols])
    md = [f"### {title}", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    md += ["| " + " | ".join(fmt(r.get(c)) for c in cols) + " |" for r in rows]
    if notes:
        md += ["", notes]
    stem.with_suffix(".md").write_text("\n".join(md) + "\n")
    print("\n".join(md) + "\n")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="two scenes, one h, short intervals")
    ap.add_argument("--out", type=Path, default=HERE / "out")
    ap.add_argument("--repeats", type=int, default=3, help="runs per timing (the least)")
    args = ap.parse_args()
    if available() is None:
        print("exudyn is not installed (pip install exudyn): nothing to compare",
              file=sys.stderr)
        return 0
    t0 = time.perf_counter()
    run(args.out, args.quick, args.repeats)
    print(f"exudyn_alpha: written to {args.out} ({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
