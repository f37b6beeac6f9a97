"""Scene -> the kernel's element tables (kernel/src/model), evaluation at one state, the
kernel's assembly of initial conditions, and the diagnosis of dependent (redundant)
constraints.

The table layouts are documented in kernel/src/model/mbdk_joints.f90 and
mbdk_force_elements.f90; this module is their only writer. Element codes, joint rows and visit
counter names come from the kernel's registry (mbdk_elements); values that depend on the initial
pose (rest lengths, relative angles) and the assembly are computed in the kernel
(mbdk_assembly).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from . import _kernel
from .codes import (BODY_KINDS, CONTACT_GEOMETRY, COORDS, EFFECT_CODES, FORCE_CODES,
                    FORMULATIONS, FROM_POSE, JOINT_CODES, JOINT_ROWS, JOINT_ROWS_BY_CODE,
                    LINEAR_SOLVES, SOLVERS, WEAR_LAWS, WEAR_LOADS)
from .errors import NotApplicableError, Status, exception_for
from .options import ModelOptions
from .scene import GROUND_JOINTS, Scene, SceneError, body_kind_problem


@dataclass
class Tables:
    mass: np.ndarray
    inertia: np.ndarray
    nj: int
    jint: np.ndarray
    jreal: np.ndarray
    nf: int
    fint: np.ndarray
    freal: np.ndarray
    m: int
    nc: int
    rows: list          # (joint name, first row (0-based), count)
    kind: np.ndarray = None   # the bodies' kind codes (kernel/src/model/mbdk_elements.f90)

    def args(self):
        return (self.mass, self.inertia, self.kind, self.nj, self.jint, self.jreal, self.nf,
                self.fint, self.freal)


def build_tables(sc: Scene, q0=None, resolve: bool = True) -> Tables:
    """The kernel's tables for a scene. Values a scene leaves to the initial configuration (a
    spring's rest length, a prismatic or fixed joint's relative angle, a distance's length, a
    coupling's or a rolling disc's offset) are marked FROM_POSE;
    with resolve (the default) the kernel fills them in at q0 (the scene's own pose if None),
    without it they stay marked for the kernel to fill in where it starts a run."""
    nb = len(sc.bodies)
    mass = np.array([b.mass for b in sc.bodies], float)
    inertia = np.array([b.inertia for b in sc.bodies], float)
    for b in sc.bodies:     # a Scene's fields can be changed after it was read
        problem = body_kind_problem(b.kind)
        if problem:
            raise (NotApplicableError if b.kind in BODY_KINDS else SceneError)(
                f"{sc.source}: body {b.name!r}: field 'kind' {problem}")
    kind = np.array([BODY_KINDS[b.kind][0] for b in sc.bodies], np.int32)
    nj = len(sc.joints)
    # the scene's forces first (the kernel names a bad one by its column), then the coast
    # flanks of each gear mesh, then one friction element per contact column that has friction,
    # then the wear elements
    gears = [k for k, f in enumerate(sc.forces) if f.type == "contact" and f.shape1[0] == "gear"]
    frictions = [k for k, f in enumerate(sc.forces) if f.type == "contact" and
                 f.friction is not None]
    nf = (len(sc.forces) + len(gears) + len(frictions) + len(set(frictions) & set(gears))
          + len(sc.wear))
    jint = np.zeros((4, max(nj, 1)), np.int32, order="F")
    jreal = np.zeros((12, max(nj, 1)), order="F")
    rows, r = [], 0
    for k, j in enumerate(sc.joints):
        b1 = sc.body_index(j.body1)
        b2 = sc.body_index(j.body2) if j.type not in GROUND_JOINTS else 0
        jint[:, k] = [JOINT_CODES[j.type], b1, b2, COORDS[j.coordinate] if j.type == "driver" else 0]
        jreal[0:2, k] = j.point1
        jreal[2:4, k] = j.point2
        jreal[4:6, k] = j.axis
        if j.type == "point_curve":
            jreal[7:12, k] = j.curve
        if j.type == "coupling":
            # q2 - ratio q1 - c = 0, c from the pose
            jreal[0:6, k] = 0.0
            jreal[COORDS[j.coordinate] - 1, k] = -j.ratio
            jreal[3 + COORDS[j.coordinate2] - 1, k] = 1.0
            jint[3, k] = FROM_POSE
        if j.type == "rolling":
            jreal[0:2, k] = 0.0
            jreal[6, k] = j.radius
            jint[3, k] = FROM_POSE
        if j.type in ("prismatic", "fixed"):
            if j.angle0 is None:
                jint[3, k] = FROM_POSE
            else:
                jreal[6, k] = j.angle0
        if j.type == "driver":
            jreal[7:12, k] = j.function
        if j.type == "distance":
            if j.length is None:
                jint[3, k] = FROM_POSE
            else:
                jreal[7:12, k] = j.length
        rows.append((j.name, r, JOINT_ROWS[j.type]))
        r += JOINT_ROWS[j.type]
    fint = np.zeros((4, max(nf, 1)), np.int32, order="F")
    freal = np.zeros((12, max(nf, 1)), order="F")
    for k, f in enumerate(sc.forces):
        code = FORCE_CODES[f.type]
        two_point = f.type in ("spring", "damper", "spring_damper")
        b1 = sc.body_index(f.body1) if f.type != "gravity" else 0
        b2 = sc.body_index(f.body2) if two_point else 0
        fint[:, k] = [code, b1, b2, COORDS[f.coordinate] if f.type.startswith("coordinate")
                      else 0]
        if f.type == "gravity":
            freal[0:2, k] = f.g
        elif f.type == "point_force":
            freal[0:2, k] = f.point1
            freal[2:4, k] = f.force
            freal[7:12, k] = f.function
        elif f.type == "torque":
            freal[0, k] = f.torque
            freal[7:12, k] = f.function
        elif f.type == "contact" and f.shape1[0] == "gear":
            fint[1:4, k] = [b1, sc.body_index(f.body2), CONTACT_GEOMETRY["gear"]]
            freal[:, k] = gear_mesh_reals(sc, f)[0]
        elif f.type == "contact":
            fint[1:4, k] = [b1, sc.body_index(f.body2), CONTACT_GEOMETRY[f.shape2[0]]]
            freal[0:2, k] = f.shape1[1]
            freal[2, k] = f.shape1[2]
            freal[3:5, k] = f.shape2[1]
            third = f.shape2[2]
            freal[5, k] = math.atan2(third[1], third[0]) if f.shape2[0] == "line" else third
            freal[6:10, k] = [f.stiffness, f.exponent, f.damping, f.damping_depth]
        elif two_point:
            freal[0:2, k] = f.point1
            freal[2:4, k] = f.point2
            freal[4, k] = f.stiffness
            if f.rest_length is None:
                fint[3, k] = FROM_POSE
            else:
                freal[5, k] = f.rest_length
            freal[6, k] = f.damping
        else:
            freal[0, k] = f.stiffness
            freal[1, k] = f.damping
            freal[2, k] = f.rest
    col = len(sc.forces)
    coast = {}
    for k in gears:         # the coast flanks: the same mesh with h = -1 and its own phases
        fint[:, col] = fint[:, k]
        freal[:, col] = gear_mesh_reals(sc, sc.forces[k])[1]
        coast[k] = col
        col += 1
    friction_col = {}
    for k in frictions:     # columns are 1-based in the kernel's tables
        for c in ([k, coast[k]] if k in coast else [k]):
            fint[:, col] = [FORCE_CODES["friction"], 0, 0, c + 1]
            freal[0:4, col] = sc.forces[k].friction
            friction_col.setdefault(sc.forces[k].name, col + 1)
            col += 1
    contact_col = {f.name: k + 1 for k, f in enumerate(sc.forces) if f.type == "contact"}
    for w in sc.wear:
        friction = w.quantity == "friction_force"
        ref = (friction_col if friction else contact_col)[w.contact]
        fint[:, col] = [EFFECT_CODES["wear"], WEAR_LAWS[w.law], WEAR_LOADS[w.quantity], ref]
        freal[0, col] = w.coefficient
        if w.law == "gear":
            freal[1:7, col] = [w.radius, w.temperature, w.a_x, w.t0, w.activation_energy,
                               w.gas_constant]
        elif w.law == "knee":
            freal[1:5, col] = w.slide_roll
        col += 1
    tab = Tables(mass, inertia, nj, jint, jreal, nf, fint, freal, r, 3 * nb, rows, kind)
    if resolve:
        resolve_tables(sc, tab, sc.q0() if q0 is None else q0)
    return tab


def gear_mesh_reals(sc: Scene, f) -> np.ndarray:
    """The kernel's reals of an involute gear mesh (kernel/src/model/mbdk_contact.f90), its
    drive flanks (h = +1) and its coast flanks (h = -1): base and tip radii, base pitch, and the
    phases that put the drive flanks in touch (delta = 0) with a flank of gear 1 at the pitch
    point at the scene's initial pose, and the coast flanks the backlash apart (delta =
    -backlash). Gear 1's coast flank of a tooth lies 2 rb1 eta_b beyond its drive flank along
    the lines of action, eta_b = pi / (2 z1) + inv(alpha0) the half thickness of a standard
    tooth at the base circle. A centre distance at which the gears do not mesh (base circles
    overlapping, or a contact ratio below 1) and a backlash of half a base pitch or more are
    SceneErrors naming the contact."""
    (z1, m1, a1, ha1), (z2, m2, a2, ha2) = f.shape1[2], f.shape2[2]
    b1, b2 = sc.bodies[sc.body_index(f.body1) - 1], sc.bodies[sc.body_index(f.body2) - 1]
    rb1, rb2 = m1 * z1 * math.cos(a1) / 2, m2 * z2 * math.cos(a2) / 2
    ra1, ra2 = m1 * z1 / 2 + ha1 * m1, m2 * z2 / 2 + ha2 * m2
    pb = math.pi * m1 * math.cos(a1)
    a = math.hypot(b2.x - b1.x, b2.y - b1.y)
    src = f"{sc.source}: force {f.name!r}"
    if not f.backlash < pb / 2:
        raise SceneError(f"{src}: field 'backlash' = {f.backlash:.6g} m is half the base pitch "
                         f"({pb / 2:.6g} m) or more: the flanks' gap would pass the next tooth; "
                         "give a backlash below it")
    if not a > rb1 + rb2:
        raise SceneError(f"{src}: the gears' centre distance {a:.6g} m does not reach their base "
                         f"radii's sum {rb1 + rb2:.6g} m: they cannot mesh (standard centre "
                         f"distance {m1 * (z1 + z2) / 2:.6g} m)")
    alpha = math.acos((rb1 + rb2) / a)
    path = math.sqrt(ra1 ** 2 - rb1 ** 2) - max(0.0, a * math.sin(alpha)
                                                  - math.sqrt(ra2 ** 2 - rb2 ** 2))
    if path < pb:
        raise SceneError(f"{src}: at the centre distance {a:.6g} m the path of contact "
                         f"({path:.6g} m) is shorter than the base pitch ({pb:.6g} m): contact "
                         f"ratio {path / pb:.3f} < 1, the gears do not mesh (standard centre "
                         f"distance {m1 * (z1 + z2) / 2:.6g} m)")
    phie = math.atan2(b2.y - b1.y, b2.x - b1.x)
    out = []
    psi_drive = rb1 * math.tan(alpha) - rb1 * (b1.angle - phie + alpha)
    for h, gap in ((1.0, 0.0), (-1.0, f.backlash)):
        raw = h * (rb1 * b1.angle + rb2 * b2.angle) - (rb1 + rb2) * (h * phie - alpha) \
            - a * math.sin(alpha)
        psi1 = psi_drive if h > 0 else \
            pb / 2 + 2 * rb1 * (math.tan(a1) - a1) - psi_drive
        out.append(np.array([rb1, rb2, ra1, ra2, pb, -gap - raw, f.stiffness, f.exponent,
                             f.damping, f.damping_depth, psi1, h]))
    return out


def resolve_tables(sc: Scene, tab: Tables, q0) -> None:
    """Fills in the tables' FROM_POSE values at q0, in the kernel, in place."""
    q0 = np.asarray(q0, float)
    bad_joint, bad_force, status = _kernel.tables_resolve(len(sc.bodies), tab.nj, tab.jint,
                                                          tab.jreal, tab.nf, tab.fint, tab.freal,
                                                          q0)
    if status != Status.SUCCESS:
        raise pose_error(sc, int(bad_joint), int(bad_force))


def pose_error(sc: Scene, bad_joint: int, bad_force: int) -> SceneError:
    """The error for an element whose value could not be taken from the initial pose."""
    if bad_force:
        f = sc.forces[bad_force - 1]
        return SceneError(f"{sc.source}: force {f.name!r}: fields 'point1' and 'point2' coincide "
                          "at the initial pose, so the element has no direction; move one "
                          "attachment point")
    if bad_joint:
        j = sc.joints[bad_joint - 1]
        if j.type == "distance":
            return SceneError(f"{sc.source}: joint {j.name!r}: fields 'point1' and 'point2' "
                              "coincide at the initial pose, so the distance has no direction; "
                              "move one point")
        return SceneError(f"{sc.source}: joint {j.name!r}: the value it keeps (a relative "
                          "angle, a length or an offset) cannot be taken from the initial pose: "
                          "its bodies are not in the scene's tables")
    return SceneError(f"{sc.source}: the initial pose is not finite")


def model_options(formulation: str = "reduced", alpha: float = 0.0, beta: float = 0.0,
                  penalty=(1e7, 10.0, 1.0), projection_tol: float = 1e-12, solver: str = "auto",
                  small_dense: bool = True) -> ModelOptions:
    """The kernel model's options (struct mbdk_model_options) from simulate's names: alpha and
    beta are Baumgarte's, penalty = (alpha_p, omega_p, mu_p) Jalon-Bayo's."""
    return ModelOptions(baumgarte_alpha=float(alpha), baumgarte_beta=float(beta),
                        penalty_alpha=float(penalty[0]), penalty_omega=float(penalty[1]),
                        penalty_mu=float(penalty[2]), projection_tol=float(projection_tol),
                        formulation=FORMULATIONS[formulation], solver=SOLVERS[solver],
                        small_dense=int(bool(small_dense)))


def _options(formulation: str, options: ModelOptions | None) -> ModelOptions:
    return replace(options or ModelOptions(), formulation=FORMULATIONS[formulation])


def evaluate(tab: Tables, q, v, t=0.0, formulation="reduced",
             options: ModelOptions | None = None) -> dict:
    """Phi, D, gamma, Phi_t, generalised forces f, accelerations a and multipliers lam at one
    state, from the kernel; solve: the linear solve the kernel took (LINEAR_SOLVES). options:
    model_options(...) for the solver and the formulation's parameters."""
    y = np.concatenate([np.asarray(q, float), np.asarray(v, float)])
    phi, d, gam, phit, fq, acc, lam, path, status = _kernel.model_eval(
        *tab.args(), _options(formulation, options).pack(), tab.m, float(t), y)
    return {"phi": phi, "D": d, "gamma": gam, "phit": phit, "f": fq, "a": acc, "lam": lam,
            "solve": LINEAR_SOLVES.get(int(path), "not built"), "status": Status(int(status))}


def profile(tab: Tables, q, v, t=0.0, formulation="reduced",
            options: ModelOptions | None = None, nrep: int = 100000) -> dict:
    """ns per evaluation of the assembly alone (forces, Phi, D, gamma) and of a full evaluation
    (assembly + the formulation's linear solve), timed in the kernel over nrep repetitions."""
    y = np.concatenate([np.asarray(q, float), np.asarray(v, float)])
    sec, status = _kernel.model_profile(*tab.args(), _options(formulation, options).pack(),
                                        float(t), y, int(nrep))
    if status != 0:
        raise exception_for(Status(int(status)))(f"profiling failed: {Status(int(status)).name}")
    return {"assembly_ns": 1e9 * sec[0] / nrep, "evaluation_ns": 1e9 * sec[1] / nrep,
            "solve_ns": 1e9 * (sec[1] - sec[0]) / nrep}


def scaled_jacobian(tab: Tables, d: np.ndarray) -> np.ndarray:
    """D made free of units, for rank tests of the geometry: each rotation column divided by
    its body's radius of gyration (its entries, lengths, become ratios), and the rows that are
    angles (a prismatic joint's first, a fixed joint's third, a driver of an angle) times the
    radius of gyration of their first body, a coupling to an angle times its second body's. A
    mechanism measured in millimetres then has the singular values of one in metres; masses
    enter only through the radii of gyration, so a light body beside heavy ones (an
    ill-conditioned D M^-1 D^T, at a regular pose) is not taken for a rank loss. A body without
    inertia is given the gyration radius of its largest joint point."""
    nb = len(tab.mass)
    reach = np.zeros(nb)
    for k in range(tab.nj):
        for b, pts in ((tab.jint[1, k], tab.jreal[0:2, k]), (tab.jint[2, k], tab.jreal[2:4, k])):
            if b > 0 and tab.jint[0, k] not in (JOINT_CODES["driver"], JOINT_CODES["coupling"]):
                reach[b - 1] = max(reach[b - 1], float(np.hypot(*pts)))
    gyr = np.sqrt(np.where(tab.inertia > 0, tab.inertia / tab.mass, 0.0))
    gyr = np.where(gyr > 0, gyr, np.where(reach > 0, reach, 1.0))
    col = np.empty(3 * nb)
    col[0::3] = col[1::3] = 1.0
    col[2::3] = 1.0 / gyr
    row = np.ones(tab.m)
    r = 0
    for k in range(tab.nj):
        code, b1 = tab.jint[0, k], tab.jint[1, k]
        g = gyr[b1 - 1] if b1 > 0 else 1.0
        if code == JOINT_CODES["prismatic"]:
            row[r] = g
        elif code == JOINT_CODES["fixed"]:
            row[r + 2] = g
        elif code == JOINT_CODES["driver"] and tab.jint[3, k] == 3:
            row[r] = g
        elif code == JOINT_CODES["coupling"] and tab.jreal[5, k] != 0:
            # in radians (body 2's angle): as an angle row
            row[r] = gyr[tab.jint[2, k] - 1]
        r += JOINT_ROWS_BY_CODE[code]
    return row[:, None] * d * col[None, :]


#: the largest D (entries) whose singular values an error message computes to name joints: the
#: SVD costs O(m nc^2), minutes beyond this; a larger scene's message names no joints
DENSE_NAMING_MAX = 4_000_000


def dependent_rows(d: np.ndarray, tol: float = 1e-9):
    """Rows of D that are linear combinations of the others: the left null space of D (give it
    scaled_jacobian's D, free of units). Empty for a D of more than DENSE_NAMING_MAX entries."""
    if d.shape[0] == 0 or d.size > DENSE_NAMING_MAX:
        return []
    u, s, _ = np.linalg.svd(d)
    smax = s[0] if s.size else 0.0
    rank = int(np.sum(s > tol * max(smax, 1.0)))
    if rank == d.shape[0]:
        return []
    null = u[:, rank:]
    return [i for i in range(d.shape[0]) if np.max(np.abs(null[i])) > 1e-8]


def rows_to_joints(tab: Tables, rows) -> list[str]:
    out = []
    for name, r0, n in tab.rows:
        if any(r0 <= r < r0 + n for r in rows):
            out.append(name)
    return out


def given_mask(sc: Scene) -> np.ndarray:
    """1 where the scene marks a coordinate (x, y, angle) or rate (vx, vy, omega) as given: the
    kernel's assembly leaves those alone. Layout [q; v] as the state."""
    nb = len(sc.bodies)
    g = np.zeros(6 * nb, np.int32)
    for i, b in enumerate(sc.bodies):
        for k, c in enumerate(("x", "y", "angle")):
            g[3 * i + k] = c in b.given
        for k, c in enumerate(("vx", "vy", "omega")):
            g[3 * nb + 3 * i + k] = c in b.given
    return g


def assembly_report(sc: Scene, q_in, v_in, q, v, iterations: int) -> dict:
    """What the assembly changed, by body and coordinate."""
    changes = {}
    for i, b in enumerate(sc.bodies):
        for k, c in enumerate(("x", "y", "angle")):
            if abs(q[3 * i + k] - q_in[3 * i + k]) > 1e-12:
                changes[f"{b.name}.{c}"] = float(q[3 * i + k] - q_in[3 * i + k])
        for k, c in enumerate(("vx", "vy", "omega")):
            if abs(v[3 * i + k] - v_in[3 * i + k]) > 1e-12:
                changes[f"{b.name}.{c}"] = float(v[3 * i + k] - v_in[3 * i + k])
    return {"moved_q": float(np.max(np.abs(q - q_in), initial=0.0)),
            "moved_v": float(np.max(np.abs(v - v_in), initial=0.0)), "iterations": int(iterations),
            "changes": changes}


def assembly_error(sc: Scene, tab: Tables, resid, velocity: bool) -> SceneError:
    """The error of a failed assembly, naming the joints of the largest residual rows."""
    resid = np.asarray(resid, float)[:tab.m]
    worst = [i for i in np.argsort(-np.abs(resid))[:3] if abs(resid[i]) > 1e-9]
    names = ", ".join(rows_to_joints(tab, worst))
    if velocity:
        return SceneError(f"{sc.source}: the initial velocities cannot be made consistent: "
                          f"joint(s) {names} keep a velocity residual of "
                          f"{np.max(np.abs(resid)):.3g} with the given rates")
    return SceneError(f"{sc.source}: the initial position cannot be assembled: joint(s) {names} "
                      f"stay violated by up to {np.max(np.abs(resid)):.3g} after Newton on the "
                      "coordinates not marked 'given'. Check the lengths and points of these "
                      "joints, or un-mark given coordinates")


def assemble(sc: Scene, tab: Tables, t0: float = 0.0):
    """Initial q, v satisfying Phi = 0 and D v + Phi_t = 0, changing only the coordinates the
    scene does not mark as given (least change, Gauss-Newton: the kernel's mbdk_assembly).
    Returns (q, v, report)."""
    q_in = np.array(sc.q0(), float)
    v_in = np.array(sc.v0(), float)
    q, v = q_in.copy(), v_in.copy()
    if tab.m == 0:
        return q, v, assembly_report(sc, q_in, v_in, q, v, 0)
    iters, resid, velocity, status = _kernel.model_assemble(*tab.args(), float(t0), q, v,
                                                            given_mask(sc), max(tab.m, 1))
    if status == Status.ERR_INCONSISTENT_INITIAL:
        raise assembly_error(sc, tab, resid, velocity=bool(velocity))
    if status != Status.SUCCESS:
        raise exception_for(Status(int(status)))(f"{sc.source}: assembly failed: "
                                                 f"{Status(int(status)).name}",
                                                 status=Status(int(status)))
    return q, v, assembly_report(sc, q_in, v_in, q, v, iters)
