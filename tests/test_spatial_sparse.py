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
    """At or below MBDK_SPATIAL_SPARSE_ROWS rows, and on redundant joints, the dense Cholesky
    (cheaper on a few rows; the redundant rows need its row selection)."""
    r = mbdk.simulate(mbdk.scene("spatial_double_pendulum"), "rk4", h=1e-3, t_end=0.01)
    assert r.manifest["linear_solve"] == SPATIAL_SCHUR[False]
    r = mbdk.simulate(mbdk.scene("bricard"), "rk4", h=1e-3, t_end=0.01)
    assert r.manifest["linear_solve"] == SPATIAL_SCHUR[False]


def test_a_long_chain_out_of_its_plane_keeps_its_joints_and_energy():
    """64 bars on spherical joints released from a zigzag tilted out of the plane (a motion in
    3D): rk4 with projection keeps every joint at the projection's tolerance and the energy to
    the integration's accuracy (no dissipation: E stays E0), and the DAE's multipliers carry
    the chain's weight at the top joint at the start (at rest: lambda's vertical part is the
    weight of the bars below, 64 m g, less their accelerations' share)."""
    n = 64
    sc = spatial_chain(n)
    r = mbdk.simulate(sc, "rk4", h=5e-4, t_end=0.3, every=60, formulation="projection")
    assert r.manifest["linear_solve"] == SPATIAL_SCHUR[True]
    assert np.max(r.residuals[:, 0]) < 1e-10
    scale = 9.81 * n * n / 2                      # the chain's weight times its half length
    assert np.max(np.abs(r.energy - r.energy[0])) < 1e-7 * scale
    assert np.max(np.abs(r.position("b63")[-1] - r.position("b63")[0])) > 0.1   # it moved


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
    # the first bar swings down under the chain's weight: its far end has moved
    assert np.linalg.norm(r.position("b0")[-1] - r.position("b0")[0]) > 0.0
