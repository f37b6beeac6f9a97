"""The large-scene path (solver="sparse", and solver="auto" above 12 constraint rows): the
Schur complement S = D M^-1 D^T, trapezoidal_index3's augmented Newton matrix and the initial
assembly factorised by SuiteSparse's AMD + LDL (kernel/src/linalg/mbdk_sparse_ldlt.f90).

Reference: the dense path (solver="schur": the same equations through LAPACK's dense Cholesky,
kernel/src/model/mbdk_constrained.f90), run on the same scene in the same process. Both solve
the same linear systems exactly, so they agree to roundoff (the ODE formulations) or to Newton's
tolerance (trapezoidal_index3, whose sparse Newton matrix is the symmetric part of the dense one
where dampers make it unsymmetric)."""
import numpy as np
import pytest

import mbdk
from mbdk.errors import RedundantConstraintsError
from mbdk.benchmarks import a02_chain, a02_crank, bar_chain
from mbdk.scene_file import scene_from_dict

SPARSE = "sparse: S = D M^-1 D^T kept sparse, SuiteSparse AMD + LDL"


def chain(n, angle_deg=0.0):
    """n bars on revolute joints hinged to the ground (mbdk.benchmarks.bar_chain): 2 n rows."""
    return bar_chain(n, angle_deg)


def mixed(n):
    """Every joint and force kind on one large scene: a trolley on a prismatic slider (with a
    coordinate spring-damper), a chain of n bars hinged to it, a tip welded to the last bar
    (fixed joint), spring-dampers between every third bar and the one two further, dampers to
    the ground, a torque and a point force: 2 + 2 n + 3 rows."""
    bodies = [{"name": "trolley", "mass": 10.0, "shape": {"type": "rectangle", "width": 0.4,
                                                          "height": 0.2}, "x": 0.0, "y": 0.0}]
    joints = [{"name": "slider", "type": "prismatic", "body1": "trolley", "body2": "ground",
               "axis": [1.0, 0.0]}]
    forces = [{"type": "gravity", "g": [0.0, -9.81]},
              {"name": "cs", "type": "coordinate_spring_damper", "body": "trolley",
               "coordinate": "x", "stiffness": 300.0, "damping": 5.0, "rest": 0.0}]
    for i in range(n):
        bodies.append({"name": f"b{i}", "mass": 1.0 + 0.1 * i,
                       "shape": {"type": "bar", "length": 1.0},
                       "x": i + 0.5, "y": 0.0, "angle_deg": 0.0})
        joints.append({"name": f"J{i}", "type": "revolute", "body1": f"b{i}",
                       "point1": [-0.5, 0.0], "body2": f"b{i - 1}" if i else "trolley",
                       "point2": [0.5, 0.0] if i else [0.0, 0.0]})
        if i % 3 == 0 and i + 2 < n:
            forces.append({"name": f"sd{i}", "type": "spring_damper", "body1": f"b{i}",
                           "point1": [0.25, 0.0], "body2": f"b{i + 2}", "point2": [-0.25, 0.0],
                           "stiffness": 50.0, "damping": 2.0})
        if i % 4 == 1:
            forces.append({"name": f"d{i}", "type": "damper", "body1": f"b{i}",
                           "point1": [0.5, 0.0], "point2": [i + 1.0, -1.0], "damping": 1.0})
    bodies.append({"name": "tip", "mass": 0.5, "shape": {"type": "disc", "radius": 0.1},
                   "x": n + 0.1, "y": 0.0})
    joints.append({"name": "weld", "type": "fixed", "body1": "tip", "body2": f"b{n - 1}",
                   "point1": [0.0, 0.0], "point2": [0.6, 0.0]})
    forces += [{"name": "tq", "type": "torque", "body": "b1", "torque": 2.0},
               {"name": "pf", "type": "point_force", "body": f"b{n // 2}", "point": [0.5, 0.0],
                "force": [0.0, 5.0]}]
    return scene_from_dict({"scene": {"name": f"mixed{n}"}, "body": bodies, "joint": joints,
                            "force": forces})


def _pair(scene, method, formulation, **kw):
    out = {}
    for solver in ("schur", "sparse"):
        out[solver] = mbdk.simulate(scene, method, formulation=formulation, solver=solver, **kw)
    return out["schur"], out["sparse"]


@pytest.mark.parametrize("formulation", ["reduced", "baumgarte", "projection"])
def test_sparse_ode_forms_agree_with_dense_on_a_chain(formulation):
    dense, sparse = _pair(chain(30, -20.0), "rk4", formulation, h=1e-3, t_end=0.4, every=40)
    assert sparse.manifest["linear_solve"] == SPARSE
    assert dense.manifest["linear_solve"] != SPARSE
    assert np.max(np.abs(sparse.q - dense.q)) < 1e-11
    assert np.max(np.abs(sparse.v - dense.v)) < 1e-9
    lam_scale = np.max(np.abs(dense.multipliers))
    assert np.max(np.abs(sparse.multipliers - dense.multipliers)) < 1e-8 * lam_scale


def test_sparse_index3_agrees_with_dense_on_a_chain():
    dense, sparse = _pair(chain(30, -20.0), "trapezoidal_index3", "augmented_lagrangian",
                          h=1e-3, t_end=0.4, every=40)
    assert sparse.manifest["linear_solve"] == SPARSE
    # Newton stops at 1e-10 relative: both runs land within it of the same solution
    assert np.max(np.abs(sparse.q - dense.q)) < 1e-9
    assert np.max(np.abs(sparse.residuals[:, 0])) < 1e-10


@pytest.mark.parametrize("method,formulation", [("rk4", "reduced"), ("rk4", "penalty"),
                                                ("trapezoidal_index3", "augmented_lagrangian")])
def test_sparse_path_agrees_with_dense_with_every_element_kind(method, formulation):
    """Prismatic, revolute and fixed joints, two-point spring-dampers and dampers (whose
    tangent is unsymmetric), torques, point and coordinate forces on a 45-row scene."""
    sc = mixed(20)
    dense, sparse = _pair(sc, method, formulation, h=5e-4, t_end=0.3, every=60)
    if formulation != "penalty":
        assert sparse.manifest["linear_solve"] == SPARSE
    assert np.max(np.abs(sparse.q - dense.q)) < 1e-8
    assert np.max(np.abs(sparse.v - dense.v)) < 1e-6
    # the dampers did work: a scene where the unsymmetric terms matter
    assert dense.energy_parts["dissipated_dampers"][-1] > 1e-3


def test_auto_goes_sparse_above_12_rows_only():
    small = mbdk.simulate(chain(6), "rk4", h=1e-3, t_end=1e-3)      # 12 rows
    large = mbdk.simulate(chain(7), "rk4", h=1e-3, t_end=1e-3)      # 14 rows
    assert small.manifest["linear_solve"].startswith("revolute_schur")
    assert large.manifest["linear_solve"] == SPARSE
    # solver="schur" keeps the dense Schur complement at any size
    dense = mbdk.simulate(chain(7), "rk4", h=1e-3, t_end=1e-3, solver="schur")
    assert "LAPACK" in dense.manifest["linear_solve"]


def test_sparse_assembly_moves_the_same_least_change_as_the_dense_least_squares():
    """A chain whose bodies are displaced off the joints: the assembly (Gauss-Newton, each
    correction the least change of the free coordinates) lands on the same pose whether its
    corrections come from the dense least squares (mbdk_least_squares) or the sparse Schur
    complement."""
    sc = chain(30, -30.0)
    rng = np.random.default_rng(7)
    for b in sc.bodies:
        b.x += 0.01 * rng.standard_normal()
        b.y += 0.01 * rng.standard_normal()
        b.omega = 0.3 * rng.standard_normal()
    sc.bodies[0].given = ["angle"]
    dense, sparse = _pair(sc, "rk4", "reduced", h=1e-3, t_end=1e-3)
    assert dense.assembly["iterations"] > 0
    assert np.max(np.abs(sparse.q[0] - dense.q[0])) < 1e-12
    assert np.max(np.abs(sparse.v[0] - dense.v[0])) < 1e-12
    assert sparse.q[0][2] == sc.bodies[0].angle      # a given coordinate stays


def test_sparse_path_names_redundant_joints_as_the_dense_one_does():
    """A chain whose tip is hinged to the ground twice at the same point: dependent rows."""
    sc = chain(25, 0.0)
    for name in ("T1", "T2"):
        sc.joints.append(type(sc.joints[0])(name=name, type="revolute", body1="b24",
                                            point1=(0.5, 0.0), body2="ground",
                                            point2=(25.0, 0.0)))
    with pytest.raises(RedundantConstraintsError, match="T1"):
        mbdk.simulate(sc, "rk4", formulation="reduced", solver="sparse", h=1e-3, t_end=1e-2)


def test_a_ten_thousand_body_chain_sets_up_and_steps():
    """Issue 20's size: 10^4 bodies, 2 x 10^4 constraint rows, neither of which the dense path
    could hold (D alone would be 4.8 GB). The run keeps its constraints, and the hanging chain
    released from the horizontal starts to fall at g at its free end."""
    n = 10_000
    r = mbdk.simulate(chain(n), "rk4", h=1e-4, t_end=1e-3, every=10,
                      outputs=("a", "residuals"))
    assert r.manifest["linear_solve"] == SPARSE
    assert r.q.shape == (2, 3 * n)
    assert np.max(r.residuals[:, 0]) < 1e-10
    # a horizontal chain released from rest: the free end accelerates downwards at about g
    # (the constraints hold it only near the hinge), the first bar less
    tip_ay = r.a[0, 3 * (n - 1) + 1]
    assert -9.81 * 1.01 < tip_ay < -9.81 * 0.5


@pytest.mark.parametrize("n,h", [(64, 5e-3), (256, 2.5e-3)])
def test_large_a02_chains_stop_at_the_flat_pose_on_the_sparse_path(n, h):
    """The reduced formulation's refusal of a near rank loss (tests/test_index3.py's one- and
    two-loop case) holds on the sparse path too: A02 chains of 64 and 256 loops (386 and 1538
    rows) stop with SingularMatrixError at the first flat pose (the exact crank angle a
    multiple of pi there), every sample on the right branch, as the dense path does (a window
    that narrows with m alone lets them stride over it unseen)."""
    with pytest.raises(mbdk.SingularMatrixError) as err:
        mbdk.simulate(a02_chain(n), "rk4", formulation="reduced", h=h, t_end=2.0,
                      outputs=("residuals",))
    r = err.value.result
    assert r.manifest["linear_solve"] == SPARSE
    theta, _ = a02_crank(n, r.t)
    assert np.abs(r.q[:, 2] - theta).max() < 1e-5
    assert abs(theta[-1] - np.pi * np.round(theta[-1] / np.pi)) < 0.1
    assert r.t[-1] < 0.75      # the first crossing, about 0.72 s


@pytest.mark.parametrize("formulation", ["reduced", "projection"])
def test_a_perturbed_ten_thousand_body_chain_assembles_and_projects(formulation):
    """Bodies moved 1 mm off their joints: the sparse assembly brings |Phi| to its roundoff
    (16 eps |q|: about 4e-11 m ten kilometres out) in a few Gauss-Newton corrections, and the
    projection formulation keeps it there (a fixed 1e-12 m is below what Phi can resolve at
    |q| = 10^4 m)."""
    n = 10_000
    sc = bar_chain(n, -20.0)
    rng = np.random.default_rng(1)
    for b in sc.bodies:
        b.x += 1e-3 * rng.standard_normal()
        b.y += 1e-3 * rng.standard_normal()
    r = mbdk.simulate(sc, "rk4", formulation=formulation, h=1e-4, t_end=3e-4, every=3,
                      outputs=("residuals",))
    floor = 16 * np.finfo(float).eps * np.abs(r.q).max()
    assert 0 < r.assembly["iterations"] <= 6
    assert r.residuals[0, 0] <= floor
    assert np.max(r.residuals[:, 0]) < 1e-9

