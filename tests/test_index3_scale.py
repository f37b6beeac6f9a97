"""trapezoidal_index3 on long planar chains (issue 40): the book scheme's Newton matrix
[K D^T; D 0] of a scene above MBDK_SPARSE_MIN_ROWS rows is one sparse symmetric matrix
factorised at linear cost (mbdk_index3_matrix: fa%kkt), so its Newton iteration, exact, keeps
its count as the chain grows; where the update's roundoff floor rises above Newton's tolerance
(the matrix's conditioning grows with the chain) a stalled update from a fresh matrix ends the
iteration instead of failing it. The reference is the dense path's solution (solver="schur",
the book matrix by LAPACK) and, for the count, the chain of 30 bars."""
import warnings

import numpy as np
import pytest

import mbdk
from mbdk.benchmarks import bar_chain


def run(n, t_end, **kw):
    with warnings.catch_warnings():
        # the book scheme's multipliers carry its index-3 error (its AccuracyWarning)
        warnings.simplefilter("ignore", mbdk.AccuracyWarning)
        return mbdk.simulate(bar_chain(n, 30.0), "trapezoidal_index3", h=1e-3, t_end=t_end,
                             formulation="index3", **kw)


def test_the_sparse_book_matrix_gives_the_dense_paths_solution():
    """60 bars (120 rows, sparse by default): the motion of the dense book matrix to Newton's
    tolerance (1e-10 of the coordinates; 1e-8 after 100 steps of it), at the same iteration
    count within one per step."""
    sparse = run(60, 0.1)
    dense = run(60, 0.1, solver="schur")
    assert np.abs(sparse.q - dense.q).max() < 1e-8
    assert abs(sparse.stats.newton_iterations - dense.stats.newton_iterations) <= \
        sparse.stats.steps


def test_newton_iterations_do_not_grow_with_the_chain():
    """30, 300, 3000 and 10 000 bars released from 30 degrees: every run reaches its end (before
    the sparse book matrix and the floor test, the book form failed from about 5000 bars and the
    augmented form's iterations grew from 3 to 9 and failed there), and the iterations per step
    grow by less than one per tenfold length (measured: 2.9, 3.5, 4.1, 4.8: the steps where the
    update meets its roundoff floor take one more iteration to show it)."""
    per_step = {}
    for n in (30, 300, 3000, 10_000):
        r = run(n, 0.05 if n < 10_000 else 0.02)
        assert r.success and r.t[-1] == pytest.approx(0.05 if n < 10_000 else 0.02)
        per_step[n] = r.stats.newton_iterations / r.stats.steps
    sizes = sorted(per_step)
    for a, b in zip(sizes, sizes[1:]):
        assert per_step[b] - per_step[a] < np.log10(b / a), per_step
    assert per_step[10_000] <= 2 * per_step[30], per_step
