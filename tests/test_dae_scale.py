"""bdf and ida on the DAE itself (bdf's i3 and si2 forms, ida's index1 and ggl) on large
scenes (issue 40): where the model keeps its constraint rows compact (its constrained solves
are sparse), the DAE is evaluated through the index-3 procedures and its Newton matrix is
sparse, in the body graph's pattern (kernel/src/dae/mbdk_dae_pattern.f90): bdf's E - c J by
colored differences of the bodies' columns and exact multiplier columns, factorised by a
sparse L D U in the KKT order with each mu row after its lam row and one step of iterative
refinement per solve (kernel/src/dae/mbdk_mechanism_dae.f90); ida's dF/dY + cj dF/dY' by
colored difference quotients, factorised by SUNDIALS' KLU (kernel/src/sundials/mbdk_ida.f90).
The dense matrices take one evaluation per unknown and n^2 memory. The reference is the dense
path on the same scene (the planar model's solver="schur", whose rows are dense): an
independent factorisation and an independent Jacobian, to the methods' tolerances; the counts
(steps, Newton iterations, evaluations) show which path ran, that its Jacobian is the dense
one's (a wrong entry costs iterations), and that the sparse one's cost does not grow with N.
"""
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
    the same chain on the dense path (solver="schur"): the same steps and Newton iterations, the
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
    assert sparse.stats.newton_iterations == dense.stats.newton_iterations
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
@pytest.mark.parametrize("method, form, phi_tol", [("bdf", "si2", 1e-9), ("ida", "index1", 1e-7)])
def test_the_evaluations_of_a_run_do_not_grow_with_the_chain(kind, sizes, method, form, phi_tol):
    """bdf si2 and ida index1 to 0.01 s on chains of growing length: every run ends, keeps its
    joints at every millisecond (si2 its position rows to 1e-9 m, a thousandth of the error
    test's 1e-6 relative, measured at most 1.8e-12 m; index1 keeps the accelerations' rows
    only and drifts, measured at most 3.8e-9 m, within 1e-7) and takes no more evaluations of
    the residual than 1.5 times the shortest chain's, Jacobians included (measured, bdf:
    planar 94, 88, 79 at 30, 300, 3000 bars, spatial 67, 63, 62 at 16, 128, 1000; ida: 477,
    487, 463 and 934, 888, 931): a colored Jacobian costs the same at every length (bdf: 19
    evaluations on a planar chain, 40 on a spatial one), where the dense one cost one per
    unknown. The steps grow slowly on the planar chain, whose longest pendulum modes quicken
    (measured bdf 14, 20, 25, ida 31, 37, 49; spatial bdf 13, 12, 11, ida 29, 28, 27): within
    twice the shortest's."""
    runs = {}
    for n in sizes:
        sc = bar_chain(n, 30.0) if kind == "planar" else spatial_chain(n)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", mbdk.AccuracyWarning)
            r = mbdk.simulate(sc, method, formulation=form, t_end=0.01, rtol=1e-6, atol=1e-8,
                              dt_out=1e-3)
        assert r.success and r.stats.nlu_sparse == r.stats.nlu > 0
        assert len(r.t) == 11 and np.abs(r.residuals[:, 0]).max() < phi_tol
        runs[n] = r.stats
    first = runs[sizes[0]]
    for n in sizes[1:]:
        assert runs[n].nfev <= 1.5 * first.nfev
        assert runs[n].steps <= 2 * first.steps


SCENES = ["double_pendulum", "four_bar", "physical_pendulum", "spring_bar", "spring_damper_bar",
          "three_link_pendulum", "trolley_crane"]


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("method, form", [("bdf", "i3"), ("bdf", "si2"), ("ida", "index1"),
                                          ("ida", "ggl")])
def test_every_element_on_the_sparse_matrix_is_the_dense_paths_motion(name, method, form):
    """The built-in planar scenes with solver="sparse" (compact rows, so the sparse Newton
    matrix of bdf and ida, whatever the size) against solver="schur" (dense rows: the dense
    matrix), 0.5 s at rtol 1e-7: revolute, prismatic and driven joints, springs, dampers and
    point forces all pass through the pattern and the colored differences. A wrong or missing
    Jacobian entry, or a solve that loses digits, shows in the Newton iterations (simplified
    Newton still converges, more slowly): within 10 % of the dense path's, and the steps too
    (measured: equal on every scene and form but the stiff spring bar's and two ida runs
    within 4 %; the bar's bdf i3 takes 282 steps and 822 iterations on the sparse path under
    every OpenBLAS kernel, the dense LU 281 and 809 under SkylakeX's but 307 and 899 under
    Prescott's, Haswell's or Zen's), the motions within 1e-6 (measured at most 1.9e-7, that bar's i3; elsewhere
    at most 7e-9)."""
    sparse = mbdk.simulate(mbdk.scene(name), method, formulation=form, t_end=0.5, rtol=1e-7,
                           atol=1e-9, solver="sparse")
    dense = mbdk.simulate(mbdk.scene(name), method, formulation=form, t_end=0.5, rtol=1e-7,
                          atol=1e-9, solver="schur")
    assert sparse.stats.nlu_sparse == sparse.stats.nlu > 0 and dense.stats.nlu_sparse == 0
    assert sparse.manifest["newton_matrix"] == DAE_NEWTON_MATRIX[method + "_sparse"]
    assert abs(sparse.stats.steps - dense.stats.steps) <= 0.1 * dense.stats.steps
    assert abs(sparse.stats.newton_iterations - dense.stats.newton_iterations) <= \
        0.1 * dense.stats.newton_iterations
    assert np.abs(sparse.q[-1] - dense.q[-1]).max() < 1e-6


@pytest.mark.parametrize("method, form", [("bdf", "si2"), ("bdf", "i3"), ("ida", "index1"),
                                          ("ida", "ggl")])
def test_two_body_forces_of_a_spatial_scene_on_the_sparse_matrix(method, form):
    """A spatial sphere-plane contact whose plane sits on a second body (k = 1e7) and a
    spring-damper between two bodies, beside a zigzag of 4 bars (15 rows: compact rows, the
    sparse matrix; a spatial contact has the index-3 object the DAE needs) move as beside one
    of 3 bars (12 rows: dense), 0.2 s at rtol 1e-9: to 1e-8 m (measured at most 1.3e-9, bdf
    i3's; the chains differ, so the steps do, and the difference is the error control's, not
    roundoff)."""
    from test_spatial_index3_scale import with_elements
    runs = {pad: mbdk.simulate(with_elements(pad), method, formulation=form, t_end=0.2,
                               rtol=1e-9, atol=1e-11, dt_out=0.05) for pad in (3, 4)}
    assert runs[3].stats.nlu_sparse == 0 and runs[4].stats.nlu_sparse > 0
    assert np.ptp(runs[4].position("R")[:, 1]) > 0.1          # the spring moves R
    for b in ("P", "Q", "R"):
        assert np.abs(runs[4].position(b) - runs[3].position(b)).max() < 1e-8


def test_ida_ggl_on_a_long_chain_from_rest_names_its_first_step_and_runs_with_one():
    """ida ggl on a planar chain of 1000 bars released from rest (rtol 1e-6, atol 1e-8, to
    0.01 s): IDA's own first step (the velocities' atol over their accelerations, about 1e-9 s)
    falls to its floor, a millionth of the interval, where the index-2 Newton iteration
    diverges in the first step; the failure says so and names the first step h, and h = 1e-4
    runs it (measured 22 to 53 steps from 800 to 10 000 bars). Not the sparse path's doing: it
    stops the same with one column per difference quotient and with KLU re-analysing at every
    setup (docs/guide/index3.md)."""
    sc = bar_chain(1000, 30.0)
    with pytest.raises(mbdk.NewtonDivergedError,
                       match="in the first step.*give the first step, h"):
        mbdk.simulate(sc, "ida", formulation="ggl", t_end=0.01, rtol=1e-6, atol=1e-8)
    r = mbdk.simulate(sc, "ida", formulation="ggl", t_end=0.01, rtol=1e-6, atol=1e-8, h=1e-4)
    assert r.success and r.stats.nlu_sparse > 0
    assert np.abs(r.residuals[:, 0]).max() < 1e-9
