"""trapezoidal_index3 on long spatial chains (issue 40): above MBDK_SPATIAL_SPARSE_ROWS rows (none
redundant) the spatial model evaluates C in compact rows and builds its own Newton matrix by
differences of colored columns into 6 x 6 body blocks, factorised by a sparse L D U
(kernel/src/spatial/mbdk_spatial_i3.f90), so that a step's cost and memory grow as the bodies
do and Newton's iterations per step do not. Before, the matrix was differences over the whole
state, dense (a 10 000-body chain could not be set up). Checked against an independent
solution: a chain of bars moving in its plane, built from spatial bodies, is the planar model's
chain (another code, with analytic tangents) under the same method and step."""
import warnings

import numpy as np
import pytest

import mbdk
from mbdk.benchmarks import bar_chain, spatial_chain
from mbdk.run_spatial import SPATIAL_INDEX3_MATRIX
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
