"""The symbolic cross-check (mbdk.symbolic, mbdk.symbolic_spatial, issue 23): SymPy derives
each scene's Phi, D, gamma, Phi_t and loads from the elements' definitions, and the reduced
accelerations from [M D^T; D 0]; the compiled assembly must agree at random states to roundoff,
on every built-in scene and on one scene of each constraint kind. A wrong row is caught; the
book's printed matrices that differ from their derivation are exactly the ones the study
flags."""
import sys

import numpy as np
import pytest

import mbdk
from mbdk import symbolic
from mbdk.scene_file import scene_from_dict

#: roundoff bounds of the accelerations: the parallelogram's rows are redundant on the manifold
#: and nearly so beside it (a near-singular solve); Bricard's linkage likewise
ACCEL_TOL = {"parallelogram_redundant": 1e-9, "bricard": 1e-11}


@pytest.mark.parametrize("name", mbdk.scenes("all"))
def test_every_built_in_scene_agrees_with_its_derivation(name):
    r = symbolic.cross_check(mbdk.scene(name), states=3)
    for k in ("phi", "D", "gamma", "phit"):
        assert r[k] < 1e-13, (k, r[k])
    if r["f"] is not None:
        assert r["f"] < 1e-13
    assert r["a"] < ACCEL_TOL.get(name, 1e-12)
    if r["lam"] is not None:
        assert r["lam"] < ACCEL_TOL.get(name, 1e-12)
    assert r["f_from_kernel"] == (name in ("pla_gears", "particle_in_ring"))


def kinds():
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[1] / "studies"))
    import symbolic_check
    return symbolic_check.kind_scenes()


@pytest.mark.parametrize("label", sorted(kinds()))
def test_every_constraint_kind_agrees_with_its_derivation(label):
    """The knife edge (a velocity row: A from d(A v)/dv, gamma from d(A v)/dt), point on a line
    and on a curve, couplings, rolling, distance with L(t)."""
    r = symbolic.cross_check(kinds()[label], states=3)
    for k in ("phi", "D", "gamma", "phit", "f", "a", "lam"):
        assert r[k] < 1e-13, (k, r[k])


def test_a_wrong_row_is_caught(monkeypatch):
    """cross_check of the four-bar with SymPy handed the derivation of a four-bar whose coupler
    is 1 mm longer: Phi differs by the millimetre, D and gamma by its share; the comparison
    could fail."""
    from mbdk.scene_file import scene_to_dict
    sc = mbdk.scene("four_bar")
    wrong = scene_from_dict(scene_to_dict(sc), "wrong.toml")
    j = wrong.joints[1]
    j.point1 = (j.point1[0] + 1e-3 * np.sign(j.point1[0] or 1.0), j.point1[1])
    derive = symbolic.derive
    monkeypatch.setattr(symbolic, "derive", lambda _sc, q0=None: derive(wrong, q0))
    r = symbolic.cross_check(sc, states=3)
    assert r["phi"] > 1e-4 and r["D"] > 1e-4 and r["a"] > 1e-4


def test_the_book_matrices_that_differ_from_their_derivation(root):
    """(2.27) puts gravity in the x rows (rows 1, 2, 4, 5 differ), (2.145) gives x2 and y2 the
    trolley's mass, (2.146)'s D^T is not the transpose of its D, and (2.151) drops gamma's
    first minus sign; (2.31)-(2.33), (2.150), the matrix of (2.151) and the reduced
    accelerations (3.64) agree."""
    sys.path.insert(0, str(root / "studies"))
    import symbolic_check
    rows = symbolic_check.book_items()
    wrong = {(r["equation"], r["item"]) for r in rows if r["verdict"] == "WRONG"}
    assert wrong == {("(2.27)", f"Newton-Euler right-hand sides row {k}") for k in (1, 2, 4, 5)} | {
        ("(2.145)", "M [2, 2]"), ("(2.145)", "M [3, 3]"), ("(2.146)", "D^T [2, 2]"),
        ("(2.151)", "right-hand side [f; gamma] row 5")}
    ok = {r["equation"] for r in rows if r["verdict"] == "OK"}
    assert {"(2.31)", "(2.32)", "(2.33)", "(2.150)", "(2.151)", "(3.64)"} <= ok
    assert all(r["why"] for r in rows if r["verdict"] == "WRONG")


def test_spatial_drivers_agree_with_their_derivation():
    """The spatial drivers, which no built-in scene has: a slider driven along an inclined
    prismatic guide and a crank driven about its hinge (rheonomic rows: Phi_t, and gamma with
    C_t w and Phi_tt)."""
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
    from test_spatial import _driven_crank, _driven_slider
    for sc in (_driven_slider(), _driven_crank(rate=0.7, amplitude=0.4)):
        r = symbolic.cross_check(sc, states=3)
        for k in ("phi", "D", "gamma", "phit"):
            assert r[k] < 1e-13, (sc.source, k, r[k])
        assert r["a"] < 1e-12


def test_a_slide_driver_between_moving_bodies_agrees_with_its_derivation():
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
    from test_spatial import _slide_between_moving_bodies
    r = symbolic.cross_check(_slide_between_moving_bodies(), states=3)
    for k in ("phi", "D", "gamma", "phit"):
        assert r[k] < 1e-13, (k, r[k])
    assert r["a"] < 1e-12
