"""Planar scenes: kernel assembly against finite differences, the textbook ODEs, free-body
balances, drift, redundancy, stiffness, assembly and bad scenes.

References: the compiled textbook problems (pendulum (4.69), trolley_crane with coupling = +1,
double_pendulum (3.64)), derived independently by Lagrange's equations in minimal coordinates
(tests/test_problems.py checks them against the book); finite differences of the kernel's own
Phi; Newton-Euler free-body equations written out here.
"""
import math

import numpy as np
import pytest

import mbdk
from mbdk import model as M
from mbdk.scene_file import scene_from_dict

ALL = mbdk.scenes()


def state(name, seed=1):
    sc = mbdk.scene(name)
    tab = M.build_tables(sc)
    q, v, _ = M.assemble(sc, tab)
    rng = np.random.default_rng(seed)
    return sc, tab, q, v + rng.normal(0, 0.7, v.size)


@pytest.mark.parametrize("name", ALL)
def test_jacobian_and_gamma_against_finite_differences(name):
    sc, tab, q, v = state(name)
    if tab.m == 0:
        pytest.skip(f"{name} has no joints: no D or gamma to check")
    q = q + np.random.default_rng(3).normal(0, 0.05, q.size)   # off the manifold on purpose
    e = M.evaluate(tab, q, v, 0.3)
    eps = 1e-6
    dfd = np.zeros_like(e["D"])
    for k in range(q.size):
        dq = np.zeros(q.size)
        dq[k] = eps
        dfd[:, k] = (M.evaluate(tab, q + dq, v, 0.3)["phi"] - M.evaluate(tab, q - dq, v, 0.3)["phi"]) / (2 * eps)
    assert np.max(np.abs(dfd - e["D"])) < 1e-8
    # gamma = -(dD/dt) v - Phi_tt, with dD/dt v from D along the motion
    dd = (M.evaluate(tab, q + eps * v, v, 0.3)["D"] - M.evaluate(tab, q - eps * v, v, 0.3)["D"]) / (2 * eps)
    assert np.max(np.abs(e["gamma"] + dd @ v)) < 1e-6 * max(1, np.abs(e["gamma"]).max())


def _every_joint_type():
    """A prismatic joint between two moving bodies, a fixed joint and a rheonomic driver."""
    return {
        "body": [
            {"name": "a", "mass": 2.0, "inertia": 0.3, "x": 0.1, "y": 0.2, "angle": 0.4},
            {"name": "b", "mass": 1.0, "inertia": 0.1, "x": 0.9, "y": 0.5, "angle": 0.7},
            {"name": "c", "mass": 1.0, "inertia": 0.1, "x": 1.5, "y": 0.1, "angle": -0.2},
        ],
        "joint": [
            {"name": "p", "type": "prismatic", "body1": "b", "point1": [0.1, 0.05], "body2": "a",
             "point2": [0.2, -0.1], "axis": [0.6, 0.8]},
            {"name": "f", "type": "fixed", "body1": "c", "point1": [0.0, 0.3], "body2": "b"},
            {"name": "d", "type": "driver", "body1": "a", "coordinate": "angle",
             "function": {"offset": 0.4, "rate": 0.5, "amplitude": 0.2, "omega": 3.0}},
        ],
    }


def test_prismatic_fixed_and_driver_rows_against_finite_differences():
    sc = scene_from_dict(_every_joint_type(), "inline.toml")
    tab = M.build_tables(sc)
    rng = np.random.default_rng(5)
    q = np.array(sc.q0()) + rng.normal(0, 0.1, 9)
    v = rng.normal(0, 1, 9)
    t, eps = 0.7, 1e-6
    e = M.evaluate(tab, q, v, t)
    dfd = np.column_stack([(M.evaluate(tab, q + eps * np.eye(9)[k], v, t)["phi"]
                            - M.evaluate(tab, q - eps * np.eye(9)[k], v, t)["phi"]) / (2 * eps)
                           for k in range(9)])
    assert np.max(np.abs(dfd - e["D"])) < 1e-8
    phit = (M.evaluate(tab, q, v, t + eps)["phi"] - M.evaluate(tab, q, v, t - eps)["phi"]) / (2 * eps)
    assert np.max(np.abs(phit - e["phit"])) < 1e-8
    # Phi'' along q(t) = q + v t', evaluated by second differences, equals D*0 - gamma (a = 0)
    h = 1e-4
    p = [M.evaluate(tab, q + s * h * v, v, t + s * h)["phi"] for s in (-1, 0, 1)]
    phidd = (p[2] - 2 * p[1] + p[0]) / h ** 2
    assert np.max(np.abs(phidd + e["gamma"])) < 1e-5


def _minimal_check(name, problem, to_minimal, params=None):
    sc, tab, q, v = state(name)
    e = M.evaluate(tab, q, v)
    y, idx = to_minimal(q, v)
    f = mbdk.evaluate_rhs(problem, 0.0, y, params)
    n = len(y) // 2
    assert np.max(np.abs(e["a"][idx] - f[n:])) < 1e-9 * max(1, np.abs(f[n:]).max())


def test_pendulum_matches_the_textbook_ode():
    # angle = phi - 90 deg; the textbook pendulum is phi'' = -(3g/2l) sin phi
    _minimal_check("physical_pendulum", "pendulum",
                   lambda q, v: (np.array([q[2] + math.pi / 2, v[2]]), [2]))


def test_double_pendulum_matches_the_textbook_ode():
    _minimal_check("double_pendulum", "double_pendulum",
                   lambda q, v: (np.array([q[2], q[5], v[2], v[5]]), [2, 5]))


def test_trolley_crane_matches_the_consistent_textbook_ode():
    # the scene is the consistent mechanism (coupling = +1); the book's printed (4.78) is not
    _minimal_check("trolley_crane", "trolley_crane",
                   lambda q, v: (np.array([q[0], q[5], v[0], v[5]]), [0, 5]),
                   {"coupling": 1.0})


def test_physical_pendulum_multipliers_closed_form():
    """Hinge force of a bar pendulum (Newton-Euler about the hinge, cf. (3.49)-(3.50)):
    radial m (l/2) phi'^2 + m g cos phi, tangential m g sin phi / 4 (for I = m l^2/12)."""
    sc = mbdk.scene("physical_pendulum")
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0, every=50)
    phi = r.q[:, 2] + math.pi / 2
    w = r.v[:, 2]
    g, m, l = 9.81, 1.0, 1.0
    # reaction on the bar in global components: along the bar towards the hinge and tangential
    e_r = np.column_stack([np.sin(phi), -np.cos(phi)])      # hinge -> centroid
    e_t = np.column_stack([np.cos(phi), np.sin(phi)])       # direction of increasing phi
    R = r.reaction("hinge")[:, :2]
    radial = -np.sum(R * e_r, axis=1)
    tangential = np.sum(R * e_t, axis=1)
    assert np.allclose(radial, m * l / 2 * w ** 2 + m * g * np.cos(phi), atol=1e-9)
    assert np.allclose(tangential, m * g * np.sin(phi) / 4, atol=1e-9)
    assert np.allclose(r.reaction("hinge")[:, 2], 0, atol=1e-12)    # a revolute takes no moment


@pytest.mark.parametrize("name", ["double_pendulum", "four_bar", "three_link_pendulum",
                                  "trolley_crane", "spring_damper_bar"])
def test_reactions_close_every_free_body(name):
    """m a = m g + sum of the joint forces (+ force elements); I alpha = their moments: the
    reactions are the forces the joints exert on body1, and minus them on body2."""
    sc = mbdk.scene(name)
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.5, every=100)
    tab = M.build_tables(sc, r.q[0])
    for k in range(len(r.t)):
        q, v = r.q[k], r.v[k]
        f_elem = M.evaluate(tab, q, v, r.t[k])["f"]     # gravity and force elements
        total = f_elem.copy()
        for jn, j in enumerate(sc.joints):
            F = r.reactions[k, jn]
            for body, point, sign in ((j.body1, j.point1, 1.0), (j.body2, j.point2, -1.0)):
                if body == "ground":
                    continue
                i = sc.body_index(body) - 1
                c, s = math.cos(q[3 * i + 2]), math.sin(q[3 * i + 2])
                # the joint point: body1's point (the prismatic force acts there too)
                i1 = sc.body_index(j.body1) - 1
                c1, s1 = math.cos(q[3 * i1 + 2]), math.sin(q[3 * i1 + 2])
                p = q[3 * i1:3 * i1 + 2] + np.array([c1 * j.point1[0] - s1 * j.point1[1],
                                                     s1 * j.point1[0] + c1 * j.point1[1]])
                rho = p - q[3 * i:3 * i + 2]
                total[3 * i:3 * i + 2] += sign * F[:2]
                total[3 * i + 2] += sign * (rho[0] * F[1] - rho[1] * F[0] + F[2])
                del c, s
        mass = np.repeat(tab.mass, 3)
        mass[2::3] = tab.inertia
        assert np.max(np.abs(mass * r.a[k] - total)) < 1e-8 * max(1, np.abs(total).max())


def test_drift_grows_without_stabilisation_and_stays_bounded_with_it():
    sc = mbdk.scene("double_pendulum")
    kw = dict(h=2e-3, t_end=100.0, every=500)
    red = mbdk.simulate(sc, "rk4", formulation="reduced", **kw)
    bau = mbdk.simulate(sc, "rk4", formulation="baumgarte", **kw)
    pro = mbdk.simulate(sc, "rk4", formulation="projection", **kw)
    pen = mbdk.simulate(sc, "rk4", formulation="penalty", **kw)
    early = red.residuals[red.t <= 10, 0].max()
    late = red.residuals[red.t >= 90, 0].max()
    assert late > 10 * early                          # drift grows
    assert bau.residuals[:, 0].max() < 1e-6           # Baumgarte (alpha = 1/h, beta = sqrt2/h)
    assert pro.residuals[:, 0].max() < 1e-11          # projection: to its tolerance
    assert pro.residuals[:, 1].max() < 1e-11
    assert pen.residuals[:, 0].max() < 1e-5
    assert red.residuals[:, 0].max() > bau.residuals[:, 0].max()


def test_redundant_constraint_is_reported_and_penalty_handles_it():
    sc = mbdk.scene("parallelogram_redundant")
    with pytest.raises(mbdk.RedundantConstraintsError, match="dependent .redundant.*rank 11 < 12"):
        mbdk.simulate(sc, "rk4", formulation="reduced", h=1e-3, t_end=0.1)
    r = mbdk.simulate(sc, "rk4", formulation="penalty", h=1e-3, t_end=5.0, every=100)
    assert r.residuals[:, 0].max() < 1e-5
    assert np.abs(r.energy_balance()).max() < 1e-3 * r.energy_parts["kinetic"].max()


def test_stiff_spring_explicit_blows_up_implicit_stays_bounded():
    """s = 3e6 N/m on the trolley: omega = sqrt(3e6 / 11) = 522 rad/s, so rk4 needs h < 2.785 /
    522 = 5.3e-3 (its real-axis limit; the mode is nearly undamped, the limit 2 sqrt 2 / 522
    applies). At h = 0.01 it blows up; the implicit methods stay bounded (the trolley starts at
    the spring's rest, the stiff mode is only excited by the swinging bar). What is checked is
    boundedness: the reduced formulation's drift at h = 0.01 (1 cm by t = 0.3 s with implicit
    Euler, which the watch would stop) is not, so the implicit runs are not watched."""
    sc = mbdk.scene("trolley_crane")
    sc.forces[0].stiffness = 3e6
    sc.bodies[0].x = 0.0
    sc.bodies[1].x = 0.5 * math.cos(-math.pi / 6)
    with pytest.raises((mbdk.EnergyDriftError, mbdk.NonFiniteSolutionError)):
        mbdk.simulate(sc, "rk4", h=0.01, t_end=5.0)
    for m in ["implicit_euler", "trapezoidal", "bdf2"]:
        r = mbdk.simulate(sc, m, h=0.01, t_end=5.0, startup="bdf", watch=False)
        assert np.abs(r.q[:, 0]).max() < 1e-5         # the stiff spring barely moves
        assert np.abs(r.q[:, 5]).max() < math.pi       # the bar swings, it does not spin


def test_inconsistent_initial_conditions_are_assembled():
    sc = mbdk.scene("double_pendulum")
    sc.bodies[1].x += 0.1
    sc.bodies[1].vy = 3.0
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01)
    assert r.assembly["moved_q"] == pytest.approx(0.1, abs=1e-9)
    assert "bar2.x" in r.assembly["changes"] and "bar2.vy" in r.assembly["changes"]
    assert r.residuals[0, 0] < 1e-12 and r.residuals[0, 1] < 1e-12
    # the given angles are kept
    assert r.q[0, 5] == pytest.approx(-1.57, abs=1e-15)


def test_impossible_assembly_names_the_joints():
    sc = mbdk.scene("four_bar")
    sc.joints[3].point2 = (5.0, 0.0)     # the rocker's ground pivot out of reach
    with pytest.raises(mbdk.SceneError, match="cannot be assembled.*joint"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01)


def test_absent_effects_are_never_visited():
    """Visits count every pass over an element: with outputs=() exactly the 4 evaluations of
    each of the 100 rk4 steps; the default outputs add, at each of the 101 samples, one
    evaluation (accelerations, multipliers) and one pass over the joints for D (residuals,
    reactions, constraint power). Elements a scene lacks are never visited."""
    r = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-3, t_end=0.1, outputs=())
    assert r.visits["revolute"] == 2 * 4 * 100 and r.visits["gravity"] == 4 * 100
    for k in ["prismatic", "fixed", "driver", "point_force", "torque", "spring_damper",
              "coordinate_spring_damper", "spring", "damper"]:
        assert r.visits[k] == 0
    r = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-3, t_end=0.1)
    assert r.visits["revolute"] == 2 * 4 * 100 + 2 * 2 * 101
    assert r.visits["gravity"] == 4 * 100 + 101
    # the bar's spring and its damper are kinds of their own: each visited once per evaluation
    r = mbdk.simulate(mbdk.scene("spring_damper_bar"), "rk4", h=1e-3, t_end=0.1, outputs=())
    assert r.visits["spring"] == 4 * 100 and r.visits["damper"] == 4 * 100
    assert r.visits["spring_damper"] == 0


@pytest.mark.parametrize("method", list(mbdk.methods("ode", step="fixed")))
@pytest.mark.parametrize("formulation", ["reduced", "baumgarte", "penalty", "projection"])
def test_every_integrator_on_every_formulation(method, formulation):
    sc = mbdk.scene("physical_pendulum")
    ref = mbdk.solve_ode("pendulum", "rk4", h=1e-4, t_end=0.5)
    kw = {}
    if formulation == "baumgarte" and mbdk.stability.spectral_radius(method, [-1 + 1j])[0] > 1 + 1e-9:
        # the book's defaults alpha = 1/h, beta = sqrt2/h put the constraint error's roots at
        # h lambda = -1 +- i; where that lies outside the method's stability region (the
        # stability module says so for euler_cromer and bdf6) the run must fail
        assert method in ("euler_cromer", "bdf6")
        # named where the constraint error starts to grow (the watch), or where it overflows
        with pytest.raises((mbdk.ConstraintDriftError, mbdk.NonFiniteSolutionError,
                            mbdk.NewtonDivergedError)):
            mbdk.simulate(sc, method, formulation=formulation, h=1e-3, t_end=0.5)
        kw = dict(alpha=5.0, beta=5.0)     # Baumgarte's own suggestion, (3.30)
    r = mbdk.simulate(sc, method, formulation=formulation, h=1e-3, t_end=0.5, **kw)
    order = mbdk.methods()[method].order
    tol = {1: 0.05, 2: 2e-4}.get(order, 1e-5)
    assert abs(r.q[-1, 2] + math.pi / 2 - ref.y[-1, 0]) < tol


@pytest.mark.parametrize("formulation", ["reduced", "baumgarte"])
@pytest.mark.parametrize("name", ["four_bar", "every_joint_type"])
def test_linear_solvers_agree(name, formulation):
    """The Schur complement assembled from the nonzeros of D and factorised by joint blocks
    (in-house, small_dense) or by the general dense Cholesky, and (every joint revolute) the
    closed-form 2 x 2 blocks of mbdk_revolute_schur, against the dense LU of the KKT matrix: 2-row
    (revolute, prismatic), 3-row (fixed) and 1-row (driver) pivot blocks, off the constraint
    manifold (so that Baumgarte's D v and Phi terms count)."""
    if name == "every_joint_type":
        sc = scene_from_dict(_every_joint_type(), "inline.toml")
        tab = M.build_tables(sc)
        rng = np.random.default_rng(5)
        q = np.array(sc.q0()) + rng.normal(0, 0.1, 9)
        v = rng.normal(0, 1, 9)
    else:
        sc, tab, q, v = state(name)
        q = q + np.random.default_rng(2).normal(0, 0.01, q.size)
    runs = [("schur", True), ("schur", False), ("kkt", True), ("kkt", False)]
    if name == "four_bar":
        runs.append(("revolute_schur", True))
    outs = []
    for solver, small in runs:
        e = M.evaluate(tab, q, v, 0.7, formulation,
                       M.model_options(solver=solver, small_dense=small, alpha=3.0, beta=4.0))
        assert e["status"] == mbdk.Status.SUCCESS
        assert e["solve"].startswith(solver)      # the path asked for is the one taken
        outs.append(np.concatenate([e["a"], e["lam"]]))
    for o in outs[1:]:
        assert np.max(np.abs(o - outs[0])) < 1e-9 * np.abs(outs[0]).max()
    # and the KKT equations themselves
    e = M.evaluate(tab, q, v, 0.7, formulation, M.model_options(alpha=3.0, beta=4.0))
    mass = np.repeat(tab.mass, 3)
    mass[2::3] = tab.inertia
    assert np.max(np.abs(mass * e["a"] + e["D"].T @ e["lam"] - e["f"])) < 1e-9 * max(
        np.abs(e["f"]).max(), np.abs(e["D"].T @ e["lam"]).max())
    # the closed form takes revolute joints only: the kernel refuses the others
    if name == "every_joint_type":
        e = M.evaluate(tab, q, v, 0.7, formulation, M.model_options(solver="revolute_schur"))
        assert e["status"] == mbdk.Status.ERR_INVALID_INPUT


def _all_revolute(sc):
    return all(j.type == "revolute" for j in sc.joints)


def _plate_with_two_bars():
    """A plate hinged to the ground with a bar hinged at each lower corner: three joints on one
    body, so every block of S couples (the chains of the built-in scenes give a block
    tridiagonal S, whose elimination never updates an off-diagonal block)."""
    return {
        "body": [
            {"name": "plate", "mass": 3.0, "inertia": 0.4, "x": 0.0, "y": 0.0, "angle": 0.0,
             "omega": 1.5},
            {"name": "u", "mass": 1.0, "shape": {"type": "bar", "length": 0.5}, "x": -0.4,
             "y": -0.45, "angle": 0.0, "omega": -2.0},
            {"name": "w", "mass": 0.7, "shape": {"type": "bar", "length": 0.5}, "x": 0.4,
             "y": -0.45, "angle": 0.0, "omega": 3.0},
        ],
        "joint": [
            {"name": "left", "type": "revolute", "body1": "u", "point1": [0.0, 0.25],
             "body2": "plate", "point2": [-0.4, -0.2]},
            {"name": "top", "type": "revolute", "body1": "plate", "point1": [0.0, 0.3],
             "point2": [0.0, 0.3]},
            {"name": "right", "type": "revolute", "body1": "w", "point1": [0.0, 0.25],
             "body2": "plate", "point2": [0.4, -0.2]},
        ],
        "force": [{"type": "gravity", "g": [0.0, -9.81]}],
    }


def test_auto_solver_takes_the_closed_form_exactly_when_every_joint_is_revolute():
    taken = set()
    for name in ALL:
        sc, tab, q, v = state(name)
        e = M.evaluate(tab, q, v)
        closed = _all_revolute(sc) and tab.m > 0 and np.all(tab.inertia > 0) and tab.m <= 12
        assert e["solve"].startswith("revolute_schur") == closed, name
        if closed:
            taken.add(name)
    assert {"double_pendulum", "four_bar", "three_link_pendulum",
            "parallelogram_redundant"} <= taken
    # the generic path for every other joint type; the penalty formulation's own matrix
    sc = scene_from_dict(_every_joint_type(), "inline.toml")
    assert M.evaluate(M.build_tables(sc), sc.q0(), sc.v0())["solve"].startswith("schur:")
    sc, tab, q, v = state("double_pendulum")
    for small, name in ((True, "in-house"), (False, "LAPACK")):
        e = M.evaluate(tab, q, v, 0.0, "penalty", M.model_options(small_dense=small))
        assert e["solve"].startswith("penalty:") and name in e["solve"]


@pytest.mark.parametrize("formulation", ["reduced", "baumgarte", "projection"])
@pytest.mark.parametrize("name", ["double_pendulum", "four_bar", "three_link_pendulum",
                                  "physical_pendulum", "plate_with_two_bars"])
def test_closed_form_revolute_schur_follows_the_table_driven_one(name, formulation):
    """Whole runs with the closed-form 2 x 2 blocks of S (mbdk_revolute_schur) against the
    Schur complement assembled from the nonzeros of D (mbdk_sparse_schur): two independent
    assemblies and eliminations of the same S, so 1 s of rk4 agrees to roundoff (chaotic
    double pendulum included: the gap after 1000 steps is about 1e-13), while a wrong weight,
    sign or block in either moves the state by the size of the accelerations."""
    sc = (scene_from_dict(_plate_with_two_bars(), "inline.toml") if name == "plate_with_two_bars"
          else mbdk.scene(name))
    a, b = (mbdk.simulate(sc, "rk4", formulation=formulation, h=1e-3, t_end=1.0, every=50,
                          solver=s) for s in ("revolute_schur", "schur"))
    assert a.manifest["linear_solve"].startswith("revolute_schur")
    assert b.manifest["linear_solve"].startswith("schur:")
    assert np.ptp(a.q, axis=0).max() > 0.1
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(a.v, b.v, rtol=0, atol=1e-10)
    np.testing.assert_allclose(a.multipliers, b.multipliers, rtol=0,
                               atol=1e-10 * np.abs(b.multipliers).max())


def test_closed_form_revolute_schur_reports_the_redundant_parallelogram():
    """The parallelogram's third crank repeats a constraint pair: S is singular, and the 2 x 2
    block elimination must say so (MBDK_ERR_SINGULAR_MATRIX) as the generic one does, not
    divide by a roundoff pivot."""
    sc = mbdk.scene("parallelogram_redundant")
    tab = M.build_tables(sc)
    q, v, _ = M.assemble(sc, tab)
    for solver in ("revolute_schur", "schur", "auto"):
        e = M.evaluate(tab, q, v, options=M.model_options(solver=solver))
        assert e["status"] == mbdk.Status.ERR_SINGULAR_MATRIX, solver
    with pytest.raises(mbdk.InvalidInputError, match="not revolute: slider .prismatic."):
        mbdk.simulate(mbdk.scene("trolley_crane"), "rk4", h=1e-3, t_end=0.1,
                      solver="revolute_schur")


def test_energy_of_conservative_scene_and_balance_of_damped_one():
    r = mbdk.simulate(mbdk.scene("four_bar"), "rk4", formulation="projection", h=1e-3, t_end=5.0)
    assert np.ptp(r.energy) < 1e-6 * r.energy_parts["kinetic"].max()
    r = mbdk.simulate(mbdk.scene("spring_damper_bar"), "rk4", h=1e-3, t_end=2.0)
    assert r.energy_parts["dissipated_dampers"][-1] > 1.0
    # damper work by the kernel's trapezoidal rule over rk4's steps: O(h^2) quadrature error
    assert np.abs(r.energy_balance()).max() < 1e-4 * r.energy_parts["dissipated_dampers"][-1]


def test_user_scene_from_toml(tmp_path):
    p = tmp_path / "slider_crank.toml"
    p.write_text("""
[scene]
name = "pendulum_on_a_rail"
[[body]]
name = "cart"
mass = 2.0
inertia = 0.1
[[body]]
name = "arm"
mass = 0.5
shape = { type = "bar", length = 0.8 }
x = 0.3
y = -0.3
angle_deg = -45
given = ["angle"]
[[joint]]
type = "prismatic"
body1 = "cart"
axis = [1, 0]
[[joint]]
type = "revolute"
body1 = "arm"
point1 = [-0.4, 0]
body2 = "cart"
[[force]]
type = "gravity"
g = [0, -9.81]
[[force]]
type = "point_force"
body = "cart"
force = [1.0, 0.0]
function = { amplitude = 1.0, omega = 2.0 }
""")
    r = mbdk.simulate(mbdk.load_scene(p), "rk4", h=1e-3, t_end=2.0)
    assert r.success and r.residuals[:, 0].max() < 1e-9
    assert r.q.shape == (2001, 6) and r.reactions.shape == (2001, 2, 3)
    assert np.abs(r.energy_balance()).max() < 1e-6


BAD = [
    ({"body": [{"name": "a", "mass": 1, "inertia": 1}], "joint": [{"type": "hinge", "body1": "a"}]},
     "joint #1: field 'type' = 'hinge' is not a joint type"),
    ({"body": [{"name": "a", "inertia": 1}]}, "body 'a': field 'mass' is missing"),
    ({"body": [{"name": "a", "mass": -1, "inertia": 1}]}, "body 'a': field 'mass' = -1.0 must be positive"),
    ({"body": [{"name": "a", "mass": 1, "inertia": -2}]}, "field 'inertia' = -2.0 must not be negative"),
    ({"body": [{"name": "a", "mass": 1, "inertia": 1}],
      "joint": [{"name": "j", "type": "revolute", "body1": "b"}]},
     "joint 'j': field 'body1' = 'b' names no body"),
    ({"body": [{"name": "a", "mass": 1, "inertia": 1}, {"name": "a", "mass": 1, "inertia": 1}]},
     "body 'a': field 'name' is used twice"),
    ({"body": [{"name": "a", "mass": 1, "inertia": 1, "x": float("nan")}]},
     "body 'a': field 'x' = nan is not finite"),
    ({"body": [{"name": "a", "mass": 1, "inertia": 1}],
      "joint": [{"type": "fixed", "body1": "a"}, {"type": "revolute", "body1": "a"}]},
     "5 constraint equations for 3 coordinates"),
    ({"body": [{"name": "a", "mass": 1, "inertia": 1, "colour": "red"}]},
     "body 'a': field 'colour' is not a field of this element type"),
    ({"body": [1]}, "body #1 = 1 is not a table"),
    ({"body": [{"name": "a", "mass": 1, "inertia": 1}], "joint": ["hinge"]},
     "joint #1 = 'hinge' is not a table"),
    ({"body": [{"name": "a", "mass": 1, "inertia": 1}], "force": [{"type": "spring", "body1": "a"}]},
     "force #1: field 'stiffness' is missing"),
]


@pytest.mark.parametrize("data, message", BAD)
def test_bad_scenes_name_file_element_and_field(data, message):
    with pytest.raises(mbdk.SceneError) as exc:
        scene_from_dict(data, "bad.toml")
    assert str(exc.value).startswith("bad.toml: ")
    assert message in str(exc.value)


def test_spring_without_direction_is_refused():
    sc = mbdk.scene("spring_bar")
    sc.forces[0].point2 = (1.0, 0.0)          # the bar's free end sits exactly there
    with pytest.raises(mbdk.SceneError, match="force 'spring': fields 'point1' and 'point2' coincide"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01)


def test_bad_files(tmp_path):
    p = tmp_path / "broken.toml"
    p.write_text("[[body]\nname = 'x'")
    with pytest.raises(mbdk.SceneError, match="broken.toml: not valid TOML"):
        mbdk.load_scene(p)
    with pytest.raises(mbdk.SceneError, match="cannot read"):
        mbdk.load_scene(tmp_path / "missing.toml")
    with pytest.raises(mbdk.SceneError, match="no built-in scene 'nope'"):
        mbdk.scene("nope")
    with pytest.raises(mbdk.InvalidInputError, match="formulation 'index3': trapezoidal_index3 runs"):
        mbdk.simulate(mbdk.scene("physical_pendulum"), "rk4", formulation="index3", h=1e-3, t_end=1)


def test_result_carries_the_done_means_fields():
    r = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", formulation="baumgarte", h=1e-3,
                      t_end=10, every=np.int64(1))     # numpy integers are whole numbers too
    n = len(r.t)
    assert n == 10001
    for a in (r.q, r.v, r.a, r.multipliers, r.energy, r.residuals):
        assert len(a) == n and np.all(np.isfinite(a))
    assert r.reactions.shape == (n, 2, 3)
    assert set(r.energy_parts) >= {"kinetic", "potential_gravity", "dissipated_dampers",
                                   "work_constraints"}
    assert r.cpu_time > 0 and r.stats.steps == 10000
    assert r.manifest["formulation"] == "baumgarte" and r.manifest["alpha"] == pytest.approx(1000)


def test_scene_drift_study(tmp_path):
    import csv
    import scene_drift
    summary = scene_drift.run(tmp_path, quick=True)
    assert all(f["path"].exists() and f["caption"] for f in summary["figures"])
    rows = list(csv.DictReader(open(tmp_path / "scene_drift.csv")))
    by = {(r["scene"], r["formulation"]): r for r in rows}
    for sc in ("double_pendulum", "four_bar"):
        assert float(by[(sc, "projection")]["max_phi"]) < 1e-12
        assert float(by[(sc, "reduced")]["max_phi"]) > 100 * float(by[(sc, "projection")]["max_phi"])
        assert all(float(r["cpu_s"]) > 0 for r in rows)
    speed = list(csv.DictReader(open(tmp_path / "scene_speed.csv")))
    assert len(speed) == 6
    assert all(float(r["ns_per_rk4_step"]) > 0 for r in speed if "not run" not in r["linear_solve"])
    yard = [r for r in speed if r["linear_solve"].startswith("C yardstick")]
    assert len(yard) == 1
    if "not run" not in yard[0]["linear_solve"]:
        assert float(yard[0]["max_diff_to_kernel"]) < 1e-9


def _book_bar(force):
    """The book's hinged bar of 2.3.1 / 2.3.2: length 1, hinge at the origin, horizontal."""
    return scene_from_dict({
        "body": [{"name": "bar", "mass": 1.0, "shape": {"type": "bar", "length": 1.0},
                  "x": 0.5, "y": 0.0, "angle": 0.0}],
        "joint": [{"name": "A", "type": "revolute", "body1": "bar", "point1": [-0.5, 0.0],
                   "body2": "ground"}],
        "force": [force]})


def test_spring_vector_of_2_99_with_the_sign_corrected():
    """Spring from B (l/6 beyond the centre) to C = (0, l/2), rest length l, at (l/2, 0, 0).
    Derived here: Delta l = 5l/6 - l = -l/6, grad Phi = [2l/3, -l/2, -l^2/12] / (5l/6), so
    -s Delta l grad Phi = s l [8, -6, -l] / 60. The book prints +6 s l / 60 for Fy."""
    s, l = 1000.0, 1.0
    sc = _book_bar({"type": "spring", "body1": "bar", "point1": [l / 6, 0.0], "body2": "ground",
                    "point2": [0.0, l / 2], "stiffness": s, "rest_length": l})
    f = M.evaluate(M.build_tables(sc), [0.5, 0.0, 0.0], [0.0, 0.0, 0.0])["f"]
    assert f == pytest.approx(s * l * np.array([8, -6, -l]) / 60, rel=1e-12)
    assert f[1] != pytest.approx(6 * s * l / 60)          # the printed (2.99)


def test_damper_vector_uses_the_signed_rate_not_2_124():
    """Damper from B (l/4 from the hinge) to C = (0, l), the bar turning at omega about A:
    v = (0, omega l/2, omega). grad Phi = [1, -4, l]/sqrt(17) (2.120), the rate of length change
    grad Phi . v = -omega l/sqrt(17) (the damper shortens), force -k rate grad Phi =
    k omega l [1, -4, l]/17. (2.124) would use |v_B| = omega l/4 > 0 instead."""
    k, l, w = 10.0, 1.0, 2.0
    sc = _book_bar({"type": "damper", "body1": "bar", "point1": [-l / 4, 0.0], "body2": "ground",
                    "point2": [0.0, l], "damping": k})
    v = np.array([0.0, w * l / 2, w])
    f = M.evaluate(M.build_tables(sc), [0.5, 0.0, 0.0], v)["f"]
    assert f == pytest.approx(k * w * l * np.array([1, -4, l]) / 17, rel=1e-12)
    assert f @ v == pytest.approx(-k * (w * l) ** 2 / 17, rel=1e-12)     # power -k rate^2 < 0
    assert f @ v != pytest.approx(-k * (w * l / 4) ** 2)                  # (2.124)'s rate


def test_scene_checks_study(tmp_path):
    """The book-element table flags (2.99), (2.124) and (2.126) and agrees elsewhere; the
    coordinate sets agree; every Baumgarte run the rk4 real-axis limit calls stable stays
    bounded, and alpha h well beyond it blows up."""
    import csv
    import scene_checks
    summary = scene_checks.run(tmp_path, quick=True)
    assert all(f["path"].exists() and f["caption"] for f in summary["figures"])
    book = {r["eq"]: r for r in csv.DictReader(open(tmp_path / "book_elements.csv"))}
    assert book["(2.96)-(2.98)"]["verdict"] == "agree"
    assert book["(2.120)-(2.121)"]["verdict"] == "agree"
    for eq in ("(2.99)", "(2.124)", "(2.126)"):
        assert book[eq]["verdict"].startswith("book wrong")
    forms = list(csv.DictReader(open(tmp_path / "four_bar_forms.csv")))
    assert len(forms) == 4
    assert all(float(r["max_joint_error_m"]) < 1e-4 and float(r["cpu_s"]) > 0 for r in forms)
    runs = list(csv.DictReader(open(tmp_path / "baumgarte_map.csv")))
    for r in runs:
        ah = float(r["alpha_h"])
        if ah < 2.0:
            assert r["outcome"] == "bounded", r
        if ah > 4.0:
            assert r["outcome"] != "bounded", r


def test_reduced_rk4_matches_the_hand_written_c_yardstick(tmp_path):
    """Both kernel paths (the closed-form revolute blocks that solver = 'auto' takes here, and
    the table-driven Schur complement from the nonzeros of D) against the same reduction
    written out by hand for the double pendulum (studies/scene_yardstick.c, the yardstick of
    table scene_speed): the two joints as LDL^T pivot blocks, a = W (f - D^T lam), rk4.
    Identical arithmetic up to the order of sums, so 2000 steps (2 s of swinging) agree to
    roundoff; a wrong slot, sign or weight anywhere in the assembly or the solve moves the
    state by far more (the steps change q by about 0.3)."""
    import shutil
    import scene_drift
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler")
    sc = mbdk.scene("double_pendulum")
    tab = M.build_tables(sc)
    assert scene_drift.yardstick_layout(tab)
    h, n = 1e-3, 2000
    exe = scene_drift.yardstick_build(cc, tmp_path)
    for solver in ("auto", "schur"):
        r = mbdk.simulate(sc, "rk4", h=h, t_end=n * h, every=n, solver=solver)
        y0 = np.concatenate([r.q[0], r.v[0]])
        _, y = scene_drift.yardstick_run(exe, tab, y0, n, h)
        assert np.abs(y - y0).max() > 0.1
        np.testing.assert_allclose(y, np.concatenate([r.q[-1], r.v[-1]]), rtol=0, atol=1e-11)


def _four_bar_scaled(length=1.0, mass=1.0):
    sc = mbdk.scene("four_bar")
    for b in sc.bodies:
        b.x, b.y = b.x * length, b.y * length
        b.mass *= mass
        b.inertia *= mass * length ** 2
    for j in sc.joints:
        j.point1 = tuple(c * length for c in j.point1)
        j.point2 = tuple(c * length for c in j.point2)
    return sc


def test_the_rank_test_is_free_of_units():
    """The singular-configuration diagnosis and the redundancy test read D scaled by M^-1/2 (and
    angle rows by a radius of gyration): the four-bar in millimetres, or with its masses in
    tonnes, has the singular values of the one in metres and kilograms, where the raw D's
    smallest / largest ratio moves by orders of magnitude (a millimetre mechanism looked close
    to losing a rank everywhere, and every failure blamed all its joints)."""
    from mbdk import model as M
    ratios, raw = [], []
    for length, mass in ((1.0, 1.0), (1e-3, 1.0), (1.0, 1e3)):
        sc = _four_bar_scaled(length, mass)
        tab = M.build_tables(sc)
        d = M.evaluate(tab, sc.q0(), sc.v0())["D"]
        sv = np.linalg.svd(M.scaled_jacobian(tab, d), compute_uv=False)
        ratios.append(sv[-1] / sv[0])
        sv_raw = np.linalg.svd(d, compute_uv=False)
        raw.append(sv_raw[-1] / sv_raw[0])
    assert ratios[1] == pytest.approx(ratios[0], rel=1e-9)
    assert ratios[2] == pytest.approx(ratios[0], rel=1e-9)
    assert ratios[0] > 1e-2                          # a regular pose is not called near-singular
    # one body 1e6 times lighter than the others: D M^-1 D^T is ill-conditioned, the geometry
    # is not (the scaled singular values are those of the uniform four-bar)
    sc = _four_bar_scaled(1.0, 1.0)
    sc.bodies[1].mass *= 1e-6
    sc.bodies[1].inertia *= 1e-6
    tab = M.build_tables(sc)
    sv = np.linalg.svd(M.scaled_jacobian(tab, M.evaluate(tab, sc.q0(), sc.v0())["D"]),
                       compute_uv=False)
    assert sv[-1] / sv[0] == pytest.approx(ratios[0], rel=1e-9)
    assert raw[1] < 1e-2 * raw[0]                    # the unscaled ratio is not free of units
