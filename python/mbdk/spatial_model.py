"""The spatial model's tables (kernel/src/spatial/mbdk_spatial_model.f90, written from a Scene of
spatial bodies), its evaluation at one state, and the checks of an initial state before a run.
"""
from __future__ import annotations

import math

import numpy as np

from . import _kernel
from .codes import (ROTATIONS, SPATIAL_EFFECT_CODES, SPATIAL_FORCE_CODES, SPATIAL_FORCE_REALS,
                    SPATIAL_JOINT_CODES, SPATIAL_JOINT_REALS, WEAR_LAWS, WEAR_LOADS)
from .errors import (InvalidInputError, NoMemoryError, Status, exception_for, format_bytes,
                     no_memory_message, status_message)
from .scene import DRIVERS, SPATIAL_TWO_BODY_FORCES, Scene, SceneError
from .spatial_file import validate_spatial


#: how far a given initial state may be off its joints before the run refuses it (a larger
#: offset is a scene error, not roundoff: the assembly would move the bodies visibly)
ASSEMBLY_TOL = 1e-6


def spatial_tables(sc: Scene):
    """The spatial model's tables (kernel/src/spatial/mbdk_spatial_model.f90): nb, mass,
    inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal; the force table holds the
    forces, then the wear elements (each naming its contact's column)."""
    nb = len(sc.bodies)
    mass = np.array([b.mass for b in sc.bodies])
    inertia = np.asfortranarray(np.stack([b.inertia for b in sc.bodies], axis=2))
    nj, nf = len(sc.joints), len(sc.forces) + len(sc.wear)
    jtype = np.zeros(max(nj, 1), dtype=np.int32)
    jbody = np.zeros((2, max(nj, 1)), dtype=np.int32, order="F")
    jreal = np.zeros((SPATIAL_JOINT_REALS, max(nj, 1)), order="F")
    for k, j in enumerate(sc.joints):
        jtype[k] = SPATIAL_JOINT_CODES[j.type]
        jbody[:, k] = sc.body_index(j.body1), sc.body_index(j.body2)
        jreal[:, k] = np.concatenate([j.point1, j.point2, j.axis1, j.axis2, j.function])
    ftype = np.zeros(max(nf, 1), dtype=np.int32)
    fbody = np.zeros((2, max(nf, 1)), dtype=np.int32, order="F")
    freal = np.zeros((SPATIAL_FORCE_REALS, max(nf, 1)), order="F")
    for k, f in enumerate(sc.forces):
        ftype[k] = SPATIAL_FORCE_CODES[f.type]
        fbody[:, k] = (sc.body_index(f.body1) if f.body1 else 0,
                       sc.body_index(f.body2) if f.type in SPATIAL_TWO_BODY_FORCES else 0)
        freal[:len(f.reals), k] = f.reals
    column = {f.name: k + 1 for k, f in enumerate(sc.forces)}     # 1-based, as the kernel's
    for k, w in enumerate(sc.wear, len(sc.forces)):
        ftype[k] = SPATIAL_EFFECT_CODES["wear"]
        fbody[:, k] = column[w.contact], WEAR_LAWS[w.law]
        freal[0, k] = w.coefficient
        if w.law == "knee":
            freal[1:5, k] = w.slide_roll
        freal[5, k] = WEAR_LOADS[w.quantity]
    return nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal


def wear0(sc: Scene) -> np.ndarray:
    """The initial worn volumes of the scene's wear elements, the state's last values."""
    return np.array([w.initial for w in sc.wear], float)


def evaluate_spatial(sc: Scene, y=None, t: float = 0.0) -> dict:
    """At the state y of the bodies (default: the scene's initial state) and time t: the energy
    parts and residuals of the outputs, Phi, C (rows x 6 bodies), gamma, Phi_t (a driver's
    rows), the rank of the joints' rows at the initial state (below the row count: redundant
    joints), the reduced formulation's multipliers and y' (ydot; with wear, the volumes' rates
    after the bodies', the volumes at their initial values), and the status of that solve
    (SINGULAR at a singular pose)."""
    validate_spatial(sc)
    nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = spatial_tables(sc)
    y0 = sc.state0()
    if y is not None:
        try:
            y = np.asarray(y, dtype=float)
        except (TypeError, ValueError):
            y = None
        if y is None or y.shape != y0.shape or not np.all(np.isfinite(y)):
            raise InvalidInputError(f"y must be a finite state of {y0.size} numbers (the "
                                    f"scene's layout: q then (v, Omega) per body)")
    y = y0 if y is None else y
    m = sc.rows
    run = f"evaluating spatial scene {sc.name!r} ({nb} bodies, {m} constraint rows)"
    try:
        out, phi, c, gam, phit, lam, ydot, rank, asked, status = _kernel.spatial_residuals(
            mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal,
            ROTATIONS[sc.rotation], np.concatenate([y0, wear0(sc)]), float(t),
            np.concatenate([y, wear0(sc)]), max(m, 1))
    except MemoryError as exc:   # the arrays f2py allocates, C (rows x 6 nb) the largest
        raise NoMemoryError(f"{run}: its arrays ({format_bytes(8.0 * max(m, 1) * 6 * nb)} for C "
                            f"alone, {m} x {6 * nb}) could not be allocated ({exc}); fewer "
                            "bodies or joints") from exc
    if status == Status.ERR_NO_MEMORY:
        raise NoMemoryError(f"{run}: " + no_memory_message(asked, samples=False))
    return {"kinetic": out[0], "potential_gravity": out[1], "potential_springs": out[2],
            "power": out[3],
            "phi": phi[:m], "C": c[:m], "gamma": gam[:m], "phi_t": phit[:m],
            "multipliers": lam[:m], "ydot": ydot,
            "rank": int(rank), "status": Status(int(status))}


def start_residuals(sc: Scene, t0: float = 0.0) -> dict:
    """At the scene's initial state: Phi, C w + Phi_t (vres) and its terms' size |C| |w| +
    |Phi_t| (vterm) per row, the rank of the joints' rows and the status, from the kernel
    (spatial_start_residuals), in memory that grows as the rows do (evaluate_spatial also
    returns C, rows x 6 bodies)."""
    nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = spatial_tables(sc)
    m = sc.rows
    y0 = np.concatenate([sc.state0(), wear0(sc)])
    phi, vres, vterm, rank, asked, status = _kernel.spatial_start_residuals(
        mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal, ROTATIONS[sc.rotation],
        y0, float(t0), max(m, 1))
    if status == Status.ERR_NO_MEMORY:
        raise NoMemoryError(f"checking the start of spatial scene {sc.name!r} ({nb} bodies, "
                            f"{m} constraint rows): " + no_memory_message(asked, samples=False))
    return {"phi": phi[:m], "vres": vres[:m], "vterm": vterm[:m], "rank": int(rank),
            "status": Status(int(status))}


#: what measures the distance from each angle set's gimbal lock
LOCK_MEASURE = {"euler313": "min |sin(theta)|", "cardan123": "min |cos(beta)|"}


def lock_distance(sc: Scene, q) -> float | None:
    """How near the bodies' angles are to their sequence's gimbal lock at coordinates q:
    the least |sin(theta)| (3-1-3) or |cos(beta)| (1-2-3); None for quaternions."""
    if sc.rotation == "quaternion":
        return None
    a = np.asarray(q).reshape(len(sc.bodies), 6)[:, 3:]
    return float(np.min(np.abs(np.sin(a[:, 1]) if sc.rotation == "euler313"
                               else np.cos(a[:, 1]))))


def check_initial(sc: Scene, assemble: bool, t0: float = 0.0) -> None:
    """Refuses, naming the joint, an initial state off its joints by more than the assembly
    should move (ASSEMBLY_TOL of the scene's size); without assembly, by more than roundoff."""
    if not sc.joints:
        return
    for j in sc.joints:
        if j.type in DRIVERS:
            c = j.function
            f0 = c[0] + c[1] * t0 + c[2] * math.sin(c[3] * t0 + c[4])
            if abs(f0) > 1e-12:
                raise SceneError(
                    f"{sc.source}: joint {j.name!r}: field 'function' gives f(t0) = {f0:.6g} at "
                    f"t0 = {t0:g}: a driver {DRIVERS[j.type]} by f(t) from where it starts, so "
                    "f(t0) must be 0 (shift the offset or the phase)")
    ev = start_residuals(sc, t0)
    if ev["rank"] == 0 and sc.rows:
        raise exception_for(Status.ERR_SINGULAR_MATRIX)(
            f"{sc.source}: the joints' rows are degenerate at the initial state (a row vanishes: "
            "e.g. a universal joint whose two axes are parallel, or coincident points where a "
            "direction is needed); give a pose where each joint is well defined")
    if ev["status"] not in (Status.SUCCESS, Status.ERR_SINGULAR_MATRIX):
        raise exception_for(ev["status"])(
            f"spatial scene {sc.name!r}: the kernel refused its tables "
            f"({status_message(ev['status'])})")
    phi = ev["phi"]
    size = max(1.0, max(float(np.max(np.abs(j.point1))) for j in sc.joints))
    tol = ASSEMBLY_TOL * size if assemble else 1e-10 * size
    cw = ev["vres"]
    # the velocity rows: against the size of the terms that must cancel (|C| |w|), with a floor
    # of the speeds the scene's size gives to 1 rad/s
    vtol = (ASSEMBLY_TOL if assemble else 1e-10) * max(float(np.max(ev["vterm"],
                                                                     initial=0.0)), size)
    for name, first, count in sc.joint_rows():
        worst = float(np.max(np.abs(cw[first:first + count])))
        if worst > vtol:
            raise InvalidInputError(
                f"{sc.source}: joint {name!r}: the initial velocities break this joint by "
                f"{worst:.3g} (largest |C w + Phi_t| of its rows; tolerance {vtol:.3g}): give "
                "velocities and angular velocities the joint allows (a body turning about a "
                "fixed point moves its centre at Omega x r)")
    for name, first, count in sc.joint_rows():
        worst = float(np.max(np.abs(phi[first:first + count])))
        if worst > tol:
            raise InvalidInputError(
                f"{sc.source}: joint {name!r}: the initial state is off this joint by "
                f"{worst:.3g} (largest |Phi| of its rows; tolerance {tol:.3g}"
                f"{'' if assemble else ', assemble_initial=False'}): give the bodies positions "
                "and orientations that satisfy it (the joint's 'at' point in space puts both "
                "ends on it)")
