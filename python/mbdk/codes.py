"""The codes Python passes to the kernel, in one module.

Where the kernel exports a table, the codes are read from it: the element kinds of planar and
spatial scenes (joints, forces and effects, kernel/src/model/mbdk_elements.f90: one code per
name, with the body kinds each applies to, its constraint rows on each and its visit counter)
and the body kinds here, the methods' names and ids in mbdk.methods, the status codes' names and
messages in mbdk.errors (whose Status mirrors them).

The kernel has no exported table of the others yet: they are kept here, each beside the name of
the kernel constants it mirrors. tests/test_codes.py compares each table with the kernel's
named constants (its Fortran parameter definitions, read from kernel/src) and, where the f2py
entry takes a bare number, with what the kernel does with the code (a run in each form, a scene
of each spatial joint and force type evaluated). Nothing else in the package writes a code the
kernel reads.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from . import _kernel
from .errors import decode_text

# ---- read from the kernel's registries -------------------------------------------------------


class ElementKind(NamedTuple):
    """One kind of the kernel's element registry: its class (JOINT_CLASS, FORCE_CLASS,
    EFFECT_CLASS), its code within the class's table, its name, its constraint rows on each
    body kind it applies to (body kind name -> rows; forces and effects have 0) and the states
    it carries."""
    cls: int
    code: int
    name: str
    rows: dict
    states: int


def _body_kinds() -> dict:
    """The kernel's body kinds: name -> (code, coordinates, velocities, available: a model of
    the kernel runs bodies of the kind)."""
    out, i = {}, 1
    while True:
        code, name, coords, vels, available = _kernel.body_kind(i)
        if code == 0:
            return out
        out[decode_text(name)] = (int(code), int(coords), int(vels), bool(available))
        i += 1


def _element_kinds(bodies: dict) -> list[ElementKind]:
    """The kernel's element registry, in the order of the visit counters."""
    out, i = [], 1
    while True:
        cls, code, name, on, rows, states = _kernel.element_kind(i)
        if cls == 0:
            return out
        out.append(ElementKind(int(cls), int(code), decode_text(name),
                               {body: int(rows[c - 1]) for body, (c, *_r) in bodies.items()
                                if int(on) >> (c - 1) & 1}, int(states)))
        i += 1


BODY_KINDS = _body_kinds()
ELEMENT_KINDS = _element_kinds(BODY_KINDS)
JOINT_CLASS, FORCE_CLASS, EFFECT_CLASS = 1, 2, 3


def _codes(cls: int, body: str) -> dict:
    """name -> code of the registry's kinds of a class that apply to a body kind."""
    return {e.name: e.code for e in ELEMENT_KINDS if e.cls == cls and body in e.rows}


#: planar joint types -> the kernel's codes, and their constraint rows
JOINT_CODES = _codes(JOINT_CLASS, "planar")
JOINT_ROWS = {e.name: e.rows["planar"] for e in ELEMENT_KINDS
              if e.cls == JOINT_CLASS and "planar" in e.rows}
JOINT_ROWS_BY_CODE = {JOINT_CODES[name]: rows for name, rows in JOINT_ROWS.items()}
_FORCE_KINDS = _codes(FORCE_CLASS, "planar")
#: planar force types -> the kernel's codes; the coordinate spring and damper are one kernel kind
FORCE_CODES = {**_FORCE_KINDS, "coordinate_spring": _FORCE_KINDS["coordinate_spring_damper"],
               "coordinate_damper": _FORCE_KINDS["coordinate_spring_damper"]}
EFFECT_CODES = _codes(EFFECT_CLASS, "planar")
#: the kernel's visit counters, in its order: one per element kind
VISIT_NAMES = [e.name for e in ELEMENT_KINDS]
#: the counters a planar run reports (its SceneResult.visits): (position, name) of each kind
#: that applies to planar bodies
PLANAR_VISITS = [(k, e.name) for k, e in enumerate(ELEMENT_KINDS) if "planar" in e.rows]
#: spatial joint and force types -> the kernel's codes (the same registry: a name that planar
#: scenes have too keeps its code), and the joints' constraint rows in a spatial scene. A
#: spatial file's spring and damper are spring_dampers (python/mbdk/spatial_file.py), a contact
#: is sphere_plane or sphere_sphere by its second shape
SPATIAL_JOINT_CODES = _codes(JOINT_CLASS, "spatial")
SPATIAL_JOINT_ROWS = {e.name: e.rows["spatial"] for e in ELEMENT_KINDS
                      if e.cls == JOINT_CLASS and "spatial" in e.rows}
SPATIAL_FORCE_CODES = _codes(FORCE_CLASS, "spatial")
#: effects of spatial scenes (wear), written in their force table after the forces
SPATIAL_EFFECT_CODES = _codes(EFFECT_CLASS, "spatial")

# ---- the kernel's structs (kernel/src/api/mbdk_structs.f90), laid out by mbdk.options ---------

#: the structs' ids (MBDK_STRUCT_*); the kernel names each, and mbdk.options checks the name
STRUCT_IDS = {"mbdk_stats": 1, "mbdk_options": 2, "mbdk_index3_options": 3,
              "mbdk_model_options": 4, "mbdk_spatial_options": 5, "mbdk_watch_report": 6}
#: a field's type code (MBDK_FIELD_INT, _INT64, _DOUBLE, _POINTER) -> its numpy type
FIELD_TYPES = {1: np.intc, 2: np.int64, 3: np.float64, 4: np.uintp}

# ---- the methods (kernel/src/core/mbdk_methods.f90), names and ids read by mbdk.methods -------

#: the kernel's method families (MBDK_FAMILY_*), as its method_info returns them
METHOD_FAMILIES = {1: "explicit_rk", 2: "euler_cromer", 3: "implicit_lmm", 4: "dae_index3",
                   5: "embedded_rk", 6: "variable_bdf", 7: "cvode", 8: "ida"}

# ---- the planar model (kernel/src/model), no exported table yet ------------------------------

#: MBDK_FORM_* of kernel/src/core/mbdk_mechanism.f90, the codes of both models
FORMULATIONS = {"reduced": 1, "baumgarte": 2, "penalty": 3, "projection": 4}
#: MBDK_SOLVER_* of mbdk_model.f90. solver="auto" takes revolute_schur when every joint is
#: revolute (and M is positive, up to 12 constraint rows), else schur when M is positive (sparse
#: above 12 constraint rows), else kkt; "schur" is the dense Schur complement at any size,
#: "sparse" the sparse one at any size
SOLVERS = {"auto": 1, "schur": 2, "kkt": 3, "revolute_schur": 4, "sparse": 5}
#: constraint rows above which solver="auto" goes sparse (MBDK_SPARSE_MIN_ROWS)
SPARSE_MIN_ROWS = 12
#: the general dense factorisations (kernel/src/linalg/mbdk_lapack.f90): LAPACK's algorithms,
#: written out in one order of sums up to this order (MBDK_FIXED_ORDER_MAX) so that every BLAS
#: kernel gives the same bits, LAPACK's own above
FIXED_ORDER_MAX = 128
DENSE_CHOLESKY = (f"dense Cholesky (mbdk_lapack: in one order of sums up to {FIXED_ORDER_MAX} "
                  "rows, LAPACK dpotrf above)")
DENSE_LU = (f"dense LU (mbdk_lapack: in one order of sums up to {FIXED_ORDER_MAX} unknowns, "
            "LAPACK dgetrf above)")
#: the linear solve an evaluation takes, by the kernel's MBDK_SOLVE_* code (mbdk_constrained)
LINEAR_SOLVES = {0: "none (no constraints)",
                 1: "revolute_schur: S = D M^-1 D^T in closed 2 x 2 blocks, block LDL^T",
                 2: "schur: S = D M^-1 D^T from the nonzeros of D, in-house block LDL^T",
                 3: f"schur: S = D M^-1 D^T from the nonzeros of D, {DENSE_CHOLESKY}",
                 4: f"kkt: [M D^T; D 0] by {DENSE_LU}",
                 5: "penalty: M + ap D^T D, in-house LDL^T",
                 6: f"penalty: M + ap D^T D, {DENSE_CHOLESKY}",
                 7: "sparse: S = D M^-1 D^T kept sparse, SuiteSparse AMD + LDL"}
#: the outputs a planar run computes at its samples, the bits of scene_run's want
#: (MBDK_OUT_* of mbdk_model.f90)
OUTPUTS = {"a": 1, "multipliers": 2, "reactions": 4, "energy": 8, "residuals": 16}
#: a planar body's coordinates, as a driver, a coupling or a coordinate spring names them
COORDS = {"x": 1, "y": 2, "angle": 3}
#: a contact's body2 shape -> the kernel's geometry code (MBDK_CONTACT_* of mbdk_contact.f90)
CONTACT_GEOMETRY = {"line": 1, "circle": 2, "ring": 3, "gear": 4}
#: wear laws and the contact quantity they take (MBDK_WEAR_* of mbdk_wear.f90)
WEAR_LAWS = {"archard": 1, "gear": 2, "knee": 3}
WEAR_LOADS = {"normal_force": 1, "friction_force": 2}
#: the 4th integer of a two-point force or a prismatic, fixed, distance, coupling or rolling
#: joint: take the value (rest length, relative angle, length, offset) from the initial pose
#: (MBDK_FROM_POSE of mbdk_assembly.f90)
FROM_POSE = 1
#: trapezoidal_index3's forms (MBDK_INDEX3_BOOK, MBDK_INDEX3_AUGMENTED of
#: kernel/src/dae/mbdk_trapezoidal_index3.f90)
INDEX3_FORMULATIONS = {"index3": 1, "augmented_lagrangian": 2}
#: trapezoidal_index3's adaptive= values and the kernel's opt%adaptive codes: local Richardson
#: extrapolation of two half-steps against the full step (True; order 3), or the step's error
#: estimated from differences of the accelerations (order 2: on P1 no distribution of its steps
#: saves more than 8 %, studies/step_control.py) (MBDK_INDEX3_EXTRAPOLATED, _ESTIMATED)
ADAPTIVE_MODES = {False: 0, True: 2, "extrapolated": 2, "estimated": 1}
#: the Newton matrix's scaling of mbdk.index3.newton_matrix (MBDK_INDEX3_UNSCALED,
#: MBDK_INDEX3_SCALED_BOOK, MBDK_INDEX3_SCALED of kernel/src/dae/mbdk_index3_matrix.f90)
INDEX3_SCALINGS = {"unscaled": 0, "book": 1, "scaled": 2}
#: the multistep methods' start-up (mbdk_options' startup)
STARTUP = {"rk4": 0, "bdf": 1}
#: the dae_form of scene_run and spatial_run by method (the same rule for both: kernel/src/api/
#: mbdk_entry.f90): ida's forms of the scene's DAE (kernel/src/sundials/mbdk_ida.f90) and bdf's
#: (MBDK_DAE_I3, MBDK_DAE_SI2 of kernel/src/dae/mbdk_mechanism_dae.f90, as MSC Adams' GSTIFF I3
#: and SI2); MBDK_DAE_NONE (0) for every other run, the index-3 family's included
DAE_FORMS = {"ida": {"index1": 1, "ggl": 2}, "bdf": {"i3": 1, "si2": 2}}
DAE_NONE = 0

#: the DAE methods' Newton matrices (kernel/src/implicit/mbdk_variable_bdf.f90,
#: kernel/src/sundials/mbdk_ida.f90): the manifest's newton_matrix (a spatial run's
#: linear_solve too: the spatial model takes no constrained solve of its own into a DAE run).
#: Dense, or sparse on a scene whose constraint rows the model keeps compact (its solves are
#: sparse: a large scene; not a planar scene with contacts, not a knife edge, and for bdf not
#: a planar body without inertia), which the run's stats.nlu_sparse shows
#: (kernel/src/dae/mbdk_mechanism_dae.f90; ida's by SUNDIALS' KLU).
DAE_NEWTON_MATRIX = {"bdf": "bdf's Newton matrix E - c J by differences over the DAE's state "
                            f"({DENSE_LU})",
                     "bdf_sparse": "bdf's Newton matrix E - c J in the body graph's pattern: "
                                   "the bodies' columns by colored differences, the "
                                   "multipliers' exact; sparse L D U (AMD, SuiteSparse LDL's "
                                   "analysis)",
                     "ida": "IDA's dense difference quotients, SUNDIALS dense LU",
                     "ida_sparse": "IDA's Newton matrix in the body graph's pattern by colored "
                                   "difference quotients, SUNDIALS KLU"}


def dae_newton_matrix(method: str, stats) -> str:
    """The manifest's newton_matrix of a DAE run by method ('bdf' or 'ida') with these stats
    (a run that stopped before its first factorisation had none)."""
    if stats is not None and stats.nlu == 0:
        return "none factorised (the run stopped before its first Newton matrix)"
    if stats is not None and stats.nlu_sparse:
        return DAE_NEWTON_MATRIX[method + "_sparse"]
    return DAE_NEWTON_MATRIX[method]

# ---- the spatial model (kernel/src/spatial/mbdk_spatial_model.f90), no exported table yet ----
# (its joint and force codes are the element registry's, above)

#: the reals per joint and per force (MBDK_SPATIAL_JOINT_REALS, MBDK_SPATIAL_FORCE_REALS: as
#: many as a contact has, kernel/src/spatial/mbdk_contact3d.f90; the other kinds use the first)
SPATIAL_JOINT_REALS, SPATIAL_FORCE_REALS = 17, 19
#: the orientation coordinates (MBDK_ROT_*) and how |p| = 1 is kept (MBDK_NORM_*)
ROTATIONS = {"quaternion": 1, "euler313": 2, "cardan123": 3}
NORMS = {"project": 1, "stabilise": 2, "none": 3}
#: the parametrisation rotation_matrix (the f2py entry) takes, its kind argument (mbdk.rotations)
ROTATION_PARAMETRISATIONS = {"angles": 1, "quaternion": 2, "axis_angle": 3}
#: the frame of an angular velocity, the body argument of the f2py entries angle_rates,
#: quaternion_ops and quaternion_omega
FRAMES = {"space": 0, "body": 1}
#: the spatial model's formulations: the planar model's codes (MBDK_FORM_* of mbdk_mechanism)
SPATIAL_FORMULATIONS = FORMULATIONS

