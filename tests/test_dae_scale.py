"""bdf on the DAE itself (the i3 and si2 forms) on long chains (issue 40): where the model keeps
its constraint rows compact (a large scene: its constrained solves are sparse), the DAE is
evaluated through the index-3 procedures and keeps its own Newton matrix E - c J sparse, in the
body graph's pattern: the bodies' columns by colored differences (a distance-2 coloring of the
body graph, so a chain's matrix costs the same number of evaluations at every length), the
multipliers' columns exactly, factorised by a sparse L D U in the KKT order with each mu row
after its lam row (kernel/src/dae/mbdk_mechanism_dae.f90). Before, the matrix was dense and by
differences over the whole state: N + 1 evaluations of a dense C per matrix, n^2 memory (bdf si2
took 164 s for 0.01 s of a planar chain of 512 bars). The reference is the dense path on the
same scene (the planar model's solver="schur", whose rows are dense), an independent
factorisation and an independent Jacobian, to the methods' tolerances; the counts (steps,
factorisations, evaluations) show which path ran and that the sparse one does not grow with N."""
import warnings

import numpy as np
import pytest

import mbdk
from mbdk.benchmarks import bar_chain, spatial_chain
from mbdk.codes import DAE_NEWTON_MATRIX


def bdf(scene, form, t_end=0.05, rtol=1e-6, atol=1e-8, **kw):
    with warnings.catch_warnings():
        # the DAE's multipliers carry their own index's error (its AccuracyWarning)
        warnings.simplefilter("ignore", mbdk.AccuracyWarning)
        return mbdk.simulate(scene, "bdf", formulation=form, t_end=t_end, rtol=rtol, atol=atol,
                             **kw)


@pytest.mark.parametrize("form, tol", [("si2", 1e-10), ("i3", 1e-8)])
def test_the_sparse_newton_matrix_gives_the_dense_paths_motion(form, tol):
    """A planar chain of 30 bars released from 30 degrees (60 rows: compact by default) against
    the same chain on the dense path (solver="schur"): the same steps and factorisations, the
    same motion to well inside the error test (measured 1.3e-13 in si2, 4.9e-11 in i3, whose
    velocities are index-2 variables tested at h times their error), not the same bits (the
    sparse path ran), with a Jacobian from far fewer evaluations of G (colored: 3 colors of 6
    unknowns on a chain and G itself, 19, against one per unknown and G, 241 in i3 and 301 in
    si2)."""
    sparse = bdf(bar_chain(30, 30.0), form)
    dense = bdf(bar_chain(30, 30.0), form, solver="schur")
    assert sparse.success and dense.success
    assert sparse.manifest["newton_matrix"] == DAE_NEWTON_MATRIX["bdf_sparse"]
    assert dense.manifest["newton_matrix"] == DAE_NEWTON_MATRIX["bdf"]
    assert sparse.stats.nlu_sparse == sparse.stats.nlu > 0 and dense.stats.nlu_sparse == 0
    assert sparse.stats.steps == dense.stats.steps
    assert np.abs(sparse.q - dense.q).max() < tol
    assert not np.array_equal(sparse.q, dense.q)
    jac_evals = (sparse.stats.nfev - sparse.stats.newton_iterations) / sparse.stats.njev
    assert jac_evals == 19


@pytest.mark.parametrize("form", ["si2", "i3"])
def test_a_spatial_chain_on_the_sparse_matrix_is_the_planar_chains_motion(form):
    """8 spatial bars on revolute joints moving in their plane (40 rows: compact) follow the
    planar model's chain on its dense path, another model, another code and another matrix,
    both at rtol 1e-9, atol 1e-11 over 0.3 s, to ten times the error test's size (measured
    1.2e-9 m in si2, 2.9e-9 m in i3), and stay in the plane exactly."""
    from test_spatial_sparse import spatial_chain_from
    planar_scene = bar_chain(8, -30.0)
    planar = bdf(planar_scene, form, t_end=0.3, solver="schur", rtol=1e-9, atol=1e-11)
    sc = spatial_chain_from(planar_scene, planar.q[0], "revolute")
    spatial = bdf(sc, form, t_end=0.3, rtol=1e-9, atol=1e-11)
    assert spatial.manifest["newton_matrix"] == DAE_NEWTON_MATRIX["bdf_sparse"]
    assert spatial.stats.nlu_sparse > 0 and planar.stats.nlu_sparse == 0
    for k, b in enumerate(planar_scene.bodies):
        xy = spatial.position(b.name)
        assert np.abs(xy[-1, :2] - planar.q[-1, 3 * k:3 * k + 2]).max() < 1e-8
        assert np.abs(xy[:, 2]).max() == 0.0


@pytest.mark.parametrize("kind, sizes", [("planar", (30, 300, 3000)),
                                         ("spatial", (16, 128, 1000))])
def test_the_evaluations_of_a_run_do_not_grow_with_the_chain(kind, sizes):
    """bdf si2 to 0.01 s on chains of growing length: every run ends, keeps its joints at every
    millisecond (the position rows to 1e-9 m, a thousandth of the error test's 1e-6 relative;
    measured at most 1.8e-12 m) and takes no more evaluations of G than 1.5 times the shortest
    chain's, Jacobians included (measured: planar 94, 88, 79 at 30, 300, 3000 bars; spatial 67,
    63, 62 at 16, 128, 1000): a colored Jacobian costs 19 evaluations at every length, where the
    dense one cost one per unknown. The steps grow slowly on the planar chain, whose longest
    pendulum modes quicken (measured 14, 20, 25; spatial 13, 12, 11): within twice the
    shortest's."""
    runs = {}
    for n in sizes:
        sc = bar_chain(n, 30.0) if kind == "planar" else spatial_chain(n)
        r = bdf(sc, "si2", t_end=0.01, dt_out=1e-3)
        assert r.success and r.stats.nlu_sparse > 0
        assert len(r.t) == 11 and np.abs(r.residuals[:, 0]).max() < 1e-9
        runs[n] = r.stats
    first = runs[sizes[0]]
    for n in sizes[1:]:
        assert runs[n].nfev <= 1.5 * first.nfev
        assert runs[n].steps <= 2 * first.steps
