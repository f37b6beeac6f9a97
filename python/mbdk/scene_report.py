"""What a scene is, before it runs (Fekete 2023, chapter 1 and section 3.1): its coordinates,
constraint rows and degrees of freedom (1.26), (2.141), the redundant joints named, each
constraint classified as table 1.1 does (holonomic or not, scleronomic or rheonomic, bilateral
or unilateral), and the differentiation index of its DAE.

>>> rep = mbdk.scene_report(mbdk.scene("four_bar"))
>>> rep.coordinates, rep.rows, rep.rank, rep.dof, rep.redundant, rep.index
(9, 8, 8, 1, [], 3)
>>> print(rep)                      # doctest: +ELLIPSIS
scene 'four_bar' (planar): 3 bodies, 9 coordinates, 9 velocities
...

The degrees of freedom are the coordinates' velocities less the rank of the constraint
Jacobian at the assembled initial pose (D for planar scenes, C on the bodies' velocities for
spatial ones), not the row count: a redundant joint (the parallelogram's third link, Bricard's
linkage) takes no freedom, and the report names the joints whose rows are dependent (the rank
test of mbdk.model.dependent_rows, on the unit-free Jacobian). Contacts are unilateral, but
compliant: forces, not rows, so they take no freedom; they are listed as such.

The index is counted, not looked up: a position-level (holonomic) row must be differentiated
twice to reach the accelerations, D q'' = gamma; there the multipliers follow algebraically
where [M B^T; B 0] is regular, B a basis of the independent rows (checked: with a body without
inertia that needs the joints to hold it), and one more differentiation gives their
derivatives: index 3. A velocity-level (nonholonomic) row, a knife edge's, needs one
differentiation less: a scene whose rows are all such is index 2. A scene without rows is an
ODE (index 0). With nonholonomic rows the freedom of position (coordinates less the rank of
the holonomic rows) exceeds the freedom of motion (velocities less the rank of all rows).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import InvalidInputError
from .model import (assemble, build_tables, dependent_rows, evaluate, rows_to_joints,
                    scaled_jacobian)
from .scene import Scene
from .scene_file import checked
from .spatial_model import evaluate_spatial


@dataclass
class ConstraintInfo:
    name: str
    type: str
    rows: int
    holonomic: bool
    rheonomic: bool
    bilateral: bool

    def kind(self) -> str:
        return ", ".join(("holonomic" if self.holonomic else "nonholonomic",
                          "rheonomic" if self.rheonomic else "scleronomic",
                          "bilateral" if self.bilateral else "unilateral"))


@dataclass
class SceneReport:
    scene: str
    kind: str                 # "planar" or "spatial"
    bodies: int
    coordinates: int          # position coordinates (7 per spatial body with quaternions)
    velocities: int           # independent velocities (3 per planar body, 6 per spatial one)
    rows: int                 # constraint rows
    rank: int                 # rank of the constraint Jacobian at the assembled pose
    dof: int                  # velocities - rank: the freedom of motion
    redundant: list = field(default_factory=list)     # joints with dependent rows
    constraints: list = field(default_factory=list)   # ConstraintInfo per joint
    contacts: list = field(default_factory=list)      # unilateral, compliant (forces)
    effects: list = field(default_factory=list)       # states of their own (wear)
    index: int = 0
    index_reason: str = ""
    #: coordinates - the rank of the holonomic rows: the freedom of position, larger than dof
    #: by the independent nonholonomic rows (a car parks anywhere, but cannot slide sideways)
    configuration_dof: int = 0

    def __str__(self) -> str:
        lines = [f"scene {self.scene!r} ({self.kind}): {_n(self.bodies, 'body', 'bodies')}, "
                 f"{_n(self.coordinates, 'coordinate')}, {_n(self.velocities, 'velocity', 'velocities')}",
                 f"constraint rows {self.rows}, rank {self.rank}: "
                 f"{_n(self.dof, 'degree')} of freedom"]
        if self.configuration_dof != self.dof:
            lines.append(f"nonholonomic: {_n(self.configuration_dof, 'degree')} of freedom of "
                         f"position (coordinates less the holonomic rows' rank), {self.dof} of "
                         "velocity")
        if self.redundant:
            lines.append(f"redundant: {self.rows - self.rank} row(s) among the joints "
                         f"{', '.join(self.redundant)} (their rows are dependent; leaving out "
                         f"{self.rows - self.rank} of them leaves the rest independent, and the "
                         "freedom unchanged)")
        for c in self.constraints:
            lines.append(f"  joint {c.name!r} ({c.type}, {_n(c.rows, 'row')}): {c.kind()}")
        for name in self.contacts:
            lines.append(f"  contact {name!r}: unilateral, compliant (a force; no rows)")
        for name in self.effects:
            lines.append(f"  wear {name!r}: a state of its own")
        lines.append(f"differentiation index {self.index}: {self.index_reason}")
        return "\n".join(lines)


def _index(rows: int, schur_regular: bool, velocity_rows: int = 0) -> tuple[int, str]:
    if rows == 0:
        return 0, "no constraint rows: an ODE"
    if not schur_regular:
        raise InvalidInputError("the mass matrix is singular on the motions the joints allow (a "
                                "body without inertia that no joint holds): the multipliers do not "
                                "follow from the accelerations, and the index is not defined; "
                                "give the body an inertia or a joint")
    if velocity_rows == rows:
        return 2, ("the rows constrain velocities only (A v = b): differentiated once they give "
                   "A q'' = gamma, where [M A^T; A 0] is regular on the independent rows, so "
                   "lambda follows algebraically; once more for lambda'")
    why = ("Phi differentiated twice gives D q'' = gamma, where [M D^T; D 0] is regular "
           "on the independent rows, so lambda follows algebraically; once more for lambda'")
    if velocity_rows:
        why += (f" (the {velocity_rows} nonholonomic row(s) need one differentiation less: "
                "index 2 in those)")
    return 3, why


def scene_report(sc) -> SceneReport:
    """The report of a Scene of either body kind (the module docstring); a scene that does
    not assemble raises the assembly's named error."""
    if not isinstance(sc, Scene):
        raise InvalidInputError(f"scene must be an mbdk Scene, got {type(sc).__name__}")
    if sc.kind == "spatial":
        return _spatial_report(sc)
    sc = checked(sc)
    tab = build_tables(sc)
    q, v, _ = assemble(sc, tab)
    tab = build_tables(sc, q)
    e = evaluate(tab, q, v)
    d = e["D"]
    rank, redundant, regular = 0, [], True
    if tab.m:
        ds = scaled_jacobian(tab, d)
        s = np.linalg.svd(ds, compute_uv=False)
        rank = int(np.sum(s > 1e-9 * max(s[0], 1.0)))
        redundant = rows_to_joints(tab, dependent_rows(ds)) if rank < tab.m else []
        # lambda follows from the accelerations where [M B^T; B 0] is regular, B a basis of
        # D's row space: M positive on the motions the joints allow (a body without inertia
        # must be held by them). With M > 0 that always holds; it is the zero inertias it tests
        b = np.linalg.svd(d)[2][:rank]
        kkt = np.block([[np.diag(tab_mass(tab)), b.T], [b, np.zeros((rank, rank))]])
        regular = np.linalg.matrix_rank(kkt) == tab.nc + rank
    constraints = []
    holo = np.ones(tab.m, bool)
    for (name, r0, nr), j in zip(tab.rows, sc.joints):
        rheo = j.type == "driver" or (j.type == "distance" and j.length is not None and
                                      (j.length[1] != 0 or j.length[2] != 0))
        # a knife edge's A v = 0 is not integrable: the blade's direction turns with the body
        # (unless a driver holds its heading constant, which the report does not look for: it
        # then counts one freedom of position too many); a rolling disc's velocity rows are
        # integrable, to its two position rows (1.18), (1.20)
        holonomic = j.type != "knife_edge"
        holo[r0:r0 + nr] = holonomic
        constraints.append(ConstraintInfo(name, j.type, nr, holonomic, rheo, True))
    rank_h = rank
    if tab.m and not holo.all():
        sh = np.linalg.svd(scaled_jacobian(tab, d)[holo], compute_uv=False)
        rank_h = int(np.sum(sh > 1e-9 * max(sh[0], 1.0))) if sh.size else 0
    index, reason = _index(tab.m, regular, int((~holo).sum()))
    return SceneReport(sc.name, "planar", len(sc.bodies), tab.nc, tab.nc, tab.m, rank,
                       tab.nc - rank, redundant, constraints,
                       [f.name for f in sc.forces if f.type == "contact"],
                       [w_.name for w_ in sc.wear], index, reason, tab.nc - rank_h)


def tab_mass(tab) -> np.ndarray:
    """The diagonal of M in the tables' coordinate order (x, y, theta per body)."""
    return np.stack([tab.mass, tab.mass, tab.inertia], axis=1).ravel()


def _spatial_report(sc) -> SceneReport:
    """The spatial model's own rank (its geometric test at the initial state); the redundant
    joints from the left null space of C with the rotation columns weighted by the bodies'
    spread (a rotation as the displacement it gives there)."""
    e = evaluate_spatial(sc)
    nb = len(sc.bodies)
    rows = int(sc.rows)
    rank = int(e["rank"]) if rows else 0
    coords = len(sc.state0()) - 6 * nb
    table = sc.joint_rows()
    redundant = []
    if rank < rows:
        pos = np.array([b.position for b in sc.bodies], float)
        scale = max(float(np.max(np.linalg.norm(pos - pos.mean(axis=0), axis=1))), 1e-3)
        c = np.array(e["C"], float).reshape(rows, -1).copy()
        for b in range(nb):
            c[:, 6 * b + 3:6 * b + 6] /= scale
        dep = dependent_rows(c)
        redundant = [name for name, r0, n in table if any(r0 <= r < r0 + n for r in dep)]
    constraints = [ConstraintInfo(name, j.type, n, True, j.type.endswith("_driver"), True)
                   for (name, _r0, n), j in zip(table, sc.joints)]
    index, reason = _index(rows, True)
    return SceneReport(sc.name, "spatial", nb, coords, 6 * nb, rows, rank, 6 * nb - rank,
                       redundant, constraints,
                       [f.name for f in sc.forces if f.type in ("sphere_plane", "sphere_sphere")],
                       [w.name for w in sc.wear], index, reason, 6 * nb - rank)


def _n(count: int, one: str, many: str | None = None) -> str:
    """'1 body', '3 bodies': the count with its noun in the right number."""
    return f"{count} {one if count == 1 else (many or one + 's')}"
