"""studies/ch6_numbers.py: its verdicts on chapter 6's printed numbers, and its computed values
against references derived here from the definitions (never read from the study's output)."""
import csv
import math

import numpy as np
import pytest

import ch6_numbers

M = 1.35                                   # table 6.2 module (mm)
ALPHA = math.radians(20.0)                 # assumed pressure angle, as in the study


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    out = tmp_path_factory.mktemp("ch6")
    summary = ch6_numbers.run(out)
    with open(out / "ch6_numbers.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    by_item = {r["item"]: r for r in rows}
    assert len(by_item) == len(rows), "items must be unique"
    return {"rows": rows, "item": by_item, "summary": summary, "out": out}


def get(table, item, verdict):
    r = table["item"][item]
    assert r["verdict"] == verdict, (item, r["verdict"], r["reason"])
    return float(r["computed"]) if r["computed"] else None


def test_every_row_is_well_formed(table):
    for r in table["rows"]:
        assert r["verdict"] in ("correct", "WRONG", "notation", "derived"), r
        assert 3770 <= int(r["seed_line"]) <= 4254, r          # chapter 6 of the seed text
        if r["verdict"] != "notation":
            assert r["computed"] != "", r
        if r["verdict"] in ("WRONG", "notation"):
            assert r["reason"], r                                # a flag always says why
    assert sum(r["verdict"] == "WRONG" for r in table["rows"]) >= 15
    fig = table["summary"]["figures"][0]
    assert fig["caption"] and fig["path"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_table_6_2_gear_geometry(table):
    # module definitions: r = m z/2, r_tip = r + 1.0 m, r_root = r - 1.25 m, s = pi m/2
    assert get(table, "T6.2 tip radius z=80", "correct") == pytest.approx(40 * M + M)
    assert get(table, "T6.2 tip radius z=40", "correct") == pytest.approx(20 * M + M)
    assert get(table, "T6.2 root radius z=80", "correct") == pytest.approx(40 * M - 1.25 * M)
    assert get(table, "T6.2 root radius z=40", "correct") == pytest.approx(20 * M - 1.25 * M)
    assert get(table, "T6.2 tooth thickness", "correct") == pytest.approx(math.pi * M / 2)
    assert get(table, "T6.2 centre distance", "derived") == pytest.approx(60 * M)
    assert get(table, "T6.2 base radius z=40", "derived") == pytest.approx(27 * math.cos(ALPHA))
    # contact ratio: eps = (sqrt(ra1^2 - rb1^2) + sqrt(ra2^2 - rb2^2) - a sin(alpha)) / pb for
    # a 20 deg, 80/40-tooth, full-depth pair; about 1.77 (between the usual 1.4 and 2)
    ra, rb = np.array([55.35, 28.35]), np.array([54.0, 27.0]) * math.cos(ALPHA)
    eps = ((np.sqrt(ra ** 2 - rb ** 2).sum() - 81.0 * math.sin(ALPHA))
           / (math.pi * M * math.cos(ALPHA)))
    assert get(table, "T6.2 contact ratio", "derived") == pytest.approx(eps, rel=1e-9)
    assert 1.7 < eps < 1.8
    get(table, "T6.2 label 'Fogszélesség'", "notation")


def test_step_sizes(table):
    assert get(table, "6.1 step h = time/steps", "WRONG") == pytest.approx(0.1 / 1500)
    assert get(table, "6.2 step h = time/steps", "correct") == pytest.approx(1.5 / 1500)


def test_five_revolutions_cannot_happen(table):
    # work-energy: T theta1 = (I1 + I2 (z1/z2)^2) w1^2 / 2 with uniform acceleration from rest;
    # solid discs I = rho pi b r^4 / 2 at the pitch radii 54 and 27 mm
    disc = lambda r: 0.5 * 1250 * math.pi * 0.013 * r ** 4
    i_eq = disc(0.054) + 4 * disc(0.027)
    theta = 0.1 * 0.1 ** 2 / (2 * i_eq)
    revs = get(table, "6.1 five revolutions with 0.1 N m in 0.1 s", "WRONG")
    assert revs == pytest.approx(theta / (2 * math.pi), rel=1e-9)
    assert 0.25 < revs < 0.35
    torque = get(table, "6.1 torque for five revolutions in 0.1 s", "derived")
    assert torque == pytest.approx(0.1 * 5 / revs, rel=1e-9)        # theta scales with torque
    time = get(table, "6.1 time for five revolutions at 0.1 N m", "derived")
    assert time == pytest.approx(0.1 * math.sqrt(5 / revs), rel=1e-9)  # and with t^2
    assert get(table, "6.1 mean speed of five revolutions in 0.1 s", "derived") == 3000


def test_friction_steps(table):
    # mu_d = mu_s / 3 (conditions 1 and 4 exactly): 0.25/3 = 0.0833 -> 0.083, 0.2/3 -> 0.067
    assert get(table, "T6.3 mu_d = mu_s/3, condition 2", "correct") == pytest.approx(0.25 / 3)
    assert get(table, "T6.3 mu_d = mu_s/3, condition 3", "WRONG") == pytest.approx(0.2 / 3)
    for step, (a, b) in zip(("1->2", "2->3", "3->4"), ((0.3, 0.25), (0.25, 0.2), (0.2, 0.15))):
        red = get(table, f"T6.3 '15 %' step {step}", "WRONG")
        assert red == pytest.approx(100 * (a - b) / a)
        assert red > 16


def test_radius_r_of_6_6(table):
    # the printed expression collapses to r_tip of gear 1 (55.35 mm)
    assert get(table, "(6.6) R as printed", "WRONG") == pytest.approx(0.05535)
    assert get(table, "(6.6) R = h_a / 2", "WRONG") == pytest.approx(M / 2 / 1000)
    # whole depth (1 + 1.25) m, a quarter of it: 0.759 mm, the printed 7.6e-4 m
    assert get(table, "(6.6) what 7.6e-4 m is", "correct") == pytest.approx(2.25 * M / 4 / 1000)
    # mean |s| along the line of action, from where it crosses the two tip circles: the line
    # through the pitch point P (origin) at angle alpha, tangent to both base circles
    u = np.array([math.cos(ALPHA), math.sin(ALPHA)])        # direction of the line of action
    ends = []
    for centre, ra in ((np.array([0.0, -54.0]), 55.35), (np.array([0.0, 27.0]), 28.35)):
        # |s u - c|^2 = ra^2 -> s^2 - 2 s (u.c) + |c|^2 - ra^2 = 0
        roots = np.roots([1.0, -2 * u @ centre, centre @ centre - ra ** 2])
        ends.append(roots)
    lo = max(min(r) for r in ends)                          # contact needs both tips reached
    hi = min(max(r) for r in ends)
    s = np.linspace(lo, hi, 200001)
    mean_arm = np.abs(s).mean() / 1000
    assert get(table, "(6.6) R against involute kinematics", "WRONG") == pytest.approx(
        mean_arm, rel=1e-4)
    assert get(table, "(6.5) 2 pi in the sliding speed", "WRONG") == pytest.approx(2 * math.pi)


def test_psi_and_temperature(table):
    # (6.8) with table 6.4: a_x = 3e-10 m, t0 = 3e-12 s, Ea = 49e3 J/mol, Rg = 8.31, 293 K
    c = lambda t: 3e-10 / 3e-12 * math.exp(-49e3 / (8.31 * t))
    psi_max = -math.expm1(-c(293) / 0.01)                  # slowest speed of the range: largest psi
    assert get(table, "(6.9) psi range with table 6.4", "WRONG") == pytest.approx(psi_max, rel=1e-6)
    assert psi_max < 1e-4
    assert get(table, "(6.10) psi v is a constant", "derived") == pytest.approx(c(293), rel=1e-9)
    assert get(table, "T 25 C vs 20 C: '40 % more wear'", "correct") == pytest.approx(
        c(298) / c(293), rel=1e-9)
    assert get(table, "T 30 C vs 20 C: 'doubled'", "correct") == pytest.approx(
        c(303) / c(293), rel=1e-9)
    assert get(table, "'5 deg = 25 % temperature change'", "WRONG") == pytest.approx(500 / 293)
    assert get(table, "T6.4 Rg = 8.31", "correct") == pytest.approx(8.314462618)   # CODATA 2018
    assert get(table, "T6.4 k = 65e-5 mm^3/(N m)", "correct") == pytest.approx(6.5e-13)
    for item in ("T6.4 mu_s 'mozgásbéli'", "T6.4 dt 'szimulációs idő 0.1 s'"):
        get(table, item, "notation")


def test_table_6_7_polynomials(table):
    sr = np.poly1d([-0.111667, 0.3631732, 0.02378365, 1.137558])
    ftf = np.poly1d([0.7702, 0.554, 1.6244, 1.0311])
    # S/R' has its roots outside [0, 1.5], so the extremes are at the ends of the cycle
    assert all(abs(r.imag) > 0 or not 0 <= r.real <= 1.5 for r in sr.deriv().roots)
    assert get(table, "T6.7 S/R(t) minimum on [0, 1.5] s", "WRONG") == pytest.approx(sr(0.0))
    assert get(table, "T6.7 S/R(t) maximum on [0, 1.5] s", "WRONG") == pytest.approx(sr(1.5))
    assert sr(0.0) > 1                                      # outside the defined [0, 1]
    assert get(table, "T6.7 F_tf/BW at t = 1.5 s", "WRONG") == pytest.approx(ftf(1.5))
    assert get(table, "T6.7 F_tf/BW at t = 0", "derived") == pytest.approx(1.0311)
    # implied mean sliding speed: W = k mu_k BW v int F_tf/BW S/R dt, W = 14.4e-6 mm^3
    integral = (ftf * sr).integ()(1.5)
    v = 14.4e-6 / (1.3e-6 * 0.0575 * 800 * integral) * 1000         # mm/s
    assert get(table, "T6.8 PS 14.4e-6 mm^3/cycle via (6.11)", "derived") == pytest.approx(
        v, rel=1e-6)
    for item in ("(6.13) label dW_lateral", "T6.5 vs T6.7 mu_k label",
                 "T6.7 v_CTt in mm/s with k in mm^3/(N m)", "(6.11) BW F_tf(t)"):
        get(table, item, "notation")


def test_table_6_8_percentages(table):
    # "x % more than PS" takes PS's 14.4 as the base
    assert get(table, "T6.8 CR vs PS '23 % more'", "WRONG") == pytest.approx(100 * 4.3 / 14.4)
    assert get(table, "T6.8 Prototype vs PS '13.7 % more'", "WRONG") == pytest.approx(
        100 * 2.3 / 14.4)
    assert get(table, "T6.8 'only PS meets 5 %'", "correct") == 1
    # (6.17): WIB = 100 (r - 1)/(r + 1) with r = W_med/W_lat; WIB = 5.9 -> r = 105.9/94.1
    assert get(table, "WIB: definition vs (6.17), Prototype", "WRONG") == pytest.approx(
        100 * (105.9 / 94.1 - 1))
