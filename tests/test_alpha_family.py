"""The generalized-alpha family of index-3 integrators (newmark, hht, generalized_alpha beside
trapezoidal_index3; issue 38): one stepping routine in the kernel, the members' parameters from
mbdk.alpha_family.

References: the closed forms of the family on the undamped oscillator (mbdk.alpha_family, an
independent numpy computation of the published amplification matrix; Chung and Hulbert 1993,
Hughes 9.3), the published high-frequency limits ((1 + alpha)/(1 - alpha) for HHT, rho_inf by
construction for generalized-alpha), the trapezoidal rule's period error Omega / (2
atan(Omega/2)) - 1 (Hughes 9.3), and reference solutions by rk4 at h = 1e-5 (planar) or dopri54
at rtol 1e-12 (spatial)."""
from __future__ import annotations

import math

import numpy as np
import pytest

import mbdk
from mbdk import alpha_family as AF
from mbdk import spectral

MEMBERS = [("trapezoidal_index3", {}), ("newmark", {"newmark_beta": 0.3025, "newmark_gamma": 0.6}),
           ("hht", {"alpha_hht": -0.1}), ("hht", {"alpha_hht": -1.0 / 3.0}),
           ("generalized_alpha", {"rho_inf": 0.8}), ("generalized_alpha", {"rho_inf": 0.0}),
           ("generalized_alpha", {"newmark_beta": 0.3, "newmark_gamma": 0.6, "alpha_m": 0.2,
                                  "alpha_f": 0.3})]


@pytest.mark.parametrize("method, opts", MEMBERS)
@pytest.mark.parametrize("omega_h", [0.05, 0.5, 3.0, 30.0])
def test_compiled_steps_have_the_closed_form_spectrum(method, opts, omega_h):
    """Spectral radius, damping ratio and period error measured from the kernel's steps on the
    oscillator (both formulations) equal the closed forms to 1e-9."""
    p = AF.parameters(method, **opts)
    cf = AF.closed_form_properties(p, omega_h)
    for form in ("augmented_lagrangian", "index3"):
        m = spectral.measured_properties(method, omega_h, formulation=form, **opts)
        assert np.allclose(m[:3], cf, rtol=0, atol=1e-9, equal_nan=True), (form, m, cf)


def test_closed_forms_are_the_published_ones():
    """The closed forms themselves: the trapezoidal rule keeps |lambda| = 1 with the period
    error Omega / (2 atan(Omega/2)) - 1; HHT's high-frequency radius is (1 + a)/(1 - a);
    generalized-alpha's is rho_inf; generalized-alpha with rho_inf = 0.5 is HHT with a = -1/3
    (alpha_m = 0)."""
    trap = AF.parameters("trapezoidal_index3")
    for w in (0.1, 1.0, 10.0):
        rho, xi, pe = AF.closed_form_properties(trap, w)
        assert rho == pytest.approx(1.0, abs=1e-14) and abs(xi) < 1e-14
        assert pe == pytest.approx(w / (2 * math.atan(w / 2)) - 1, rel=1e-12)
    # at Omega = 1e7 (where the designs' double root at infinity splits like Omega^-1/2)
    for a in (-0.05, -0.2, -1.0 / 3.0):
        assert AF.closed_form_properties(AF.parameters("hht", alpha_hht=a), 1e7)[0] == \
            pytest.approx((1 + a) / (1 - a), abs=1e-4)
    for r in (0.0, 0.3, 0.8, 1.0):
        assert AF.closed_form_properties(AF.parameters("generalized_alpha", rho_inf=r),
                                         1e7)[0] == pytest.approx(r, abs=1e-4)
    assert AF.parameters("generalized_alpha", rho_inf=0.5).as_options() == pytest.approx(
        AF.parameters("hht", alpha_hht=-1.0 / 3.0).as_options())


@pytest.mark.parametrize("method, opts", [("hht", {"alpha_hht": -0.3}),
                                          ("generalized_alpha", {"rho_inf": 0.6}),
                                          ("generalized_alpha", {"rho_inf": 0.0}),
                                          ("newmark", {"newmark_beta": 0.3025,
                                                       "newmark_gamma": 0.6})])
def test_a_stiff_spring_mode_loses_its_energy_at_the_spectral_radius(method, opts):
    """A stiff mode (Omega = omega h = 1000), 40 steps: its energy falls like rho^(2n), rho the
    closed-form spectral radius there (the per-step decay fitted to log E over steps 10-40
    within 6 %: the energy of an oscillating pair wobbles about that line), while the
    trapezoidal rule keeps it to 1e-6."""
    sc = spectral.oscillator()
    rho = AF.closed_form_properties(AF.parameters(method, **opts), 1000.0)[0]
    runs = {m: mbdk.simulate(sc, m, h=1000.0, t_end=40000.0, every=1, outputs=("energy",),
                             watch=False, **o)
            for m, o in ((method, opts), ("trapezoidal_index3", {}))}
    e = runs["trapezoidal_index3"].energy
    assert np.abs(e / e[0] - 1).max() < 1e-6
    e = runs[method].energy
    n = np.arange(len(e))
    slope = np.polyfit(n[10:], 0.5 * np.log(e[10:]), 1)[0]
    assert math.exp(slope) == pytest.approx(rho, rel=0.06)


@pytest.mark.parametrize("formulation", ["augmented_lagrangian", "index3"])
def test_rho_inf_1_and_hht_0_are_the_trapezoidal_rule(formulation):
    """generalized_alpha with rho_inf = 1 (alpha_m = alpha_f = 1/2: the pseudo-acceleration
    stays the acceleration from a consistent start) and hht with alpha = 0 (the trapezoidal
    rule's own parameters) reproduce trapezoidal_index3 on the double pendulum to roundoff."""
    sc = mbdk.scene("double_pendulum")
    kw = dict(h=1e-3, t_end=1.0, every=100, formulation=formulation, outputs=())
    ref = mbdk.simulate(sc, "trapezoidal_index3", **kw)
    for m, o in (("generalized_alpha", {"rho_inf": 1.0}), ("hht", {"alpha_hht": 0.0})):
        r = mbdk.simulate(sc, m, **kw, **o)
        assert np.abs(r.q - ref.q).max() < 1e-12 and np.abs(r.v - ref.v).max() < 1e-10, m


PLANAR_ORDER = [("double_pendulum", 1.0), ("four_bar", 1.0)]


@pytest.mark.parametrize("name, t_end", PLANAR_ORDER)
@pytest.mark.parametrize("method, opts", MEMBERS[1:6])
@pytest.mark.parametrize("formulation", ["augmented_lagrangian", "index3"])
def test_order_in_q_v_and_lambda_on_planar_mechanisms(name, t_end, method, opts, formulation):
    """Against rk4 at h = 1e-5: the error in q and v falls 4-fold per halving of h for the
    second-order members (gamma = 1/2 - alpha_m + alpha_f) and 2-fold for Newmark with gamma =
    0.6; the projected form's multipliers (from the constrained solve at the step's state)
    likewise; the joints hold to 1e-10."""
    sc = mbdk.scene(name)
    ref = mbdk.simulate(sc, "rk4", h=1e-5, t_end=t_end, every=round(t_end / 1e-5),
                        outputs=("multipliers",))
    p = AF.parameters(method, **opts)
    errs, lerrs = [], []
    for h in (2e-3, 1e-3, 5e-4):
        r = mbdk.simulate(sc, method, formulation=formulation, h=h, t_end=t_end, every=1,
                          outputs=("multipliers", "residuals"), **opts)
        assert r.residuals[:, 0].max() < 1e-10            # at every step
        errs.append(max(np.abs(r.q[-1] - ref.q[-1]).max(), np.abs(r.v[-1] - ref.v[-1]).max()))
        lerrs.append(np.abs(r.multipliers[-1] - ref.multipliers[-1]).max())
    ratio = 4.0 if p.second_order else 2.0
    for e in (errs,) + ((lerrs,) if formulation == "augmented_lagrangian" else ()):
        assert 0.85 * ratio < e[0] / e[1] < 1.15 * ratio, (errs, lerrs)
        assert 0.85 * ratio < e[1] / e[2] < 1.15 * ratio, (errs, lerrs)


@pytest.mark.parametrize("name", ["heavy_top", "spatial_double_pendulum", "bricard"])
@pytest.mark.parametrize("method, opts", [("generalized_alpha", {"rho_inf": 0.8}),
                                          ("hht", {"alpha_hht": -0.2})])
def test_second_order_on_spatial_mechanisms_on_the_rotation_group(name, method, opts):
    """The same step on spatial bodies (the retraction turns a body by the exponential map:
    the Lie-group form), against dopri54 at rtol 1e-12: 4-fold per halving of h in q and v, the
    joints to 1e-12, in the augmented form (Bricard's redundant row included) and, but for
    Bricard, in the index3 form (Bricard's is refused by name: its Newton matrix is singular
    with redundant rows)."""
    sc = mbdk.scene(name)
    ref = mbdk.simulate(sc, "dopri54", formulation="projection", rtol=1e-12, atol=1e-14,
                        t_end=0.5, dt_out=0.5)
    forms = ["augmented_lagrangian"] + ([] if name == "bricard" else ["index3"])
    for form in forms:
        errs = []
        for h in (4e-3, 2e-3, 1e-3):
            r = mbdk.simulate(sc, method, formulation=form, h=h, t_end=0.5, every=1, **opts)
            assert r.residuals[:, 0].max() < 1e-12        # at every step
            errs.append(max(np.abs(r.q[-1] - ref.q[-1]).max(), np.abs(r.v[-1] - ref.v[-1]).max()))
        assert 3.5 < errs[0] / errs[1] < 4.5 and 3.5 < errs[1] / errs[2] < 4.5, (form, errs)
    if name == "bricard":
        with pytest.raises(mbdk.RedundantConstraintsError, match="augmented_lagrangian"):
            mbdk.simulate(sc, method, formulation="index3", h=1e-3, t_end=0.1, **opts)


def test_the_damped_members_run_the_plain_index3_form_where_the_book_scheme_fails():
    """The plain index-3 form (no projections, as HHT-I3 in Adams and Chrono) on the heavy top
    at h = 2e-3: the trapezoidal rule's undamped oscillation in the constrained directions
    drives its angular momentum about the vertical off (InvariantDriftError, named), while
    generalized_alpha (rho_inf = 0.8) and hht damp it and run with the joint at roundoff."""
    sc = mbdk.scene("heavy_top")
    with pytest.raises(mbdk.InvariantDriftError):
        mbdk.simulate(sc, "trapezoidal_index3", formulation="index3", h=2e-3, t_end=0.5)
    for m, o in (("generalized_alpha", {}), ("hht", {"alpha_hht": -0.1})):
        r = mbdk.simulate(sc, m, formulation="index3", h=2e-3, t_end=0.5, **o)
        assert r.success and r.residuals[:, 0].max() < 1e-12


@pytest.mark.parametrize("method, kw, error, text", [
    ("rk4", {"rho_inf": 0.5}, mbdk.InvalidInputError, "not of rk4"),
    ("hht", {"rho_inf": 0.5}, mbdk.InvalidInputError, "it takes alpha_hht"),
    ("hht", {"alpha_hht": 0.1}, mbdk.InvalidInputError, r"\[-1/3, 0\]"),
    ("generalized_alpha", {"rho_inf": 1.5}, mbdk.InvalidInputError, r"\[0, 1\]"),
    ("generalized_alpha", {"rho_inf": 0.5, "alpha_m": 0.1}, mbdk.InvalidInputError, "not both"),
    ("generalized_alpha", {"alpha_m": 0.1}, mbdk.InvalidInputError, "all four"),
    ("newmark", {"newmark_gamma": 0.4}, mbdk.InvalidInputError, "unconditionally stable"),
    ("newmark", {"newmark_beta": 0.1}, mbdk.InvalidInputError, "2 beta < gamma"),
    ("generalized_alpha", {"newmark_beta": 0.3, "newmark_gamma": 0.3, "alpha_m": 0.0,
                           "alpha_f": 0.0}, mbdk.InvalidInputError, "unconditionally stable"),
    ("generalized_alpha", {"newmark_beta": 0.3, "newmark_gamma": 0.4, "alpha_m": 0.3,
                           "alpha_f": 0.2}, mbdk.InvalidInputError, "alpha_m <= alpha_f"),
    ("newmark", {"newmark_beta": float("nan")}, mbdk.InvalidInputError, "finite"),
    ("generalized_alpha", {"adaptive": True}, mbdk.NotApplicableError,
     "adaptive='estimated'"),
    ("newmark", {"newmark_beta": 0.3025, "newmark_gamma": 0.6, "adaptive": "estimated"},
     mbdk.NotApplicableError, "first order"),
])
def test_bad_family_options_are_named(method, kw, error, text):
    with pytest.raises(error, match=text):
        mbdk.simulate(mbdk.scene("double_pendulum"), method, h=1e-3, t_end=0.01, **kw)


def test_the_stable_set_is_stable():
    """Every parameter set alpha_family.stable admits has a spectral radius of at most 1 at
    every Omega from 1e-3 to 1e6 (the closed form, 400 random sets), and the members built
    from rho_inf and alpha_hht lie in it; sets outside it that amplify exist (a check that can
    fail)."""
    rng = np.random.default_rng(7)
    omegas = np.geomspace(1e-3, 1e6, 40)
    admitted = amplifying_outside = 0
    for _ in range(3000):
        am, af = rng.uniform(-1.0, 0.9, 2)
        p = AF.AlphaParameters(beta=rng.uniform(0.01, 1.0), gamma=rng.uniform(0.3, 1.2),
                               alpha_m=am, alpha_f=af)
        rho = max(AF.closed_form_properties(p, w)[0] for w in omegas)
        if AF.stable(p):
            admitted += 1
            assert rho <= 1 + 1e-9, p
        elif rho > 1 + 1e-6:
            amplifying_outside += 1
        if admitted >= 400:
            break
    assert admitted >= 100 and amplifying_outside > 0
    for r in np.linspace(0, 1, 11):
        assert AF.stable(AF.parameters("generalized_alpha", rho_inf=r))
    for a in np.linspace(-1 / 3, 0, 11):
        assert AF.stable(AF.parameters("hht", alpha_hht=a))


def test_the_trapezoidal_members_take_step_size_control():
    """hht with alpha = 0 and newmark with its defaults are the trapezoidal rule: step-size
    control runs them (the same steps as trapezoidal_index3's); extrapolation is theirs alone
    (test_bad_family_options_are_named)."""
    sc = mbdk.scene("double_pendulum")
    kw = dict(h=1e-2, t_end=1.0, adaptive=True, err_rtol=1e-6, dt_out=0.1, outputs=())
    ref = mbdk.simulate(sc, "trapezoidal_index3", **kw)
    for m, o in (("hht", {"alpha_hht": 0.0}), ("newmark", {})):
        r = mbdk.simulate(sc, m, **kw, **o)
        assert r.stats.steps == ref.stats.steps and np.array_equal(r.q, ref.q), m


def test_the_book_form_multipliers_are_flagged_on_spatial_scenes_too():
    """The index3 form's multipliers (no projections) carry the book scheme's error on
    spatial scenes as on planar ones: an AccuracyWarning and the manifest's note say so; the
    augmented form's come without one."""
    sc = mbdk.scene("spatial_double_pendulum")
    with pytest.warns(mbdk.AccuracyWarning, match="multipliers"):
        r = mbdk.simulate(sc, "generalized_alpha", formulation="index3", h=1e-3, t_end=0.05)
    assert "multipliers" in r.manifest
    r = mbdk.simulate(sc, "generalized_alpha", h=1e-3, t_end=0.05)
    assert "multipliers" not in r.manifest


@pytest.mark.parametrize("method, opts", [("generalized_alpha", {"rho_inf": 0.8}),
                                          ("hht", {"alpha_hht": -0.2})])
def test_substep_retries_keep_the_pseudo_acceleration(method, opts):
    """A Newton limit of 3 iterations makes the parallelogram's augmented steps fail and be
    retried in substeps (the step is cut fourfold, the pseudo-acceleration carried over): the
    run still agrees with the one without retries to the method's error (rk4 at h = 1e-5 on
    the penalty formulation, which runs the redundant joint, the reference), and the retries
    happened."""
    sc = mbdk.scene("parallelogram_redundant")
    ref = mbdk.simulate(sc, "rk4", formulation="penalty", h=1e-5, t_end=0.5, every=50000,
                        outputs=())
    kw = dict(h=2e-3, t_end=0.5, every=250, outputs=(), **opts)
    plain = mbdk.simulate(sc, method, **kw)
    retried = mbdk.simulate(sc, method, max_iter=3, **kw)
    assert retried.stats.newton_failures > 0
    e_plain = np.abs(plain.q[-1] - ref.q[-1]).max()
    e_retried = np.abs(retried.q[-1] - ref.q[-1]).max()
    assert e_retried < 2 * e_plain


def _moving_double_pendulum():
    """The double pendulum started in motion (3 and -2 rad/s), where q''' != 0 at t0: a start
    at rest hides the pseudo-acceleration's start-up error (q''' = 0 there)."""
    sc = mbdk.scene("double_pendulum")
    for b, w in zip(sc.bodies, (3.0, -2.0)):
        b.omega = w
        b.given = ["angle", "omega"]
    return sc


@pytest.mark.parametrize("method, opts", [("generalized_alpha", {"rho_inf": 0.5}),
                                          ("generalized_alpha", {"rho_inf": 0.0}),
                                          ("hht", {"alpha_hht": -0.3})])
def test_the_pseudo_acceleration_starts_at_its_shifted_time(method, opts):
    """Arnold and Bruls (2007): ap approximates q'' at t + (alpha_m - alpha_f) h, so a start
    at ap = a(t0) is an O(h) error that decays only as the spurious root's powers. Started
    there (the kernel's shifted_start), the first steps keep the local order of a second-order
    step: after three steps the errors of v and of the projected form's multipliers fall
    8-fold per halving of h (they fell about 3-fold, order 1.5-1.8, from ap = a(t0): v's first
    step took h gamma times ap's O(h) error). Reference: rk4 at h / 200."""
    sc = _moving_double_pendulum()
    ev, el = [], []
    for h in (2.5e-3, 1.25e-3, 6.25e-4):
        ref = mbdk.simulate(sc, "rk4", h=h / 200, t_end=3 * h, every=200,
                            outputs=("multipliers",))
        r = mbdk.simulate(sc, method, formulation="augmented_lagrangian", h=h, t_end=3 * h,
                          outputs=("multipliers",), **opts)
        ev.append(np.abs(r.v[3] - ref.v[3]).max())
        el.append(np.abs(r.multipliers[1] - ref.multipliers[1]).max())
    for e in (ev, el):
        assert 7.0 < e[0] / e[1] < 9.0 and 7.0 < e[1] / e[2] < 9.0, (ev, el)


def test_the_book_forms_multipliers_from_a_start_in_motion():
    """The plain index-3 form from a start in motion: the first steps' multipliers carry the
    index-3 error O(h^3) / h^2 = O(h) of their positions, which generalized_alpha damps
    (rho_inf^n): by t = 0.2 s they are second order; the trapezoidal member (rho_inf = 1) never
    damps it and its multipliers do not converge at all (the book's scheme's weakness, the
    module header's), while q and v stay second order in both."""
    sc = _moving_double_pendulum()
    ref = mbdk.simulate(sc, "rk4", h=1e-5, t_end=0.2, every=20000, outputs=("multipliers",))
    ga, tr, qv = [], [], []
    for h in (3.125e-3, 1.5625e-3):
        r = mbdk.simulate(sc, "generalized_alpha", rho_inf=0.5, formulation="index3", h=h,
                          t_end=0.2, every=round(0.2 / h), outputs=("multipliers",))
        ga.append(np.abs(r.multipliers[-1] - ref.multipliers[-1]).max())
        qv.append(np.abs(r.v[-1] - ref.v[-1]).max())
        with pytest.warns(mbdk.AccuracyWarning):
            t = mbdk.simulate(sc, "trapezoidal_index3", formulation="index3", h=h, t_end=0.2,
                              every=round(0.2 / h), outputs=("multipliers",))
        tr.append(np.abs(t.multipliers[-1] - ref.multipliers[-1]).max())
    assert 3.5 < ga[0] / ga[1] < 4.5 and 3.5 < qv[0] / qv[1] < 4.5, (ga, qv)
    assert tr[1] > 0.5 * tr[0] and tr[1] > 100 * ga[1], (tr, ga)


@pytest.mark.parametrize("method, opts", [("generalized_alpha", {"rho_inf": 0.5}),
                                          ("generalized_alpha", {"rho_inf": 0.0}),
                                          ("hht", {"alpha_hht": -0.3}),
                                          ("newmark", {"newmark_beta": 0.3025}),
                                          ("trapezoidal_index3", {})])
def test_the_local_error_constants_are_one_steps_error(method, opts):
    """The kernel's constants of the estimated step-size control (index3_error_constants:
    local errors lte_q h^3 q''' and lte_v h^3 q'''') against one step of the family's own
    amplification matrix (mbdk.alpha_family.amplification, an independent numpy form of the
    published relations) on q = sin(t + 0.7), started from the exact q, v and the
    pseudo-acceleration at its shifted time (ap = q''(t + d h) + c h^2 q'''', Arnold and Bruls
    2007): (q1 - q(h)) / (h^3 q'''(0)) -> lte_q and (v1 - v(h)) / (h^3 q''''(0)) -> lte_v as
    h -> 0 (v's h^2 term vanishes for every second-order member)."""
    from mbdk import _kernel
    p = AF.parameters(method, **opts)
    opt = mbdk.Index3Options(**p.as_options())
    lte_q, lte_v, status = _kernel.index3_error_constants(opt.pack())
    assert status == 0
    am, af = p.alpha_m, p.alpha_f
    d = am - af
    c = 0.5 * (1 - af) - 0.5 * ((1 - am) * (1 + d) ** 2 + am * d * d)
    phase = 0.7
    for h in (1e-2, 5e-3):
        ap0 = -math.sin(d * h + phase) + c * h * h * math.sin(phase)
        x1 = AF.amplification(p, h) @ np.array([math.sin(phase), h * math.cos(phase),
                                                h * h * ap0])
        eq = (x1[0] - math.sin(h + phase)) / (h ** 3 * -math.cos(phase))
        ev = (x1[1] / h - math.cos(h + phase)) / (h ** 3 * math.sin(phase))
        assert eq == pytest.approx(lte_q, abs=2 * h), (h, eq, lte_q)
        assert ev == pytest.approx(lte_v, abs=2 * h), (h, ev, lte_v)


@pytest.mark.parametrize("method, opts", [("generalized_alpha", {"rho_inf": 0.8}),
                                          ("hht", {"alpha_hht": -0.2})])
def test_the_damped_members_take_estimated_step_size_control(method, opts):
    """adaptive='estimated' on the damped members, planar and spatial: the run lands on its
    dt_out grid, the joints hold, and the error against a tight reference falls as err_rtol
    is tightened (each tenfold at least 3-fold: a second-order step under local error control
    gives about tol^(2/3))."""
    for name in ("double_pendulum", "heavy_top"):
        sc = mbdk.scene(name)
        ref = (mbdk.simulate(sc, "rk4", h=1e-5, t_end=1.0, every=100000)
               if name == "double_pendulum" else
               mbdk.simulate(sc, "dopri54", formulation="projection", rtol=1e-12, atol=1e-14,
                             t_end=1.0, dt_out=1.0))
        errs = []
        for tol in (1e-4, 1e-5, 1e-6):
            r = mbdk.simulate(sc, method, h=1e-3, t_end=1.0, adaptive="estimated",
                              err_rtol=tol, err_atol=tol, dt_out=0.5, **opts)
            assert r.success and np.allclose(r.t, [0.0, 0.5, 1.0], rtol=0, atol=1e-12)
            assert r.residuals[:, 0].max() < 1e-10
            assert r.manifest["step_control"]["mode"] == "estimated"
            errs.append(max(np.abs(r.q[-1] - ref.q[-1]).max(),
                            np.abs(r.v[-1] - ref.v[-1]).max()))
        assert errs[0] > 3 * errs[1] > 9 * errs[2], (name, errs)


def test_the_driven_slider_in_closed_form():
    """mbdk.benchmarks.driven_slider: q is the joints' at every step, so every error is in the
    constraint directions. Against the closed form (mbdk.benchmarks.driven_slider_exact: the
    drive's force m x'' + k x, the guide's m g): the projected form's v, a and multipliers are
    exact to roundoff for every member; in the book's form v is second order, and the damped
    members' multipliers converge (rho_inf^n damps each step's index-3 error) while the
    trapezoidal member's stay off by the same amount at every h."""
    from mbdk.benchmarks import driven_slider, driven_slider_exact
    sc = driven_slider()
    for method, opts in MEMBERS[:1] + MEMBERS[2:6]:
        r = mbdk.simulate(sc, method, h=1e-2, t_end=1.0, every=5, **opts)
        ex = driven_slider_exact(r.t)
        for key in ("q", "v", "a", "multipliers"):
            assert np.abs(getattr(r, key) - ex[key]).max() < 1e-12, (method, opts, key)
    lam = {}
    for method, opts in (("trapezoidal_index3", {}), ("generalized_alpha", {"rho_inf": 0.5})):
        for h in (5e-3, 2.5e-3):
            with pytest.warns(mbdk.AccuracyWarning) if method == "trapezoidal_index3" else \
                    _no_warning():
                r = mbdk.simulate(sc, method, formulation="index3", h=h, t_end=1.0,
                                  every=round(0.05 / h), **opts)
            ex = driven_slider_exact(r.t)
            lam[method, h] = np.abs(r.multipliers - ex["multipliers"]).max()
            assert np.abs(r.q - ex["q"]).max() < 1e-12
    assert lam["generalized_alpha", 5e-3] > 3.5 * lam["generalized_alpha", 2.5e-3]
    assert lam["trapezoidal_index3", 2.5e-3] > 0.9 * lam["trapezoidal_index3", 5e-3] > 1.0


def _no_warning():
    import contextlib
    return contextlib.nullcontext()
