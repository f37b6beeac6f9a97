"""Iterations that stop at what floating point allows (issue 36): every index-3 and DAE method
converges, or fails for a named reason, from h = 1e-2 down to 1e-6 (tolerances down to near
double precision), on every built-in scene, and shows its order down to the roundoff plateau;
the same on the BLAS kernel where the spatial Newton test used to fail (OPENBLAS_CORETYPE=
Prescott, checked in a subprocess on x86-64).

References: dopri54 at rtol 1e-13 on the projection formulation (an independent method and
formulation), or, for the A02 chain, the exact crank angle (mbdk.benchmarks.a02_crank)."""
from __future__ import annotations

import os
import platform
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import mbdk
from mbdk.scene_file import scene_from_dict

SPATIAL = ["heavy_top", "spatial_double_pendulum", "bricard", "flyball_governor"]
PLANAR = [n for n in mbdk.scenes() if n not in ("particle_in_ring", "pla_gears")]
T = 0.02


def _reference(sc, t_end):
    return mbdk.simulate(sc, "dopri54", formulation="projection", rtol=1e-13, atol=1e-15,
                         t_end=t_end, dt_out=t_end)


def _state_error(r, ref):
    return max(np.abs(r.q[-1] - ref.q[-1]).max(), np.abs(r.v[-1] - ref.v[-1]).max())


@pytest.mark.parametrize("name", SPATIAL)
def test_spatial_index3_converges_at_second_order_down_to_its_plateau(name):
    """Spatial trapezoidal_index3 from h = 1e-3 to 1e-6: the error falls 4-fold per halving
    where truncation dominates, down to h = 1e-6 (5000 steps to t = 5 ms), or stays at its
    roundoff plateau, instead of failing: with the old tolerances the spatial
    double pendulum and Bricard's linkage stopped at t = 0 for h <= 2e-4, the heavy top for
    h <= 5e-5, the flyball governor for h <= 3e-4."""
    sc = mbdk.scene(name)
    errs = {}
    for hs, t_end in (((1e-3, 5e-4, 2.5e-4), T), ((1e-5, 1e-6), 0.005)):
        ref = _reference(sc, t_end)
        for h in hs:
            r = mbdk.simulate(sc, "trapezoidal_index3", h=h, t_end=t_end,
                              every=round(t_end / h), outputs=("residuals",))
            assert r.success and r.t[-1] == pytest.approx(t_end)
            assert r.residuals[:, 0].max() < 1e-12           # the joints, at every h
            errs[h] = _state_error(r, ref)
    assert 3.5 < errs[1e-3] / errs[5e-4] < 4.5, errs
    assert 3.5 < errs[5e-4] / errs[2.5e-4] < 4.5, errs
    # at 5 ms the roundoff plateau lies near 1e-12 (Bricard, the spatial double pendulum) to
    # 1e-11 (the governor): from h = 1e-5 to 1e-6 the error still falls tenfold or more, or
    # has reached the plateau
    assert errs[1e-5] < 1e-8, errs
    assert errs[1e-6] < errs[1e-5] / 10 or errs[1e-6] < 1e-12, errs


def test_spatial_index3_small_steps_under_the_prescott_blas_kernel():
    """The failing case of the issue (the spatial double pendulum at h = 3.125e-4 stopped with
    NewtonDivergedError under OpenBLAS's SkylakeX and Prescott kernels, not under Haswell or
    Zen) and h = 1e-5, run in a fresh process with OPENBLAS_CORETYPE=Prescott."""
    if platform.machine() not in ("x86_64", "AMD64"):
        pytest.skip("OPENBLAS_CORETYPE=Prescott names an x86-64 kernel")
    code = textwrap.dedent("""
        import mbdk
        for h in (3.125e-4, 1e-5):
            r = mbdk.simulate(mbdk.scene("spatial_double_pendulum"), "trapezoidal_index3", h=h,
                              t_end=0.3 if h > 1e-4 else 0.01, outputs=("residuals",))
            assert r.success and r.residuals[:, 0].max() < 1e-12, h
        print("ok")
    """)
    # OPENBLAS_VERBOSE=2: OpenBLAS says which kernel it took ("Core: Prescott"); another BLAS,
    # or an OpenBLAS without the runtime choice, says nothing, and the case does not apply
    env = dict(os.environ, OPENBLAS_CORETYPE="Prescott", OPENBLAS_VERBOSE="2")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=600)
    if "Core: Prescott" not in out.stdout + out.stderr:
        pytest.skip("the BLAS did not take OpenBLAS's Prescott kernel")
    assert out.returncode == 0 and out.stdout.strip().endswith("ok"), out.stderr[-2000:]


@pytest.mark.parametrize("name", PLANAR)
@pytest.mark.parametrize("form", ["augmented_lagrangian", "index3"])
def test_planar_index3_runs_from_1e_2_to_1e_6(name, form):
    """Both forms of trapezoidal_index3 at every h from 1e-2 to 1e-6 on every built-in planar
    scene with joints: each run succeeds (or, the book's scheme on redundant joints, is refused
    by name), and the joints hold."""
    sc = mbdk.scene(name)
    for h in (1e-2, 1e-3, 1e-4, 1e-5, 1e-6):
        t_end = min(0.2, 2000 * h)
        try:
            r = mbdk.simulate(sc, "trapezoidal_index3", formulation=form, h=h, t_end=t_end,
                              every=round(t_end / h), outputs=("residuals",))
        except mbdk.RedundantConstraintsError:
            assert form == "index3" and name == "parallelogram_redundant"
            continue
        assert r.success and r.residuals[:, 0].max() < 1e-9, (h, r.residuals[:, 0].max())


DAE_CASES = [("bdf", "i3"), ("bdf", "si2"), ("ida", "index1"), ("ida", "ggl")]


@pytest.mark.parametrize("name", SPATIAL + ["double_pendulum", "four_bar", "trolley_crane",
                                            "spring_damper_bar", "three_link_pendulum"])
@pytest.mark.parametrize("method, form", DAE_CASES)
def test_dae_methods_converge_down_to_rtol_1e_11(name, method, form):
    """bdf on the i3 and si2 forms and ida on index1 and ggl at rtol 1e-6 to 1e-11 on the
    built-in mechanisms: every run succeeds and the error at 1e-11 is a thousandth of the one
    at 1e-6 or below 1e-9 (ida ggl at 1e-10 and 1e-11 stopped with NewtonDivergedError on the
    flyball governor: its multipliers were tested below the index-2 iteration's roundoff)."""
    sc = mbdk.scene(name)
    t_end = 0.3
    ref = _reference(sc, t_end)
    errs = []
    for tol in (1e-6, 1e-8, 1e-10, 1e-11):
        r = mbdk.simulate(sc, method, formulation=form, rtol=tol, atol=1e-2 * tol, t_end=t_end,
                          dt_out=t_end, outputs=())
        assert r.success
        errs.append(_state_error(r, ref))
    assert errs[-1] < 1e-3 * errs[0] or errs[-1] < 1e-9, errs


@pytest.mark.parametrize("name", ["double_pendulum", "four_bar", "bricard", "flyball_governor"])
def test_bdf_on_the_dae_names_tolerances_beyond_double_precision(name):
    """bdf on the DAE at rtol 1e-13, atol 1e-15: where its corrector stalls at the roundoff
    floor of its update the run ends with TooMuchAccuracyError (the cause), not with a step
    shrinking to nothing (StepTooSmallError, as before) or a wrong result; i3 and si2 at
    rtol 1e-11 run (at 1e-12 they run too, at step counts that differ with the BLAS kernel:
    the edge of what double precision allows)."""
    sc = mbdk.scene(name)
    for form in ("i3", "si2"):
        assert mbdk.simulate(sc, "bdf", formulation=form, rtol=1e-11, atol=1e-13, t_end=0.3,
                             dt_out=0.1, outputs=()).success
    outcomes = set()
    for form in ("i3", "si2"):
        try:
            mbdk.simulate(sc, "bdf", formulation=form, rtol=1e-13, atol=1e-15, t_end=0.3,
                          dt_out=0.1, outputs=())
            outcomes.add("ran")
        except mbdk.TooMuchAccuracyError as exc:
            assert "double precision" in str(exc)
            outcomes.add("named")
    assert "named" in outcomes


def test_implicit_newton_stops_at_its_floor():
    """The implicit ODE methods' Newton asked for 1e-18 (below eps |y|): it stops at the
    update's roundoff floor instead of failing (NewtonDivergedError before), and the result is
    the one at the default tolerance to roundoff."""
    sc = mbdk.scene("double_pendulum")
    runs = [mbdk.simulate(sc, "trapezoidal", h=1e-3, t_end=1.0, outputs=(), **kw)
            for kw in ({}, {"newton_rtol": 1e-18, "newton_atol": 1e-20})]
    assert all(r.success for r in runs)
    assert np.abs(runs[0].q[-1] - runs[1].q[-1]).max() < 1e-9


@pytest.mark.parametrize("name", ["heavy_top", "flyball_governor", "double_pendulum"])
def test_projection_under_error_control_follows_atol(name):
    """bdf with the projection formulation at rtol 1e-10, atol 1e-12: the projection's leftover
    |Phi| is a thousandth of atol by default (it was 1e-12 = atol, and bdf's history took the
    leftover into its error estimate: StepTooSmallError on the heavy top), and the error
    against the reference is of the tolerance's order."""
    sc = mbdk.scene(name)
    ref = _reference(sc, 1.0)
    r = mbdk.simulate(sc, "bdf", formulation="projection", rtol=1e-10, atol=1e-12, t_end=1.0,
                      dt_out=1.0, outputs=())
    assert r.manifest["projection_tol"] == pytest.approx(1e-15)
    assert _state_error(r, ref) < 1e-6
    given = mbdk.simulate(sc, "bdf", formulation="projection", rtol=1e-6, atol=1e-8, t_end=0.1,
                          dt_out=0.1, outputs=(), projection_tol=1e-9)
    assert given.manifest["projection_tol"] == 1e-9


def _slider_crank(omega):
    return scene_from_dict({
        "scene": {"name": "slider_crank", "description": "crank 0.1 m, rod 0.3 m, slider"},
        "body": [
            {"name": "crank", "mass": 0.2, "shape": {"type": "bar", "length": 0.1},
             "x": 0.035355339, "y": 0.035355339, "angle_deg": 45.0, "omega": omega,
             "given": ["angle", "omega"]},
            {"name": "rod", "mass": 0.5, "shape": {"type": "bar", "length": 0.3},
             "x": 0.2, "y": 0.035, "angle_deg": -14.0},
            {"name": "slider", "mass": 1.0, "shape": {"type": "rectangle", "width": 0.05,
                                                      "height": 0.03}, "x": 0.35, "y": 0.0}],
        "joint": [
            {"name": "O", "type": "revolute", "body1": "crank", "point1": [-0.05, 0.0]},
            {"name": "A", "type": "revolute", "body1": "rod", "point1": [-0.15, 0.0],
             "body2": "crank", "point2": [0.05, 0.0]},
            {"name": "B", "type": "revolute", "body1": "rod", "point1": [0.15, 0.0],
             "body2": "slider", "point2": [0.0, 0.0]},
            {"name": "slide", "type": "prismatic", "body1": "slider", "body2": "ground",
             "axis": [1.0, 0.0]}],
        "force": [{"type": "gravity", "g": [0.0, -9.81]}]})


def test_ida_ggl_starts_a_slider_crank_turning_at_10_rad_s():
    """ida's GGL form tests its start's velocity rows against the largest row's terms: a
    slider-crank whose crank turns at 10 rad/s was refused ("does not satisfy the constraints
    ... keep assemble_initial=True") although its assembled residuals were 1e-16, because the
    slider's rows have no terms of their own. It runs now, and agrees with bdf's si2 form and
    ida's index1 form."""
    sc = _slider_crank(10.0)
    runs = {(m, f): mbdk.simulate(sc, m, formulation=f, rtol=1e-9, atol=1e-11, t_end=0.5,
                                  dt_out=0.5)
            for m, f in (("ida", "ggl"), ("ida", "index1"), ("bdf", "si2"))}
    q = {k: r.q[-1] for k, r in runs.items()}
    assert np.abs(q[("ida", "ggl")] - q[("bdf", "si2")]).max() < 1e-6
    assert np.abs(q[("ida", "ggl")] - q[("ida", "index1")]).max() < 1e-6


def _rssr():
    """A spatial RSSR four-bar (crank about z at the origin, coupler on two spherical joints,
    rocker about x), its coupler's frame along the line of its joints, released from rest."""
    a, p = np.array([0.1, 0.0, 0.0]), np.array([0.25, 0.15, 0.05])
    b = p + np.array([0.0, 0.0, 0.12])
    ex = (b - a) / np.linalg.norm(b - a)
    ez = np.cross(ex, [0.0, 1.0, 0.0])
    ez /= np.linalg.norm(ez)
    rot = np.column_stack([ex, np.cross(ez, ex), ez])
    from mbdk.rotations import to_quaternion
    quat = [float(c) for c in to_quaternion(rot)]
    length2 = float(np.sum((b - a) ** 2))
    return scene_from_dict({
        "scene": {"name": "rssr", "rotation": "quaternion",
                  "description": "a spatial RSSR four-bar released from rest"},
        "body": [
            {"name": "crank", "kind": "spatial", "mass": 0.5, "inertia": [1e-5, 5e-4, 5e-4],
             "position": [0.05, 0.0, 0.0], "quaternion": [1.0, 0.0, 0.0, 0.0]},
            {"name": "coupler", "kind": "spatial", "mass": 1.0,
             "inertia": [2e-4, length2 / 12, length2 / 12],
             "position": [float(c) for c in (a + b) / 2], "quaternion": quat},
            {"name": "rocker", "kind": "spatial", "mass": 0.8, "inertia": [1e-3, 1e-3, 1e-5],
             "position": [0.25, 0.15, 0.11], "quaternion": [1.0, 0.0, 0.0, 0.0]}],
        "joint": [
            {"name": "R1", "type": "revolute", "body1": "crank", "at": [0.0, 0.0, 0.0],
             "axis": [0.0, 0.0, 1.0]},
            {"name": "S1", "type": "spherical", "body1": "coupler", "body2": "crank",
             "at": [float(c) for c in a]},
            {"name": "S2", "type": "spherical", "body1": "coupler", "body2": "rocker",
             "at": [float(c) for c in b]},
            {"name": "R2", "type": "revolute", "body1": "rocker", "at": [float(c) for c in p],
             "axis": [1.0, 0.0, 0.0]}],
        "force": [{"type": "gravity", "g": [0.0, -9.81, -3.0]}]})


def test_spatial_index3_on_an_rssr_loop():
    """The issue's closed loop: trapezoidal_index3 on a spatial RSSR four-bar failed near
    0.67 s at h = 1e-3 and at 0.05 s at h = 5e-4 (a smaller step failed sooner). It runs 1 s
    at h = 1e-3, 5e-4 and 2.5e-4, second order against dopri54 (rtol 1e-12, projection)."""
    sc = _rssr()
    ref = mbdk.simulate(sc, "dopri54", formulation="projection", rtol=1e-12, atol=1e-14,
                        t_end=1.0, dt_out=1.0)
    errs = []
    for h in (1e-3, 5e-4, 2.5e-4):
        r = mbdk.simulate(sc, "trapezoidal_index3", h=h, t_end=1.0, every=round(1.0 / h),
                          outputs=("residuals",))
        assert r.success and r.residuals[:, 0].max() < 1e-12
        errs.append(_state_error(r, ref))
    assert 3.5 < errs[0] / errs[1] < 4.5 and 3.5 < errs[1] / errs[2] < 4.5, errs
