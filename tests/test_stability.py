"""Stability regions from the kernel's step matrices against values derived here.

Every reference is derived in this file from the method's definition (stability polynomials,
BDF generating polynomials from backward differences, Jury's criterion) or quoted with its
source (Hairer & Wanner, Solving ODE II, 2nd ed., Table V.2.3, for the A(alpha) angles).
"""
import math

import numpy as np
import pytest

import mbdk
from mbdk import stability as S
from mbdk.errors import InvalidInputError, NotApplicableError

RNG = np.random.default_rng(20261121)
Z = RNG.uniform(-4, 1, 40) + 1j * RNG.uniform(-3, 3, 40)


def bdf_polys(k):
    """rho, sigma of BDFk (coefficients, highest power first), from the definition
    sum_{j=1..k} (1/j) nabla^j y_{n+1} = h f_{n+1}: rho(zeta) = sum_j (1/j) zeta^(k-j) (zeta-1)^j."""
    rho = np.zeros(k + 1)
    for j in range(1, k + 1):
        p = np.polymul(np.poly1d([1.0, -1.0]) ** j, np.poly1d([1.0] + [0.0] * (k - j)))
        rho = np.polyadd(rho, np.asarray(p.coeffs) / j)
    sigma = np.zeros(k + 1)
    sigma[0] = 1.0
    return np.asarray(rho), sigma


def bdf_root_radius(k, z):
    rho, sigma = bdf_polys(k)
    return max(abs(np.roots(rho - z * sigma)))


RK_POLY = {  # R(z) of the explicit RK methods: the Taylor polynomial of exp(z) to their order
    "explicit_euler": [1, 1],
    "heun": [1, 1, 1 / 2],
    "rk4": [1, 1, 1 / 2, 1 / 6, 1 / 24],
}


@pytest.mark.parametrize("method", list(RK_POLY))
def test_explicit_amplification_is_the_taylor_polynomial(method):
    r = S.amplification_factor(method, Z)
    ref = np.polyval(RK_POLY[method][::-1], Z)
    assert np.max(np.abs(r - ref)) < 1e-13


@pytest.mark.parametrize("method, ref", [
    ("implicit_euler", lambda z: 1 / (1 - z)),
    ("bdf1", lambda z: 1 / (1 - z)),
    ("trapezoidal", lambda z: (1 + z / 2) / (1 - z / 2)),
])
def test_implicit_amplification(method, ref):
    r = S.amplification_factor(method, Z)
    assert np.max(np.abs(r - ref(Z)) / np.abs(ref(Z))) < 1e-12


def test_amplification_follows_the_kernels_butcher_data():
    """R(z) = 1 + z b^T (I - zA)^-1 1 from the tableau the kernel reports equals the step
    matrix: both come from the same Fortran data."""
    from mbdk import _kernel
    for m in RK_POLY:
        a, b, c, s, order, ok = _kernel.butcher_tableau(mbdk.methods()[m].id)
        s = int(s)
        a, b = np.asarray(a)[:s, :s], np.asarray(b)[:s]
        ref = [1 + z * b @ np.linalg.solve(np.eye(s) - z * a, np.ones(s)) for z in Z]
        assert np.max(np.abs(S.amplification_factor(m, Z) - ref)) < 1e-13


@pytest.mark.parametrize("k", range(2, 7))
def test_bdf_companion_radius_is_the_root_radius(k):
    got = S.spectral_radius(f"bdf{k}", Z)
    ref = np.array([bdf_root_radius(k, z) for z in Z])
    assert np.max(np.abs(got - ref)) < 1e-9


@pytest.mark.parametrize("method", ["rk4", "heun", "trapezoidal", "bdf3", "bdf6"])
def test_oscillator_form_gives_the_same_radius(method):
    """The second-order test system (roots z and conj z), used for euler_cromer, agrees with
    the 2 x 2 real form for the first-order methods, so the regions are comparable."""
    zz = Z[np.abs(Z.imag) > 0.05]
    a = np.zeros((zz.size, 2, 2))
    a[:, 0, 1] = 1
    a[:, 1, 0] = -np.abs(zz) ** 2
    a[:, 1, 1] = 2 * zz.real
    m = S.step_matrices(method, a, 1.0)
    osc = np.abs(np.linalg.eigvals(m)).max(axis=1)
    assert np.max(np.abs(osc - S.spectral_radius(method, zz))) < 1e-8


def test_real_intervals():
    # explicit Euler and Heun: R(-2) = -1 and 1; rk4: the real root of R(x) = 1 left of 0
    assert S.real_interval("explicit_euler")[0] == pytest.approx(-2.0, abs=1e-12)
    assert S.real_interval("heun")[0] == pytest.approx(-2.0, abs=1e-12)
    cubic = np.roots([1 / 24, 1 / 6, 1 / 2, 1])          # (R(x) - 1)/x
    x = min(r.real for r in cubic if abs(r.imag) < 1e-12)
    assert abs(np.polyval(RK_POLY["rk4"][::-1], x + 0.0) - 1) < 1e-12
    assert S.real_interval("rk4")[0] == pytest.approx(x, abs=1e-11)
    assert S.real_interval("rk4")[0] == pytest.approx(-2.785293563405282, abs=1e-11)
    # Euler-Cromer on the critically damped oscillator, step matrix in (q, h v):
    # [[1 - x^2, 1 + 2x], [-x^2, 1 + 2x]]; Jury: |det| <= 1 and |tr| <= 1 + det give
    # x >= -1 and x^2 - 4x - 4 <= 0, i.e. x >= 2 - 2 sqrt 2
    assert S.real_interval("euler_cromer")[0] == pytest.approx(2 - 2 * math.sqrt(2), abs=1e-11)
    for m in ["implicit_euler", "trapezoidal", "bdf1", "bdf2", "bdf3", "bdf4", "bdf5", "bdf6"]:
        assert S.real_interval(m) == (-math.inf, 0.0)


def locus_angle(k):
    """min over the BDF boundary locus z(phi) = rho/sigma(e^{i phi}) in the left half-plane of
    the angle from the negative real axis: the A(alpha) angle (Hairer & Wanner V.2)."""
    from scipy.optimize import minimize_scalar
    rho, sigma = bdf_polys(k)

    def psi(phi):
        w = np.exp(1j * phi)
        z = np.polyval(rho, w) / np.polyval(sigma, w)
        return math.atan2(abs(z.imag), -z.real) if z.real < 0 else math.pi / 2
    phis = np.linspace(1e-3, math.pi, 20001)
    vals = np.array([psi(p) for p in phis])
    i = int(np.argmin(vals))
    r = minimize_scalar(psi, bounds=(phis[i - 1], phis[i + 1]), method="bounded",
                        options={"xatol": 1e-13})
    return math.degrees(r.fun)


@pytest.mark.parametrize("k, table", [(3, 86.03), (4, 73.35), (5, 51.84), (6, 17.84)])
def test_bdf_alpha_angles(k, table):
    got = S.a_alpha(f"bdf{k}")
    assert got == pytest.approx(locus_angle(k), abs=1e-6)
    assert got == pytest.approx(table, abs=0.006)    # Hairer & Wanner II, Table V.2.3


@pytest.mark.parametrize("method", ["implicit_euler", "trapezoidal", "bdf1", "bdf2"])
def test_a_stable_methods(method):
    assert S.a_alpha(method) == 90.0


def test_explicit_methods_are_not_a_stable():
    for m in ["explicit_euler", "heun", "rk4", "euler_cromer"]:
        assert S.a_alpha(m) == 0.0


def test_stability_region_object():
    r = S.stability_region("rk4", n=121)
    assert r.rho.shape == (121, 121)
    assert r.real_interval[0] == pytest.approx(-2.785293563405282, abs=1e-11)
    assert r.a_stable is None and r.alpha_deg is None
    # the boundary is where |R| = 1, to the grid's resolution
    pts = np.concatenate(r.boundary)
    assert np.max(np.abs(np.abs(S.amplification_factor("rk4", pts)) - 1)) < 0.02
    # the region contains the stable disc of explicit Euler's boundary point -1 +- 0.5i
    assert S.spectral_radius("rk4", [-1 + 0.5j])[0] < 1
    r = S.stability_region("bdf4", n=61)
    assert r.a_stable is False and r.alpha_deg == pytest.approx(locus_angle(4), abs=1e-6)


def test_oscillator_limits():
    # rk4: |R(iy)|^2 = 1 - y^6/72 + y^8/576 = 1 at y = 2 sqrt 2; Euler-Cromer: det = 1,
    # tr = 2 - y^2, |tr| <= 2 up to y = 2; explicit Euler |1 + iy| > 1; heun 1 + y^4/4 > 1;
    # trapezoidal |R(iy)| = 1 for all y
    assert S.oscillator_limit("rk4") == pytest.approx(2 * math.sqrt(2), rel=1e-9)
    assert S.oscillator_limit("euler_cromer") == pytest.approx(2.0, rel=1e-9)
    assert S.oscillator_limit("explicit_euler") == 0.0
    assert S.oscillator_limit("heun") == 0.0
    assert S.oscillator_limit("trapezoidal") == math.inf
    # bdf3 is weakly unstable on the imaginary axis near 0: its root radius there exceeds 1
    assert bdf_root_radius(3, 0.3j) > 1 + 1e-6
    assert S.oscillator_limit("bdf3") == 0.0
    # with damping zeta = 0.1 explicit Euler becomes stable: |1 + z| <= 1, z = h(-0.1 + i 0.995)
    # gives h <= 2 * 0.1 = 0.2
    assert S.oscillator_limit("explicit_euler", zeta=0.1) == pytest.approx(0.2, rel=1e-7)


def test_oscillator_response_closed_forms():
    hT = np.array([0.01, 0.05, 0.1, 0.2, 0.3])
    w = 2 * math.pi * hT
    tr = S.oscillator_response("trapezoidal", hT)
    assert np.allclose(tr.spectral_radius, 1, atol=1e-12)
    assert np.allclose(tr.numerical_damping, 0, atol=1e-12)
    assert np.allclose(tr.period_error, w / (2 * np.arctan(w / 2)) - 1, rtol=1e-9)
    ec = S.oscillator_response("euler_cromer", hT)
    assert np.allclose(ec.spectral_radius, 1, atol=1e-12)
    assert np.allclose(ec.period_error, w / np.arccos(1 - w ** 2 / 2) - 1, rtol=1e-9)
    ee = S.oscillator_response("explicit_euler", hT)
    assert np.allclose(ee.spectral_radius, np.sqrt(1 + w ** 2), rtol=1e-12)
    assert np.all(ee.numerical_damping < 0)          # it amplifies
    ie = S.oscillator_response("implicit_euler", hT)
    assert np.allclose(ie.spectral_radius, 1 / np.sqrt(1 + w ** 2), rtol=1e-12)
    assert np.all(ie.numerical_damping > 0)          # it damps


def test_damped_oscillator_step_limit_matches_linear_theory():
    """The damped oscillator is linear, so the bisection on runs must find the limit the step
    matrices predict for the same run length and growth bound."""
    _, jac = S.linearisation("damped_oscillator")
    assert np.allclose(jac, [[0, 1], [-10, -0.5]], atol=1e-7)
    for m in ["explicit_euler", "rk4"]:
        lim = S.largest_stable_step("damped_oscillator", m, t_span=20.0)
        forever, horizon = S.linear_step_limits(m, jac, t_span=20.0)
        assert lim.h == pytest.approx(horizon, rel=0.03)
        assert lim.h_fail is not None and lim.h_fail > lim.h
    # explicit Euler, bounded for ever: |1 + h lambda| <= 1 with lambda = -0.25 +- i sqrt(9.9375)
    # gives h <= 0.5 / 10 = 0.05
    forever, _ = S.linear_step_limits("explicit_euler", jac)
    assert forever == pytest.approx(0.05, rel=1e-7)


def test_implicit_method_tolerates_the_cap_on_the_pendulum():
    lim = S.largest_stable_step("pendulum", "implicit_euler", t_span=20.0, h_cap=0.5)
    assert lim.h == 0.5 and lim.h_fail is None


def test_registry_claims_match_the_computation():
    about = {m: i.stability for m, i in mbdk.methods().items()}
    assert "2.785" in about["rk4"]
    assert f"{-S.real_interval('rk4')[0]:.3f}".startswith("2.785")
    for k in range(3, 7):
        stated = float(about[f"bdf{k}"].split("alpha = ")[1].split()[0])
        assert S.a_alpha(f"bdf{k}") == pytest.approx(stated, abs=0.005)


def test_bad_input():
    with pytest.raises(InvalidInputError, match="n = 2"):
        S.stability_region("rk4", n=2)
    with pytest.raises(InvalidInputError, match="re ="):
        S.stability_region("rk4", re=(1.0, -1.0))
    with pytest.raises(InvalidInputError, match="zeta"):
        S.oscillator_response("rk4", [0.1], zeta=1.5)
    with pytest.raises(InvalidInputError, match="square"):
        S.step_matrices("rk4", np.zeros((2, 3)), 1.0)
    with pytest.raises(InvalidInputError, match="h\\[0\\]"):
        S.step_matrices("rk4", np.eye(2), -1.0)
    with pytest.raises(InvalidInputError, match="not finite"):
        S.step_matrices("rk4", np.array([[np.nan, 0], [0, 1]]), 1.0)
    with pytest.raises(NotApplicableError, match="multistep"):
        S.amplification_factor("bdf3", [0.1])
    with pytest.raises(NotApplicableError, match="second-order"):
        S.amplification_factor("euler_cromer", [0.1])
    with pytest.raises(NotApplicableError, match="even"):
        S.step_matrices("euler_cromer", np.eye(3), 0.1)
    with pytest.raises(mbdk.UnknownMethodError):
        S.spectral_radius("rk5", [0.1])


def test_pole_is_reported_as_infinite():
    # implicit Euler: R(z) = 1/(1 - z) has its pole at z = 1
    assert S.spectral_radius("implicit_euler", [1.0 + 0j])[0] == math.inf


def test_stability_study(tmp_path, root):
    import csv
    import stability
    summary = stability.run(tmp_path, quick=True)
    assert len(summary["figures"]) == 7 and all(f["path"].exists() and f["caption"]
                                                for f in summary["figures"])
    family = list(csv.DictReader(open(tmp_path / "alpha_family_spectra.csv")))
    # the compiled steps against the closed forms, every member, over Omega in [0.05, 100]
    assert all(float(r["max_diff_closed_form"]) < 1e-8 for r in family)
    rows = {r["method"]: r for r in csv.DictReader(open(tmp_path / "stability_intervals.csv"))}
    assert float(rows["rk4"]["real_interval_a"]) == pytest.approx(-2.785293563405282, abs=1e-9)
    assert float(rows["bdf5"]["A_alpha_deg"]) == pytest.approx(locus_angle(5), abs=1e-5)
    claims = list(csv.DictReader(open(tmp_path / "stability_book_claims.csv")))
    heun = next(r for r in claims if r["equation"] == "(4.29)")
    assert heun["verdict"] == "FLAG" and "2.0000000000" in heun["computed"]
    assert all(float(r["cpu_s"]) > 0 for r in claims)
    # section 6: the closed forms computed here independently (rk4's |R(3i)|, the trapezoidal
    # period error at Omega = 1, Euler-Cromer's unit radius, -rho_inf along a constraint), the
    # measured values beside them, and a CPU time on every row of its three tables
    spectra = list(csv.DictReader(open(tmp_path / "oscillator_spectra.csv")))
    osc = {(r["method"], float(r["Omega"])): r for r in spectra}
    r = osc[("rk4", 3.0)]
    z = 3j
    assert float(r["spectral_radius_cf"]) == pytest.approx(
        abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24), rel=1e-13)
    assert float(r["spectral_radius"]) == pytest.approx(float(r["spectral_radius_cf"]),
                                                        rel=1e-10)
    assert float(osc[("trapezoidal", 1.0)]["period_error"]) == pytest.approx(
        1 / (2 * math.atan(0.5)) - 1, abs=1e-9)
    assert float(osc[("euler_cromer", 1.5)]["spectral_radius"]) == pytest.approx(1.0, abs=1e-12)
    assert all(float(r["max_diff"]) < 1e-9 for r in spectra), \
        [(r["method"], r["Omega"]) for r in spectra if not float(r["max_diff"]) < 1e-9]
    pend = list(csv.DictReader(open(tmp_path / "pendulum_spectra.csv")))
    assert all(float(r["max_diff"]) < 1e-9 for r in pend)
    con = {(r["method"], r["formulation"]): r
           for r in csv.DictReader(open(tmp_path / "constrained_direction_spectra.csv"))}
    r = con[("generalized_alpha rho 0.8", "index3")]
    assert float(r["spectral_radius_cf"]) == pytest.approx(0.8, abs=1e-5)
    assert float(r["spectral_radius"]) == pytest.approx(0.8, abs=1e-3)
    assert con[("generalized_alpha rho 0.8", "augmented_lagrangian")]["roots"] == "none"
    for name in ("oscillator_spectra", "pendulum_spectra", "constrained_direction_spectra"):
        assert all(float(r["cpu_s"]) > 0 for r in csv.DictReader(open(tmp_path / f"{name}.csv")))
