"""The four-bar in absolute (scene 'four_bar', (1.27)), relative (1.29) and natural (1.31)
coordinates: three independent descriptions of one mechanism (kernel/src/model and
kernel/src/problems/mbdk_four_bar_forms.f90) must give the same motion.

References: each form against the others. The absolute form is assembled from joints and bodies;
the other two are hand-written mass matrices and constraints, so an error in any one shows up.
"""
import numpy as np
import pytest

import mbdk
from mbdk.problems import four_bar_points, four_bar_state

A_LEN, B_LEN = 0.6, 1.8


def _absolute_points(q):
    crank, coupler_c, coupler_angle = q[:, 2], q[:, 3:5], q[:, 5]
    rb = A_LEN * np.c_[np.cos(crank), np.sin(crank)]
    rc = coupler_c + 0.5 * B_LEN * np.c_[np.cos(coupler_angle), np.sin(coupler_angle)]
    return rb, rc


def test_scene_and_hand_written_forms_describe_the_same_mechanism():
    p = mbdk.problems()["four_bar_relative"].params
    sc = mbdk.scene("four_bar")
    assert (p["a"], p["b"], p["c"], p["d"]) == (0.6, 1.8, 1.2, 2.0)
    assert [b.mass for b in sc.bodies] == [p["m1"], p["m2"], p["m3"]]
    r = mbdk.simulate(sc, "rk4", formulation="reduced", h=1e-3, t_end=1e-3)
    rb, rc = _absolute_points(r.q[:1])
    eb, ec = four_bar_points(p, np.pi / 3)
    assert np.allclose(rb[0], eb, atol=1e-9) and np.allclose(rc[0], ec, atol=1e-9)


def test_initial_accelerations_agree():
    """At rest at crank 60 deg the crank's angular acceleration is one number; each form
    computes it from its own M, D and gamma."""
    sc = mbdk.scene("four_bar")
    r = mbdk.simulate(sc, "rk4", formulation="reduced", h=1e-3, t_end=1e-3)
    crank_acc = r.a[0, 2]
    f_rel = mbdk.evaluate_rhs("four_bar_relative", 0.0, four_bar_state("relative"))
    f_nat = mbdk.evaluate_rhs("four_bar_natural", 0.0, four_bar_state("natural"))
    s, c = np.sin(np.pi / 3), np.cos(np.pi / 3)
    assert f_rel[3] == pytest.approx(crank_acc, rel=1e-12)
    # at rest the acceleration of B is a * phi1'' * (-sin, cos)
    assert f_nat[4:6] == pytest.approx(A_LEN * crank_acc * np.array([-s, c]), rel=1e-12)
    assert abs(crank_acc) > 1.0          # it does move


def test_trajectories_agree_over_five_seconds():
    sc = mbdk.scene("four_bar")
    diffs = []
    for h in (1e-3, 5e-4):
        r = mbdk.simulate(sc, "rk4", formulation="reduced", h=h, t_end=5.0)
        rel = mbdk.solve_ode("four_bar_relative", "rk4", h=h, t_end=5.0)
        nat = mbdk.solve_ode("four_bar_natural", "rk4", h=h, t_end=5.0)
        rb, rc = _absolute_points(r.q)
        assert np.abs(r.q[:, 2] - rel.y[:, 0]).max() < 1e-9
        diffs.append(max(np.abs(rb - nat.y[:, 0:2]).max(), np.abs(rc - nat.y[:, 2:4]).max()))
        # the motion is large: the crank turns through more than a radian
        assert np.ptp(rel.y[:, 0]) > 1.0
    # natural against absolute: the difference is the two truncation errors, so it shrinks
    # with order 4 (a factor 16 for half the step) and is small
    assert diffs[0] / diffs[1] > 12
    assert diffs[1] < 2e-7


@pytest.mark.parametrize("form", ["four_bar_relative", "four_bar_natural"])
def test_energy_matches_the_scene_and_is_conserved(form):
    info = mbdk.problems()[form]
    res = mbdk.solve_ode(form, "rk4", h=1e-3, t_end=5.0)
    e = info.energy(res.y, info.params)
    sc = mbdk.simulate(mbdk.scene("four_bar"), "rk4", formulation="reduced", h=1e-3, t_end=1e-3)
    assert e[0] == pytest.approx(sc.energy[0], rel=1e-12)
    assert np.ptp(e) < 1e-6 * abs(e[0])


def test_baumgarte_parameters_act_on_the_hand_written_forms():
    """alpha = beta = 0 is the plain reduction; Baumgarte terms shrink the drift of (1.31)."""
    plain = mbdk.solve_ode("four_bar_natural", "rk4", h=2e-3, t_end=5.0)
    stab = mbdk.solve_ode("four_bar_natural", "rk4", h=2e-3, t_end=5.0,
                          params={"alpha": 10.0, "beta": 10.0})
    def drift(y):
        return np.abs(y[:, 0] ** 2 + y[:, 1] ** 2 - A_LEN**2).max()
    assert drift(stab.y) < drift(plain.y) / 10


def test_unassemblable_crank_angle_is_refused():
    with pytest.raises(mbdk.InvalidInputError, match="cannot be assembled"):
        four_bar_points({"a": 0.6, "b": 0.5, "c": 0.5, "d": 2.0}, 0.0)
    with pytest.raises(mbdk.InvalidInputError, match="'relative' or 'natural'"):
        four_bar_state("absolute")


def test_bad_parameters_get_a_named_error():
    with pytest.raises(mbdk.InvalidInputError, match="m2"):
        mbdk.solve_ode("four_bar_natural", "rk4", h=1e-3, t_end=0.01, params={"m2": 0.0})
