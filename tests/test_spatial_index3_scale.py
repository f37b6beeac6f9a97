"""trapezoidal_index3 on long spatial chains (issue 40): above MBDK_SPATIAL_SPARSE_ROWS rows (none
redundant) the spatial model evaluates C in compact rows and builds its own Newton matrix by
differences of colored columns into 6 x 6 body blocks, factorised by a sparse L D U
(kernel/src/spatial/mbdk_spatial_i3.f90), so that a step's cost and memory grow as the bodies
do and Newton's iterations per step do not. Before, the matrix was differences over the whole
state, dense (a 10 000-body chain could not be set up). Checked against an independent
solution: a chain of bars moving in its plane, built from spatial bodies, is the planar model's
chain (another code, with analytic tangents) under the same method and step."""
import math
import warnings

import numpy as np
import pytest

import mbdk
from mbdk.benchmarks import bar_chain, spatial_chain, spatial_chain_elements
from mbdk.codes import DAE_NEWTON_MATRIX
from mbdk.run_spatial import SPATIAL_INDEX3_MATRIX
from mbdk.scene_file import scene_from_dict
from test_spatial_sparse import spatial_chain_from


def index3(scene, t_end, formulation, **kw):
    with warnings.catch_warnings():
        # the book scheme's multipliers carry its index-3 error (its AccuracyWarning)
        warnings.simplefilter("ignore", mbdk.AccuracyWarning)
        return mbdk.simulate(scene, "trapezoidal_index3", h=1e-3, t_end=t_end,
                             formulation=formulation, **kw)


@pytest.mark.parametrize("joint, rows", [("spherical", 24), ("revolute", 40)])
@pytest.mark.parametrize("formulation, tol", [("index3", 5e-9), ("augmented_lagrangian", 1e-10)])
def test_a_chain_in_its_plane_is_the_planar_chains_motion(joint, rows, formulation, tol):
    """8 bars released from -30 degrees, 0.5 s at h = 1e-3: the spatial chain on the sparse
    Newton matrix follows the planar model's trapezoidal_index3 to Newton's tolerance (measured
    5.5e-10 in the book form, whose iterations stop at 1e-10 of the coordinates; 1.3e-12 in the
    augmented one) and stays in its plane."""
    planar_scene = bar_chain(8, -30.0)
    planar = index3(planar_scene, 0.5, formulation, every=50)
    sc = spatial_chain_from(planar_scene, planar.q[0], joint)
    assert sc.rows == rows
    r = index3(sc, 0.5, formulation, every=50)
    assert r.manifest["linear_solve"] == SPATIAL_INDEX3_MATRIX[True]
    for k, b in enumerate(planar_scene.bodies):
        assert np.max(np.abs(r.position(b.name)[:, :2] - planar.q[:, 3 * k:3 * k + 2])) < tol
        assert np.max(np.abs(r.position(b.name)[:, 2])) < 1e-12
    assert np.max(r.residuals[:, 0]) < 1e-9


def test_the_few_rows_keep_the_matrix_by_differences():
    """At or below MBDK_SPATIAL_SPARSE_ROWS rows: the dense evaluation and the integrator's
    differences over the whole state."""
    r = index3(mbdk.scene("spatial_double_pendulum"), 0.01, "augmented_lagrangian")
    assert r.manifest["linear_solve"] == SPATIAL_INDEX3_MATRIX[False]


@pytest.mark.parametrize("formulation, sizes", [("index3", (8, 64, 512, 10_000)),
                                                ("augmented_lagrangian", (8, 64, 1024))])
def test_newton_iterations_do_not_grow_with_the_spatial_chain(formulation, sizes):
    """Chains of spherical joints released from a zigzag out of their plane (a motion in 3D),
    0.05 s at h = 1e-3, up to 10 000 bodies (30 000 rows) in the book form: every run reaches
    its end with its joints kept (max |Phi| at the roundoff of coordinates that grow to 10^4 m:
    measured 7e-15 to 5.5e-12) and its energy (no dissipation: E stays E0 to the method's
    accuracy; measured 1.8e-8 to 3.5e-8 J, the same at every length: in 0.05 s only the free
    end has moved, by 12 mm), and the iterations per step stay within 1.3 times the 8-body
    chain's (measured: book 2.64, 2.64, 2.30, 2.02; augmented 2.88 at every length)."""
    per_step = {}
    for n in sizes:
        r = index3(spatial_chain(n), 0.05, formulation, every=10)
        assert r.success and r.t[-1] == pytest.approx(0.05)
        assert r.manifest["linear_solve"] == SPATIAL_INDEX3_MATRIX[True]
        assert np.max(r.residuals[:, 0]) < 1e-12 * max(1.0, n / 1000)
        assert np.ptp(r.energy) < 1e-6
        per_step[n] = r.stats.newton_iterations / r.stats.steps
    assert max(per_step.values()) <= 1.3 * per_step[8], per_step


def with_elements(pad):
    """Far from a zigzag of `pad` bars (mbdk.benchmarks.spatial_chain's; no coupling to it): a
    body Q pinned at its centre with a plane on its top face, a sphere P resting on that plane
    (a sphere-plane contact between two bodies, k = 1e7: it sinks 9.81e-7 m), a body R hanging
    from Q by a spring-damper. 3 + 3 pad rows."""
    bodies, joints = spatial_chain_elements(pad)
    box = {"kind": "spatial", "mass": 1.0, "inertia": [0.1, 0.1, 0.1],
           "quaternion": [1.0, 0.0, 0.0, 0.0]}
    bodies += [{"name": "Q", "position": [0.0, -10.0, 5.0], **box},
               {"name": "P", "position": [0.0, -9.4 - 9.81e-7, 5.0], **box},
               {"name": "R", "position": [0.3, -11.2, 5.0], **box}]
    joints.append({"name": "SQ", "type": "spherical", "body1": "Q", "at": [0.0, -10.0, 5.0]})
    forces = [{"type": "gravity", "g": [0.0, -9.81, 0.0]},
              {"type": "contact", "name": "c", "body1": "P",
               "shape1": {"type": "sphere", "radius": 0.1, "centre": [0.0, 0.0, 0.0]},
               "body2": "Q",
               "shape2": {"type": "plane", "point": [0.0, 0.5, 0.0], "normal": [0.0, 1.0, 0.0]},
               "stiffness": 1e7, "damping": 2e3},
              {"type": "spring_damper", "name": "s", "body1": "Q", "point1": [0.0, -0.5, 0.0],
               "body2": "R", "point2": [0.0, 0.5, 0.0], "stiffness": 100.0, "damping": 1.0,
               "rest_length": 0.5}]
    return scene_from_dict({"scene": {"name": f"elements_{pad}"}, "body": bodies,
                            "joint": joints, "force": forces})


@pytest.mark.parametrize("formulation", ["index3", "augmented_lagrangian"])
@pytest.mark.parametrize("pad", [4, 100])
def test_two_body_forces_on_the_sparse_path_give_the_dense_paths_motion(formulation, pad):
    """A sphere-plane contact whose plane sits on a second body and a spring-damper between two
    bodies couple their bodies in the sparse matrix's pattern and colors: the same bodies beside
    a zigzag of 4 or 100 bars (15 or 303 rows: the sparse path) move as beside one of 3 bars
    (12 rows: the dense path, its matrix by differences over the whole state), to Newton's
    tolerance. (With the contact left out of the pattern, the book form stopped in its first
    step; beside 100 bars, with increments from the scene's spread, about 100 m, the sphere's
    column stepped it out of contact, 1.5e-6 m against its 9.8e-7 m, and the book form
    diverged.)"""
    dense = index3(with_elements(3), 0.2, formulation, every=50)
    sparse = index3(with_elements(pad), 0.2, formulation, every=50)
    assert dense.manifest["linear_solve"] == SPATIAL_INDEX3_MATRIX[False]
    assert sparse.manifest["linear_solve"] == SPATIAL_INDEX3_MATRIX[True]
    assert np.ptp(sparse.position("R")[:, 1]) > 1e-3          # the spring moves R
    for b in ("P", "Q", "R"):
        assert np.max(np.abs(sparse.position(b) - dense.position(b))) < 1e-9


def near_straight_loop(pad: bool):
    """Three bars on spherical joints between two ground points 3 - 1e-3 m apart (a loop near
    its straight, singular pose: C M^-1 C^T nearly loses a rank), with or without a pendulum
    beside it that takes the scene to 15 rows (the sparse path)."""
    n, slack = 3, 1e-3
    c = (n - slack) / n
    s = math.sqrt(1 - c * c)
    ex, bodies, joints, p = np.array([1.0, 0.0, 0.0]), [], [], np.zeros(3)
    for i, sgn in enumerate((-1, 0, 1)):
        d = np.array([c, sgn * s, 0.0]) if sgn else ex.copy()
        d /= np.linalg.norm(d)
        half = (ex + d) / np.linalg.norm(ex + d)
        bodies.append({"name": f"b{i}", "kind": "spatial", "mass": 1.0,
                       "inertia": [0.01, 0.1, 0.1], "position": (p + 0.5 * d).tolist(),
                       "quaternion": [float(half @ ex), *np.cross(ex, half).tolist()]})
        joint = {"name": f"S{i}", "type": "spherical", "body1": f"b{i}",
                 "point1": [-0.5, 0.0, 0.0]}
        if i:
            joint.update(body2=f"b{i - 1}", point2=[0.5, 0.0, 0.0])
        joints.append(joint)
        p = p + d
    joints.append({"name": "end", "type": "spherical", "body1": "b2", "point1": [0.5, 0.0, 0.0],
                   "point2": p.tolist()})
    if pad:
        bodies.append({"name": "D", "kind": "spatial", "mass": 1.0, "inertia": [0.01, 0.1, 0.1],
                       "position": [0.0, -20.5, 3.0], "quaternion": [1.0, 0.0, 0.0, 0.0]})
        joints.append({"name": "SD", "type": "spherical", "body1": "D", "at": [0.0, -20.0, 3.0]})
    return scene_from_dict({"scene": {"name": "near_straight"}, "body": bodies,
                            "joint": joints, "force": [{"type": "gravity",
                                                        "g": [0.0, -9.81, 0.0]}]})


def test_the_augmented_forms_regular_path_on_the_sparse_path():
    """Near a rank loss the augmented form's projections take the regular path (M + beta C^T C),
    on the sparse path as on the dense one: the loop near its straight pose runs beside a
    pendulum (sparse) as alone (dense), to Newton's tolerance (measured 1e-14). (Without the
    sparse regular path it stopped at t = 0 with SingularMatrixError.)"""
    alone = index3(near_straight_loop(False), 0.3, "augmented_lagrangian", every=100)
    padded = index3(near_straight_loop(True), 0.3, "augmented_lagrangian", every=100)
    assert padded.manifest["linear_solve"] == SPATIAL_INDEX3_MATRIX[True]
    assert alone.manifest["linear_solve"] == SPATIAL_INDEX3_MATRIX[False]
    for b in ("b0", "b1", "b2"):
        assert np.max(np.abs(padded.position(b) - alone.position(b))) < 1e-9


@pytest.mark.parametrize("scene", ["four_bar", "heavy_top"])
@pytest.mark.parametrize("method, formulation", [("bdf", "si2"), ("ida", "index1")])
def test_the_dae_methods_name_their_dense_newton_matrix(scene, method, formulation):
    """On a small scene (rows the model keeps dense) bdf's and ida's Newton matrices are dense
    over the DAE's state in both models, and every manifest says so (ida's is dense on long
    chains too; bdf's goes sparse there: tests/test_dae_scale.py)."""
    r = mbdk.simulate(mbdk.scene(scene), method, t_end=0.05, formulation=formulation)
    assert r.manifest["newton_matrix"] == DAE_NEWTON_MATRIX[method]
    assert r.stats.nlu > 0 and r.stats.nlu_sparse == 0
