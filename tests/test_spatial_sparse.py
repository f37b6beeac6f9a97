"""The spatial model's sparse path (issue 40): above MBDK_SPATIAL_SPARSE_ROWS constraint rows the
ODE formulations' constrained solves go by compact rows (12 values a row) and the sparse
LDL^T of S = C M^-1 C^T (kernel/src/linalg/mbdk_compact_schur.f90), so that a chain's cost per
step grows as its bodies do (benchmarks/spatial_chain.py measures it). Checked against an
independent solution: a chain of bars moving in its plane, built from spatial bodies, is the
planar chain's motion (the planar model, another code), to the integration's agreement."""
import math

import numpy as np
import pytest

import mbdk
from mbdk.benchmarks import bar_chain, spatial_chain
from mbdk.run_spatial import SPATIAL_SCHUR
from mbdk.scene_file import scene_from_dict

N = 8          # 8 joints: 24 rows on spherical joints, 40 on revolute ones: the sparse path


def spatial_chain_from(planar, q0, joint):
    """The planar chain rebuilt from spatial bars at the planar run's assembled state q0, on
    spherical or revolute (axis z) joints."""
    bodies, joints = [], []
    for k, b in enumerate(planar.bodies):
        bodies.append({"name": b.name, "kind": "spatial", "mass": b.mass,
                       "shape": {"type": "bar", "length": math.sqrt(12 * b.inertia / b.mass)},
                       "position": [q0[3 * k], q0[3 * k + 1], 0.0],
                       "cardan123": [0.0, 0.0, q0[3 * k + 2]]})
    for j in planar.joints:
        d = {"name": j.name, "type": joint, "body1": j.body1, "point1": [*j.point1, 0.0]}
        if j.body2 != "ground":
            d.update(body2=j.body2, point2=[*j.point2, 0.0])
        else:
            d.update(point2=[*j.point2, 0.0])
        if joint == "revolute":
            d["axis"] = [0.0, 0.0, 1.0]
        joints.append(d)
    return scene_from_dict({"scene": {"name": f"spatial_{planar.name}"}, "body": bodies,
                            "joint": joints, "force": [{"type": "gravity",
                                                        "g": [0.0, -9.81, 0.0]}]})


@pytest.mark.parametrize("joint, rows", [("spherical", 3 * N), ("revolute", 5 * N)])
@pytest.mark.parametrize("formulation", ["reduced", "baumgarte", "projection"])
def test_a_chain_in_its_plane_is_the_planar_chains_motion(joint, rows, formulation):
    planar_scene = bar_chain(N, -30.0)
    planar = mbdk.simulate(planar_scene, "rk4", h=1e-3, t_end=0.5, every=50,
                           formulation=formulation)
    sc = spatial_chain_from(planar_scene, planar.q[0], joint)
    assert sc.rows == rows
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.5, every=50, formulation=formulation)
    assert r.manifest["linear_solve"] == SPATIAL_SCHUR[True]
    for k, b in enumerate(planar_scene.bodies):
        assert np.max(np.abs(r.position(b.name)[:, :2] - planar.q[:, 3 * k:3 * k + 2])) < 1e-10
        assert np.max(np.abs(r.position(b.name)[:, 2])) < 1e-12      # it stays in its plane
    assert np.max(np.abs(r.energy - planar.energy)) < 1e-9
    if formulation == "projection":      # (the reduced form drifts, in both models alike)
        assert np.max(r.residuals[:, :2]) < 1e-9


def test_the_few_rows_keep_the_dense_path():
    """At or below MBDK_SPATIAL_SPARSE_ROWS rows, on redundant joints, and up to
    MBDK_SPATIAL_DENSE_MAX_ROWS rows where S would be more than three quarters full, the dense
    Cholesky (cheaper on a few rows or a few bodies; the redundant rows need its row selection);
    a chain of 5 spherical joints (15 rows, S 52 % full) takes the sparse path."""
    r = mbdk.simulate(mbdk.scene("spatial_double_pendulum"), "rk4", h=1e-3, t_end=0.01)
    assert r.manifest["linear_solve"] == SPATIAL_SCHUR[False]
    r = mbdk.simulate(mbdk.scene("bricard"), "rk4", h=1e-3, t_end=0.01)
    assert r.manifest["linear_solve"] == SPATIAL_SCHUR[False]
    fly = mbdk.scene("flyball_governor")           # 20 rows on 4 bodies
    assert fly.rows == 20 and len(fly.bodies) == 4
    r = mbdk.simulate(fly, "rk4", h=1e-4, t_end=0.001)
    assert r.manifest["linear_solve"] == SPATIAL_SCHUR[False]
    r = mbdk.simulate(spatial_chain(5), "rk4", h=1e-3, t_end=0.01)
    assert r.manifest["linear_solve"] == SPATIAL_SCHUR[True]


def test_a_long_chain_out_of_its_plane_keeps_its_joints_and_energy():
    """64 bars on spherical joints released from a zigzag tilted out of the plane (a motion in
    3D): rk4 with projection keeps every joint at the projection's tolerance and the energy to
    the integration's accuracy (no dissipation: E stays E0) while the chain falls (its free end
    drops by more than 0.1 m)."""
    n = 64
    sc = spatial_chain(n)
    r = mbdk.simulate(sc, "rk4", h=5e-4, t_end=0.3, every=60, formulation="projection")
    assert r.manifest["linear_solve"] == SPATIAL_SCHUR[True]
    assert np.max(r.residuals[:, 0]) < 1e-10
    scale = 9.81 * n * n / 2                      # the chain's weight times its half length
    assert np.max(np.abs(r.energy - r.energy[0])) < 1e-7 * scale
    end = r.position(f"b{n - 1}")
    assert end[-1, 1] < end[0, 1] - 0.1                 # the free end falls


def test_a_ten_thousand_body_spatial_chain_sets_up_and_steps():
    """10 000 bars on spherical joints (30 000 rows): set up (each joint's rows checked on their
    own: a tree) and stepped in memory that grows as the rows do (a dense C alone would be 14
    GB), its joints kept over the steps (the reduced form's drift after ten steps of 1e-4 s
    is at roundoff of the chain's size)."""
    sc = spatial_chain(10_000)
    r = mbdk.simulate(sc, "rk4", h=1e-4, t_end=1e-3, every=10, formulation="reduced")
    assert r.manifest["linear_solve"] == SPATIAL_SCHUR[True]
    assert np.max(r.residuals[:, 0]) < 1e-10 * 10_000
    assert np.all(np.isfinite(r.q[-1]))
    # the free end falls under gravity, 1/2 g t^2 = 4.9e-6 m in 1 ms, as a free body would
    # (the chain above it has not yet pulled on it)
    drop = r.position("b9999")[0, 1] - r.position("b9999")[-1, 1]
    assert drop == pytest.approx(0.5 * 9.81 * 1e-3 ** 2, rel=0.05)


@pytest.mark.parametrize("method, kw", [
    ("rk4", {"h": 1e-3, "formulation": "reduced"}),
    ("rk4", {"h": 1e-3, "formulation": "projection"}),
    ("ida", {"rtol": 1e-9, "atol": 1e-11, "dt_out": 0.1}),
    ("bdf", {"formulation": "si2", "rtol": 1e-9, "atol": 1e-11, "dt_out": 0.1}),
    ("bdf", {"formulation": "i3", "rtol": 1e-9, "atol": 1e-11, "dt_out": 0.1}),
    ("trapezoidal_index3", {"h": 1e-3}),
])
def test_the_sparse_path_is_the_dense_one_on_a_driven_chain(method, kw):
    """The sparse path (41 rows, none redundant) against the dense one on the same motion (one
    hinge doubled: redundant rows, which only the dense path's row selection takes), the root
    driven by f(t) = 0.3 sin(2 t) (Phi_t in both), by the ODE formulations, ida (its Newton
    matrix dense either way), bdf on the DAE (its Newton matrix sparse on the sparse path:
    mbdk_mechanism_dae) and the index-3 family: the same q and the same driven angle to the
    methods' roundoff."""
    planar = bar_chain(8, -30.0)
    start = mbdk.simulate(planar, "rk4", h=1e-3, t_end=1e-3)
    runs = {}
    for dup in (False, True):
        d = {"scene": {"name": "driven"},
             # the chain turning as one about the origin at f'(0) = 0.6 rad/s, as the driver
             # asks of the root and the hinges (at rest relative to each other) allow
             "body": [{"name": b.name, "kind": "spatial", "mass": b.mass,
                       "shape": {"type": "bar", "length": 1.0},
                       "position": [start.q[0][3 * k], start.q[0][3 * k + 1], 0.0],
                       "cardan123": [0.0, 0.0, start.q[0][3 * k + 2]],
                       "velocity": [-0.6 * start.q[0][3 * k + 1], 0.6 * start.q[0][3 * k], 0.0],
                       "omega_body": [0.0, 0.0, 0.6]}
                      for k, b in enumerate(planar.bodies)],
             "joint": [{"name": j.name, "type": "revolute", "body1": j.body1,
                        "point1": [*j.point1, 0.0], "axis": [0.0, 0.0, 1.0],
                        **({"body2": j.body2, "point2": [*j.point2, 0.0]}
                           if j.body2 != "ground" else {"point2": [*j.point2, 0.0]})}
                       for j in planar.joints]
             + [{"name": "drive", "type": "angle_driver", "body1": "b0", "axis": [0, 0, 1],
                 "function": {"rate": 0.0, "amplitude": 0.3, "omega": 2.0}}]
             + ([{"name": "again", "type": "revolute", "body1": "b7", "body2": "b6",
                  "point1": [-0.5, 0.0, 0.0], "point2": [0.5, 0.0, 0.0],
                  "axis": [0.0, 0.0, 1.0]}] if dup else []),
             "force": [{"type": "gravity", "g": [0.0, -9.81, 0.0]}]}
        runs[dup] = mbdk.simulate(scene_from_dict(d), method, t_end=0.3, **kw)
    sparse, dense = runs[False], runs[True]
    assert sparse.manifest["linear_solve"] != dense.manifest["linear_solve"] or \
        method in ("ida", "trapezoidal_index3")
    assert np.max(np.abs(sparse.q - dense.q)) < 1e-9
    angle = np.unwrap(np.arctan2(sparse.orientation("b0")[:, 1, 0],
                                 sparse.orientation("b0")[:, 0, 0]))
    assert np.max(np.abs(angle - angle[0] - 0.3 * np.sin(2.0 * sparse.t))) < 1e-9
