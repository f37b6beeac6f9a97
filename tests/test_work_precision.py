"""Reading work-precision curves (mbdk.analysis.work_precision; the tables "cheapest method per
target error" of studies/work_precision.py): on synthetic curves whose answers follow in closed
form. A power law, error = C h^p at CPU time K / h, is a straight line in log-log, so the
interpolated cost of reaching an error e is exact there: h = (e / C)^(1/p), cpu = K / h."""
import math

import pytest

from mbdk.analysis.work_precision import cheapest, cost_to_reach, error_ratios


def power_law(c, p, k, hs):
    return [(k / h, c * h ** p) for h in hs]


HS = [0.1 / 2 ** i for i in range(8)]


def law_cost(c, p, k, e):
    return k / (e / c) ** (1.0 / p)


@pytest.mark.parametrize("p", [1, 2, 4])
def test_the_cost_of_a_power_law_is_exact_between_runs(p):
    pts = power_law(3.0, p, 1e-4, HS)
    for e in (2e-3, 7.3e-5, 1e-7):
        if not pts[-1][1] <= e < pts[0][1]:
            continue
        r = cost_to_reach(pts, e)
        assert r.how == "interpolated"
        assert r.cpu == pytest.approx(law_cost(3.0, p, 1e-4, e), rel=1e-12)
        # between the last run above the target and the first at or below it
        assert pts[r.index - 1][1] > e >= pts[r.index][1]


def test_a_run_on_the_target_is_measured_and_beyond_the_runs_is_none():
    pts = power_law(1.0, 2, 1e-3, HS)
    hit = pts[3][1]
    r = cost_to_reach(pts, hit)
    assert r.cpu == pytest.approx(pts[3][0], rel=1e-12) and r.index == 3
    assert cost_to_reach(pts, pts[-1][1] / 2) is None            # finer than the finest run
    first = cost_to_reach(pts, 10 * pts[0][1])                   # coarser than the coarsest
    assert first.how == "first run" and first.cpu == pts[0][0]   # at most that: a bound


def test_the_cheapest_method_changes_where_the_curves_cross():
    """A cheap second-order method (error h^2, cost 1/h) against a dearer fourth-order one
    (error h^4, cost 10/h): equal cost where (e)^(-1/2) = 10 e^(-1/4), e = 1e-4. Above that
    error the second-order method wins, below it the fourth-order one."""
    hs = [1.0 / 2 ** i for i in range(1, 16)]
    curves = {"o2": power_law(1.0, 2, 1.0, hs), "o4": power_law(1.0, 4, 10.0, hs)}
    for e, winner in ((1e-2, "o2"), (1e-3, "o2"), (1e-5, "o4"), (1e-8, "o4")):
        ranked = cheapest(curves, e)
        assert ranked[0][0] == winner, e
        assert ranked[0][1].cpu == pytest.approx(
            law_cost(1.0, 2 if winner == "o2" else 4, 1.0 if winner == "o2" else 10.0, e),
            rel=1e-12)
        assert ranked[0][1].cpu <= ranked[1][1].cpu


def test_no_segment_spans_a_failed_run_and_a_rising_tail_keeps_the_first_crossing():
    pts = power_law(1.0, 2, 1.0, HS)
    # the run that would bracket 1e-4 failed: the next crossing is a measured run further on
    e = 1e-4
    i = next(k for k, (_c, err) in enumerate(pts) if err <= e)
    broken = list(pts)
    broken[i] = (None, None)
    r = cost_to_reach(broken, e)
    assert r.how == "measured" and r.index == i + 1
    # a curve that turns up again at its finest runs (roundoff): the first crossing wins
    rising = pts[:5] + [(pts[5][0], pts[3][1]), (pts[6][0], 1.0)]
    r = cost_to_reach(rising, pts[3][1] * 0.9)
    assert pts[3][0] < r.cpu < pts[4][0] and r.how == "interpolated"
    assert cheapest({"a": [(None, None)] * 3}, 1e-3) == []


def test_error_ratios_pair_the_same_controls_only():
    a = {0.1: 2e-3, 0.05: 5e-4, 0.025: None, 0.0125: 3e-5}
    b = {0.1: 1e-3, 0.05: 2.5e-4, 0.025: 6e-5}
    assert error_ratios(a, b) == [2.0, 2.0]
    assert error_ratios(a, {}) == []
    with pytest.raises(ValueError):
        cost_to_reach([(1.0, 1.0)], 0.0)
    assert math.isfinite(cost_to_reach([(1.0, 1.0)], 2.0).cpu)
