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


@pytest.mark.parametrize("n, solver", [(60, "auto"), (4, "sparse")])
def test_the_sparse_book_matrix_gives_the_dense_paths_solution(n, solver):
    """60 bars (120 rows, sparse by default) and 4 bars with the sparse path asked for: the
    motion of the dense book matrix to Newton's tolerance (1e-10 of the coordinates; 1e-8 after
    100 steps of it), at the same iteration count within one per step; not its bits (the other
    factorisation's roundoff: the sparse path did run)."""
    sparse = run(n, 0.1, solver=solver)
    dense = run(n, 0.1, solver="schur")
    assert np.abs(sparse.q - dense.q).max() < 1e-8
    assert not np.array_equal(sparse.q, dense.q)
    assert abs(sparse.stats.newton_iterations - dense.stats.newton_iterations) <= \
        sparse.stats.steps


def test_newton_iterations_do_not_grow_with_the_chain():
    """30, 300, 3000 and 10 000 bars released from 30 degrees to 0.2 s: every run reaches its
    end (before the sparse book matrix and the floor test, the book form failed from about 5000
    bars, and the augmented form's iterations grew to 14 per step and failed at 10 000), and the
    iterations per step stay within 1.3 times the 30-bar chain's (measured: 3.8, 3.5, 2.9, 4.5:
    at 10 000 bars the steps where the update meets its roundoff floor take an iteration more
    to show it)."""
    per_step = {}
    for n in (30, 300, 3000, 10_000):
        r = run(n, 0.2)
        assert r.success and r.t[-1] == pytest.approx(0.2)
        per_step[n] = r.stats.newton_iterations / r.stats.steps
    assert max(per_step.values()) <= 1.3 * per_step[30], per_step


def test_a_failed_augmented_run_on_a_long_chain_names_the_books_scheme():
    """The augmented form (trapezoidal_index3's default) fails on the 10 000-bar chain (its
    multiplier update contracts more slowly as the chain lengthens: NewtonDivergedError at about
    t = 0.034 s), and its message names formulation = 'index3', which runs that chain (above)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", mbdk.AccuracyWarning)
        with pytest.raises(mbdk.NewtonDivergedError, match="formulation = 'index3'"):
            mbdk.simulate(bar_chain(10_000, 30.0), "trapezoidal_index3", h=1e-3, t_end=0.05)
