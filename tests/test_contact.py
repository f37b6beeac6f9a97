"""Contacts, friction and wear (kernel/src/model/mbdk_contact.f90, mbdk_wear.f90) against closed
forms: a ball's restitution and contact time, a block sliding to rest on an incline, a particle
held in a ring (Fekete 2023, (1.22)) and where it leaves the wall, and each wear law's volume
against an independent quadrature of the simulated contact forces."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from scipy.special import beta

import mbdk
from mbdk.errors import NotApplicableError
from mbdk.scene import SceneError
from mbdk.scene_file import scene_from_dict

G = 9.81


def ball(k=1e5, c=0.0, e=1.0, v0=2.0, r=0.1, m=1.0, depth=0.0, gravity=False, wear=None):
    d = {"scene": {"name": "ball"},
         "body": [{"name": "ball", "mass": m, "inertia": 0.4 * m * r * r, "y": r + 0.01,
                   "vy": -v0}],
         "force": [{"type": "contact", "name": "floor", "body1": "ball",
                    "shape1": {"type": "circle", "radius": r},
                    "shape2": {"type": "line", "point": [0, 0], "normal": [0, 1]},
                    "stiffness": k, "exponent": e, "damping": c, "damping_depth": depth}]}
    if gravity:
        d["force"].append({"type": "gravity", "g": [0, -G]})
    if wear:
        d["wear"] = wear
    return scene_from_dict(d)


def test_kelvin_voigt_restitution():
    """A linear spring-dashpot contact without gravity: the ball leaves when the force k x + c x'
    returns to zero (the contact does not pull), at the speed of the damped oscillator's closed
    form x = v0/wd exp(-z w t) sin(wd t) there; not the unclipped exp(-z pi / sqrt(1 - z^2))."""
    m, k, c, v0 = 1.0, 1e5, 20.0, 2.0
    r = mbdk.simulate(ball(k, c, v0=v0), "rk4", h=2e-6, t_end=0.03, every=50)
    w, z = math.sqrt(k / m), c / (2 * math.sqrt(k * m))
    wd = w * math.sqrt(1 - z * z)
    x = lambda t: v0 / wd * math.exp(-z * w * t) * math.sin(wd * t)          # noqa: E731
    xd = lambda t: v0 / wd * math.exp(-z * w * t) * (wd * math.cos(wd * t)   # noqa: E731
                                                     - z * w * math.sin(wd * t))
    ts = brentq(lambda t: k * x(t) + c * xd(t), 0.5 * math.pi / wd, math.pi / wd)
    e_closed = -xd(ts) / v0
    e_sim = r.v[-1, 1] / v0
    assert abs(e_sim - e_closed) < 2e-5, (e_sim, e_closed)
    unclipped = math.exp(-z * math.pi / math.sqrt(1 - z * z))
    assert abs(e_sim - unclipped) > 1e-3     # the clip matters at this damping


def test_error_control_locates_where_the_contact_closes_and_lets_go():
    """dopri54 ends a step where the ball touches (delta = 0, where the damping force jumps in),
    where the clipped force lets go (k delta + c delta' = 0) and where the surfaces part: its
    restitution's error against the closed form (test above) is then a few times rtol, not the
    hundred times rtol of the kinks inside steps. Measured over 17 tolerances from 1e-12 to 1e-8
    (the error of one tolerance depends on where its steps happen to fall): the median of
    error / rtol is 15 with the events located and 110 without, for about the same steps."""
    m, k, c, v0 = 1.0, 1e5, 20.0, 2.0
    w, z = math.sqrt(k / m), c / (2 * math.sqrt(k * m))
    wd = w * math.sqrt(1 - z * z)
    x = lambda t: v0 / wd * math.exp(-z * w * t) * math.sin(wd * t)          # noqa: E731
    xd = lambda t: v0 / wd * math.exp(-z * w * t) * (wd * math.cos(wd * t)   # noqa: E731
                                                     - z * w * math.sin(wd * t))
    ts = brentq(lambda t: k * x(t) + c * xd(t), 0.5 * math.pi / wd, math.pi / wd, xtol=1e-15)
    e_closed = -xd(ts) / v0
    ratio, steps = {True: [], False: []}, {True: 0, False: 0}
    for located in (True, False):
        for rtol in np.logspace(-12, -8, 17):
            r = mbdk.simulate(ball(k, c, v0=v0), "dopri54", rtol=rtol, atol=1e-12, t_end=0.03,
                              dt_out=0.03, locate_events=located)
            ratio[located].append(abs(r.v[-1, 1] / v0 - e_closed) / rtol)
            steps[located] += r.stats.steps
            assert r.manifest["locate_events"] is located
    med = {key: float(np.median(v)) for key, v in ratio.items()}
    assert med[True] < 30 and med[True] < med[False] / 4, med
    assert steps[True] < 1.2 * steps[False], steps


def test_hertz_contact_time_and_restitution():
    """F = k delta^(3/2) without damping: the ball leaves at its arrival speed, after
    t_c = 2 delta_max/v0 * (2/5) B(2/5, 1/2), delta_max = (5 m v0^2 / (4 k))^(2/5) (energy)."""
    m, k, v0 = 1.0, 1e8, 1.0
    r = mbdk.simulate(ball(k, e=1.5, v0=v0), "rk4", h=1e-6, t_end=0.015, every=1)
    dmax = (5 * m * v0 ** 2 / (4 * k)) ** 0.4
    tc = 2 * dmax / v0 * 0.4 * beta(0.4, 0.5)
    pen = 0.1 - r.q[:, 1]
    inside = r.t[pen > 0]
    assert abs((inside[-1] - inside[0]) - tc) < 3e-6, (inside[-1] - inside[0], tc)
    assert abs(pen.max() - dmax) < 1e-3 * dmax
    assert abs(r.v[-1, 1] - v0) < 1e-8


def incline(alpha_deg=20.0, mu=0.5, v0=1.0, k=1e6, wear=None):
    a = math.radians(alpha_deg)
    n = (-math.sin(a), math.cos(a))
    d0 = G * math.cos(a) / k            # the static penetration: no normal oscillation
    d = {"scene": {"name": "incline"},
         "body": [{"name": "block", "mass": 1.0, "inertia": 0.1, "x": n[0] * -d0,
                   "y": n[1] * -d0, "vx": -v0 * math.cos(a), "vy": -v0 * math.sin(a)}],
         "force": [{"type": "gravity", "g": [0, -G]},
                   {"type": "contact", "name": "slope", "body1": "block",
                    "shape1": {"type": "point"},
                    "shape2": {"type": "line", "point": [0, 0], "normal": list(n)},
                    "stiffness": k, "damping": 200.0,
                    "friction": {"static": mu, "dynamic": mu, "stiction_speed": 1e-3,
                                 "transition_speed": 2e-3}}]}
    if wear:
        d["wear"] = wear
    return scene_from_dict(d), a


def test_block_slides_to_rest_on_an_incline():
    """mu > tan(alpha): the block decelerates at g (mu cos a - sin a) and stops after
    v0 / that, having slid v0^2 / (2 that). Then the regularised friction, which vanishes at
    zero slip, lets it creep at the speed u_c where mu(u_c) = tan a: 3 s^2 - 2 s^3 = tan a / mu
    with s = u_c / stiction_speed (the law's cubic step)."""
    sc, a = incline()
    r = mbdk.simulate(sc, "rk4", h=1e-4, t_end=1.2, every=10, outputs=("energy",))
    dec = G * (0.5 * math.cos(a) - math.sin(a))
    ts, dist = 1.0 / dec, 1.0 / (2 * dec)
    s = -(r.q[:, 0] * math.cos(a) + r.q[:, 1] * math.sin(a))
    speed = np.hypot(r.v[:, 0], r.v[:, 1])
    t_stop = r.t[np.argmax(speed < 1e-3)]
    assert abs(t_stop - (ts - 1e-3 / dec)) < 2e-3
    uc = 1e-3 * brentq(lambda x: x * x * (3 - 2 * x) - math.tan(a) / 0.5, 0, 1)
    assert abs(speed[-1] - uc) < 1e-3 * uc
    assert abs(s[-1] - dist - uc * (r.t[-1] - ts)) < 2e-4
    # the friction's and the damper's work close the energy balance
    assert np.abs(r.energy_balance()).max() < 1e-4 * 0.5


def ring(v0, k=1e7, r=0.05, R=1.0):
    """Started at the penetration that carries its circular motion (m (v0^2/L + g) / k), so that
    the wall does not ring."""
    L = R - r
    d = {"scene": {"name": "ring"},
         "body": [{"name": "p", "mass": 1.0, "inertia": 1e-4, "y": -L - (v0 ** 2 / L + G) / k,
                   "vx": v0}],
         "force": [{"type": "gravity", "g": [0, -G]},
                   {"type": "contact", "name": "wall", "body1": "p",
                    "shape1": {"type": "circle", "radius": r},
                    "shape2": {"type": "ring", "radius": R, "centre": [0, 0]},
                    "stiffness": k}]}
    return scene_from_dict(d), L


def test_particle_in_a_ring_loops_like_a_pendulum():
    """Fast enough (v0^2 = 6 g L) the particle presses on the wall all the way round: it stays
    inside (penetration at most the force's m (v^2/L + g) / k) and moves as the rigid pendulum of
    length L (integrated here by SciPy) to within the wall's compliance."""
    sc, L = ring(math.sqrt(6 * G * 0.95))
    r = mbdk.simulate(sc, "rk4", h=2e-5, t_end=2.0, every=50)
    rho = np.hypot(r.q[:, 0], r.q[:, 1])
    assert rho.max() - L <= 7 * G / 1e7 * 1.01
    assert rho.min() - L > 0          # touching throughout: never off the wall
    phi = np.unwrap(np.arctan2(r.q[:, 0], -r.q[:, 1]))
    ref = solve_ivp(lambda t, y: [y[1], -G / L * math.sin(y[0])], (0, 2.0),
                    [0.0, math.sqrt(6 * G * L) / L], t_eval=r.t, rtol=1e-12, atol=1e-12)
    assert np.abs(phi - ref.y[0]).max() < 2e-3


def test_particle_leaves_the_wall_where_the_normal_force_vanishes():
    """2 g L < v0^2 < 5 g L: the contact is unilateral, and the particle leaves the wall where
    m v^2 / L = -m g cos(phi), cos(phi_s) = -(v0^2/(g L) - 2)/3 (phi from the bottom): 120 deg
    for v0^2 = 3.5 g L."""
    sc, L = ring(math.sqrt(3.5 * G * 0.95))
    r = mbdk.simulate(sc, "rk4", h=2e-5, t_end=1.5, every=5)
    rho = np.hypot(r.q[:, 0], r.q[:, 1])
    off = np.argmax(rho < L)           # the first sample without penetration
    phi_s = math.degrees(math.atan2(r.q[off, 0], -r.q[off, 1]))
    assert abs(phi_s - 120.0) < 0.3, phi_s
    # it lands again and stays inside: an undamped impact penetrates at most as far as the
    # normal speed's energy carries it, |v| sqrt(m/k) <= v0 sqrt(m/k), far less than its radius
    v0 = math.sqrt(3.5 * G * 0.95)
    assert rho[off:].max() > L
    assert rho.max() - L < v0 / math.sqrt(1e7) + 5 * G / 1e7


def quadrature(r, integrand):
    f = integrand(r)
    return np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(r.t))])


def test_archard_wear_of_the_sliding_block():
    """dW = k F u dt integrated with the motion against the trapezoidal quadrature of k F |u|
    recomputed here from the sampled states (F = k_c delta + c delta', u the slip), and against
    the closed form k m g cos(a) * sliding distance."""
    kw = 1e-9
    sc, a = incline(wear=[{"name": "w", "law": "archard", "load": "slope.normal_force",
                           "coefficient": kw}])
    r = mbdk.simulate(sc, "rk4", h=1e-4, t_end=1.0, every=1)
    n = np.array([-math.sin(a), math.cos(a)])
    tdir = np.array([-n[1], n[0]])

    def rate(res):
        delta = -(res.q[:, :2] @ n)
        rate_ = -(res.v[:, :2] @ n)
        f = np.maximum(0.0, 1e6 * delta + 200.0 * rate_) * (delta > 0)
        return kw * f * np.abs(res.v[:, :2] @ tdir)
    w_ref = quadrature(r, rate)
    assert np.abs(r.wear["w"] - w_ref).max() < 1e-6 * w_ref[-1]
    dec = G * (0.5 * math.cos(a) - math.sin(a))
    assert abs(r.wear["w"][-1] - kw * G * math.cos(a) / (2 * dec)) < 1e-3 * r.wear["w"][-1]


def spinning_disc(wear):
    d = {"scene": {"name": "disc"},
         "body": [{"name": "disc", "mass": 1.0, "shape": {"type": "disc", "radius": 0.1},
                   "y": 0.1 - G / 1e6, "omega": 30.0}],
         "force": [{"type": "gravity", "g": [0, -G]},
                   {"type": "contact", "name": "floor", "body1": "disc",
                    "shape1": {"type": "circle", "radius": 0.1},
                    "shape2": {"type": "line", "point": [0, 0], "normal": [0, 1]},
                    "stiffness": 1e6, "damping": 500.0,
                    "friction": {"static": 0.3, "dynamic": 0.25, "stiction_speed": 1e-3,
                                 "transition_speed": 1e-2}}],
         "wear": wear}
    return scene_from_dict(d)


def test_gear_and_knee_wear_laws_against_quadrature():
    """A disc spun on the floor slides until it rolls (omega from 30 to 30/3 rad/s, the
    friction's closed form for a disc, I = m r^2/2). The gear law (6.8)-(6.10) with its speed
    R |omega1 - omega2| and lubrication factor psi, and the knee law (6.12) on the friction force
    with S/R(t), each against the quadrature of its rate from the sampled states."""
    psi_pars = dict(radius=7.6e-4, temperature=293.0)
    sr = [1.137558, 0.02378365, 0.3631732, -0.111667]
    sc = spinning_disc([{"name": "gear", "law": "gear", "load": "floor.normal_force",
                         "coefficient": 6.5e-13, **psi_pars},
                        {"name": "knee", "law": "knee", "load": "floor.friction_force",
                         "coefficient": 1.3e-15, "slide_roll": sr}])
    r = mbdk.simulate(sc, "rk4", h=1e-5, t_end=0.6, every=1)
    assert abs(r.v[-1, 2] - 10.0) < 0.05          # rolling: omega0 / 3 for a uniform disc
    assert abs(r.v[-1, 0] + 1.0) < 0.005          # v = -omega r

    def contact(res):
        delta = 0.1 - res.q[:, 1]
        f = np.maximum(0.0, 1e6 * delta + 500.0 * -res.v[:, 1]) * (delta > 0)
        slip = res.v[:, 0] + 0.1 * res.v[:, 2]    # the contact point's speed along t = (1, 0)
        return f, slip

    def gear_rate(res):
        f, _ = contact(res)
        u = 7.6e-4 * np.abs(res.v[:, 2])
        x = 3e-10 / (u * 3e-12) * math.exp(-49e3 / (8.31 * 293.0))
        return 6.5e-13 * f * -np.expm1(-x) * u

    def mu(u):
        a = np.abs(u)
        s1 = np.clip(a / 1e-3, 0, 1)
        s2 = np.clip((a - 1e-3) / 9e-3, 0, 1)
        m_ = np.where(a <= 1e-3, 0.3 * s1 * s1 * (3 - 2 * s1),
                      0.3 + (0.25 - 0.3) * s2 * s2 * (3 - 2 * s2))
        return m_

    def knee_rate(res):
        f, slip = contact(res)
        t = res.t
        slide_roll = sr[0] + t * (sr[1] + t * (sr[2] + t * sr[3]))
        return 1.3e-15 * mu(slip) * f * np.abs(slip) * slide_roll
    for name, fn in (("gear", gear_rate), ("knee", knee_rate)):
        ref = quadrature(r, fn)
        assert ref[-1] > 0
        assert np.abs(r.wear[name] - ref).max() < 1e-5 * ref[-1], name


def test_energy_balance_with_friction_and_damping():
    """The disc's kinetic energy lost while it slides is the friction's and the dampers'
    dissipated work (energy_balance() stays at roundoff of the quadrature)."""
    sc = spinning_disc([])
    r = mbdk.simulate(sc, "rk4", h=1e-5, t_end=0.6, every=1, outputs=("energy",))
    lost = r.energy[0] - r.energy[-1]
    assert lost > 0.1
    assert np.abs(r.energy_balance()).max() < 1e-4 * lost


def test_only_declared_effects_are_visited():
    """A scene without contacts visits none; a contact without friction visits no friction."""
    r = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-3, t_end=0.01)
    assert r.visits["contact"] == r.visits["friction"] == r.visits["wear"] == 0
    r = mbdk.simulate(ball(), "rk4", h=1e-4, t_end=0.01)
    assert r.visits["contact"] > 0 and r.visits["friction"] == 0 and r.visits["wear"] == 0


@pytest.mark.parametrize("change, field", [
    (lambda d: d["force"][0].update(stiffness=-1.0), "stiffness"),
    (lambda d: d["force"][0].update(exponent=0.5), "exponent"),
    (lambda d: d["force"][0].update(damping=-2.0), "damping"),
    (lambda d: d["force"][0].update(friction={"static": -0.1}), "static"),
    (lambda d: d["force"][0].update(friction={"static": 0.2, "stiction_speed": 1e-2,
                                              "transition_speed": 1e-3}), "transition_speed"),
    (lambda d: d["force"][0].update(shape2={"type": "ring", "radius": 0.05}), "shape2"),
    (lambda d: d["force"][0].update(shape2={"type": "line", "normal": [0, 0]}), "normal"),
    (lambda d: d["force"][0].update(shape1={"type": "square"}), "shape1"),
    (lambda d: d.update(wear=[{"law": "archard", "load": "wall.normal_force",
                               "coefficient": 1.0}]), "'wall.normal_force' names no contact"),
    (lambda d: d.update(wear=[{"law": "archard", "load": "floor.friction_force",
                               "coefficient": 1.0}]), "has no friction"),
    (lambda d: d.update(wear=[{"law": "archard", "load": "floor.normal_force",
                               "coefficient": -1.0}]), "coefficient"),
    (lambda d: d.update(wear=[{"law": "gear", "load": "floor.normal_force",
                               "coefficient": 1.0, "radius": 1e-3}]), "temperature"),
    (lambda d: d.update(wear=[{"law": "paris", "load": "floor.normal_force",
                               "coefficient": 1.0}]), "law"),
])
def test_bad_contacts_and_wear_are_named(change, field):
    d = {"scene": {"name": "bad"},
         "body": [{"name": "ball", "mass": 1.0, "inertia": 0.01, "y": 0.2}],
         "force": [{"type": "contact", "name": "floor", "body1": "ball",
                    "shape1": {"type": "circle", "radius": 0.1},
                    "shape2": {"type": "line", "normal": [0, 1]}, "stiffness": 1e5}]}
    change(d)
    with pytest.raises(SceneError) as exc:
        scene_from_dict(d, "bad.toml")
    msg = str(exc.value)
    assert "bad.toml" in msg and field in msg, msg


def test_methods_without_contacts_or_wear_say_so():
    with pytest.raises(NotApplicableError, match="floor"):
        mbdk.simulate(ball(), "trapezoidal_index3", h=1e-4, t_end=0.01)
    sc = ball(wear=[{"name": "w", "law": "archard", "load": "floor.normal_force",
                     "coefficient": 1e-9}])
    with pytest.raises(NotApplicableError, match="wear"):
        mbdk.simulate(sc, "ida", t_end=0.01, rtol=1e-6)


MOD = 1.35e-3     # table 6.2 of the book: module 1.35 mm, 80 and 40 teeth, 13 mm wide, PLA


def gear_pair(a=None, friction=None, damping=0.0, torque1=0.0, torque2=0.0, driver=None,
              wear=None, k=1e8, backlash=0.0, function1=None, free2=None):
    def disc(z):
        r = MOD * z / 2
        mass = math.pi * r * r * 13e-3 * 1250.0
        return mass, mass * r * r / 2
    (m1, j1), (m2, j2) = disc(80), disc(40)
    a = MOD * 60 if a is None else a
    mesh = {"type": "contact", "name": "mesh", "body1": "g1", "body2": "g2",
            "shape1": {"type": "gear", "teeth": 80, "module": MOD},
            "shape2": {"type": "gear", "teeth": 40, "module": MOD},
            "stiffness": k, "exponent": 1.5, "damping": damping, "damping_depth": 1e-6,
            "backlash": backlash}
    if friction:
        mesh["friction"] = friction
    d = {"scene": {"name": "gears"},
         "body": [{"name": "g1", "mass": m1, "inertia": j1, "given": ["angle"]},
                  {"name": "g2", "mass": m2, "inertia": j2, "x": a, "given": ["angle"]}],
         "joint": [{"type": "revolute", "name": "axle1", "body1": "g1"},
                   {"type": "revolute", "name": "axle2", "body1": "g2", "point2": [a, 0]}],
         "force": [mesh]}
    for body, tq in (("g1", torque1), ("g2", torque2)):
        if tq:
            d["force"].append({"type": "torque", "body": body, "torque": tq})
            if body == "g1" and function1:
                d["force"][-1]["function"] = function1
    if free2:     # gear 2's centre on two springs to the ground instead of its axle
        d["joint"].pop(1)
        d["body"][1]["x"] = a - free2[1]
        d["force"].append({"type": "spring", "body1": "g2", "body2": "ground",
                           "point2": [a + 0.05, 0.0], "stiffness": free2[0],
                           "rest_length": 0.05 + 2 * free2[1]})
        d["force"].append({"type": "spring", "body1": "g2", "body2": "ground",
                           "point2": [a - free2[1], 0.05], "stiffness": free2[0]})
    if driver:
        d["joint"].append({"type": "driver", "name": "motor", "body1": "g1",
                           "coordinate": "angle", "function": {"rate": driver}})
        d["body"][0]["omega"] = driver
        d["body"][1]["omega"] = -2 * driver
    if wear:
        d["wear"] = wear
    return scene_from_dict(d), (j1, j2)


def involute(a):
    """Base and tip radii, base pitch, working pressure angle and contact ratio of the pair at
    centre distance a, from the module's definitions (r = m z/2, r_tip = r + m,
    r_base = r cos 20 deg, p_b = pi m cos 20 deg)."""
    c = math.cos(math.radians(20))
    rb1, rb2, ra1, ra2 = MOD * 40 * c, MOD * 20 * c, MOD * 41, MOD * 21
    pb = math.pi * MOD * c
    alpha = math.acos((rb1 + rb2) / a)
    eps = (math.sqrt(ra1 ** 2 - rb1 ** 2) + math.sqrt(ra2 ** 2 - rb2 ** 2)
           - a * math.sin(alpha)) / pb
    return rb1, rb2, pb, alpha, eps


@pytest.mark.parametrize("stretch", [1.0, 1.01])
def test_involute_mesh_statics(stretch):
    """Gear 1 turned through one base pitch with gear 2 following the conjugate motion
    (theta2 = -(rb1/rb2) theta1 + delta0/rb2: a constant penetration delta0 along the line of
    action, the involute's property). The force on gear 2's centre points along the line of
    action at the working pressure angle acos((rb1 + rb2)/a) from the normal to the centre line;
    the torques stand as rb1 : rb2; the load, in pairs, is 1 or 2, and two pairs carry it over a
    share eps - 1 - relief of the pitch (eps the contact ratio, relief the 0.1 pitch over which a
    pair takes up its load)."""
    from mbdk import model as M
    a = MOD * 60 * stretch
    sc, _ = gear_pair(a=a)
    tab = M.build_tables(sc)
    rb1, rb2, pb, alpha, eps = involute(a)
    delta0, k = 2e-6, 1e8
    full = k * delta0 ** 1.5
    q0 = np.array(sc.q0(), float)
    loads, plain = [], []
    for th1 in np.linspace(0, pb / rb1, 2001)[:-1]:
        q = q0.copy()
        q[2], q[5] = th1, -(rb1 / rb2) * th1 + delta0 / rb2
        f = M.evaluate(tab, q, np.zeros(6))["f"]
        loads.append(-f[5] / (full * rb2))
        if abs(loads[-1] - round(loads[-1])) < 1e-9:      # no pair in its relief ramp
            plain.append(f)
    loads = np.array(loads)
    assert loads.min() > 0.999 and loads.max() < 2.001
    assert abs(np.mean(loads > 1.5) - (eps - 1 - 0.1)) < 2e-3
    assert len(plain) > 1000
    for f in plain:
        assert abs(f[2] / f[5] - rb1 / rb2) < 1e-9
        assert abs(math.atan2(f[3], f[4]) - alpha) < 1e-9     # gear 2's centre: along d
        assert np.allclose(f[0:2], -f[3:5], rtol=0, atol=1e-9 * full)


def test_gear_train_spins_up_as_a_rigid_train():
    """A torque on gear 1 of the frictionless pair spins both up as the rigid train would:
    theta1 = T t^2 / (2 (J1 + (z1/z2)^2 J2)), theta2 = -(z1/z2) theta1 (the mesh's compliance
    and its ringing aside), and the undamped mesh conserves energy: the torque's work is the
    kinetic and mesh energy."""
    sc, (j1, j2) = gear_pair(torque1=0.1, backlash=1e-4)   # the ringing stays off the coast
    r = mbdk.simulate(sc, "rk4", h=1e-5, t_end=0.1, every=10, outputs=("energy",))
    th1 = 0.5 * 0.1 / (j1 + 4 * j2) * r.t ** 2
    assert np.abs(r.q[:, 2] - th1).max() < 1e-4 * th1[-1]
    # gear 2 lags the rigid ratio by the mesh's deflection along the line of action, a few
    # times the static one (F/k)^(2/3), F = J2 alpha2 / rb2 (the suddenly applied load rings)
    rb2 = involute(MOD * 60)[1]
    static = (j2 * 2 * 0.1 / (j1 + 4 * j2) / rb2 / 1e8) ** (2 / 3)
    assert np.abs(r.q[:, 5] + 2 * r.q[:, 2]).max() * rb2 < 10 * static
    assert np.abs(r.energy_balance()).max() < 1e-6 * r.energy[-1]
    # the contact outputs: the drive flanks carry the mesh force F = J2 alpha2 / rb2 (ringing
    # about it: its mean over the second half, where the ringing has had many periods), the
    # coast flanks, the backlash apart, none
    assert set(r.contacts) == {"mesh", "mesh.coast"}
    force = j2 * 2 * 0.1 / (j1 + 4 * j2) / rb2
    late = r.t > 0.05
    assert r.contacts["mesh"]["normal_force"][late].mean() == pytest.approx(force, rel=0.02)
    assert not r.contacts["mesh.coast"]["normal_force"].any()
    assert r.contacts["mesh.coast"]["penetration"].max() < -0.5e-4


def test_reversing_load_meets_the_coast_flanks_across_the_backlash():
    """An alternating torque on gear 1 drives the pair back and forth: the drive flanks (in touch
    at the start) and the coast flanks (the backlash B apart) take turns. Along the line of
    action the flanks' relative position rb1 theta1 + rb2 theta2 (the involute's rolling
    property, the axles fixed) stays between -B and 0 but for the contacts' small penetrations,
    reaches both ends, and the undamped, frictionless rattle conserves energy."""
    backlash, k = 1e-4, 1e8
    sc, (j1, j2) = gear_pair(torque1=0.2, function1={"amplitude": 1.0, "omega": 40.0},
                             backlash=backlash, k=k)
    r = mbdk.simulate(sc, "rk4", h=2e-6, t_end=0.4, every=5, outputs=("energy",))
    rb1, rb2, *_ = involute(MOD * 60)
    rel = rb1 * (r.q[:, 2] - r.q[0, 2]) + rb2 * (r.q[:, 5] - r.q[0, 5])
    # how far flanks can penetrate: an impact at the largest closing speed along the line of
    # action (Hertz's (5 m v^2 / (4 k))^(2/5), m the pair's mass reduced to it) on top of the
    # static deflection under the largest torque
    m_eq = 1 / (rb1 ** 2 / j1 + rb2 ** 2 / j2)
    v_rel = np.abs(rb1 * r.v[:, 2] + rb2 * r.v[:, 5]).max()
    pen = (5 * m_eq * v_rel ** 2 / (4 * k)) ** 0.4 + (0.2 / rb1 / k) ** (2 / 3)
    assert -backlash - pen < rel.min() < -backlash + pen
    assert -pen < rel.max() < pen
    assert np.abs(r.energy_balance()).max() < 1e-5 * np.abs(r.energy).max()


def test_gear_mesh_conserves_energy_with_a_moving_centre():
    """Gear 2 hangs on two springs instead of its axle, pressed into the mesh: its centre moves
    (the centre distance and the centre line's direction) as the pair turns, so the mesh's
    potential depends on it (through the pressure angle and the path of contact's start).
    Undamped and frictionless, the energy balance holds only if the mesh's forces are that
    potential's exact gradient: 8e-9 of the energy here, 4e-6 without the term of d w/d a."""
    sc, _ = gear_pair(torque1=0.05, free2=(2e4, 2e-5))
    r = mbdk.simulate(sc, "rk4", h=2e-6, t_end=0.1, every=5, outputs=("energy",))
    a = np.hypot(r.q[:, 3] - r.q[:, 0], r.q[:, 4] - r.q[:, 1])
    phi = np.arctan2(r.q[:, 4] - r.q[:, 1], r.q[:, 3] - r.q[:, 0])
    assert a.max() - a.min() > 1e-7 and np.ptp(phi) > 1e-6       # the centre does move
    assert np.abs(r.energy_balance()).max() < 1e-6 * np.abs(r.energy).max()


def test_gear_friction_costs_efficiency_and_wear_follows_the_mesh():
    """Driven at a constant speed against a load torque, friction makes gear 1's driver supply
    more than the load takes (efficiency below 1); the speed ratio stays z1/z2; the Archard
    wear of the mesh grows monotonically and stays below its bound k F_total max|u| t, the slip
    largest at gear 1's tip (the per-pair quadrature of k F u is the disc's test above, on the
    same wear routine)."""
    sc, _ = gear_pair(driver=10.0, torque2=0.5, damping=20.0,
                      friction={"static": 0.3, "dynamic": 0.1, "stiction_speed": 1e-3,
                                "transition_speed": 1e-2},
                      wear=[{"name": "W", "law": "archard", "load": "mesh.normal_force",
                             "coefficient": 6.5e-13}])
    r = mbdk.simulate(sc, "rk4", h=1e-5, t_end=0.2, every=10, outputs=("energy", "multipliers"))
    late = r.t > 0.05
    assert abs(r.v[late, 5].mean() / 10.0 + 2) < 1e-4
    # the driver's moment (its multiplier) against the load's 0.5 N m over the ratio 2
    drive = -r.multipliers[late, -1].mean()
    assert 0.25 < drive and 0.25 / drive < 0.99
    rb1, rb2, pb, alpha, eps = involute(MOD * 60)
    u_max = 30.0 * (math.sqrt((MOD * 41) ** 2 - rb1 ** 2) - rb1 * math.tan(alpha))
    f_total = 0.5 / rb2 * 1.2
    w = r.wear["W"]
    assert np.all(np.diff(w) >= 0) and w[-1] > 0
    assert w[-1] < 6.5e-13 * f_total * u_max * r.t[-1]


@pytest.mark.parametrize("change, field", [
    (lambda d: d["force"][0].update(shape2={"type": "line", "normal": [1, 0]}), "meshes only"),
    (lambda d: d["force"][0]["shape2"].update(module=1.5e-3), "base pitch"),
    (lambda d: d["force"][0].update(body2="ground"), "body2"),
    (lambda d: d["body"][1].update(x=MOD * 62), "contact ratio"),
    (lambda d: d["body"][1].update(x=MOD * 50), "cannot mesh"),
    (lambda d: d["force"][0].update(backlash=2.5e-3), "backlash"),
])
def test_gears_that_do_not_mesh_are_named(change, field):
    from mbdk import model as M
    d = {"scene": {"name": "bad"},
         "body": [{"name": "g1", "mass": 1.0, "inertia": 1e-3},
                  {"name": "g2", "mass": 1.0, "inertia": 1e-3, "x": MOD * 60}],
         "force": [{"type": "contact", "name": "mesh", "body1": "g1", "body2": "g2",
                    "shape1": {"type": "gear", "teeth": 80, "module": MOD},
                    "shape2": {"type": "gear", "teeth": 40, "module": MOD},
                    "stiffness": 1e8}]}
    change(d)
    with pytest.raises(SceneError) as exc:
        M.build_tables(scene_from_dict(d, "bad.toml"))
    msg = str(exc.value)
    assert "bad.toml" in msg and field in msg and "mesh" in msg, msg


def test_contact_outputs_of_a_dropped_ball_in_closed_form():
    """SceneResult.contacts: a ball dropped 1 m onto a linear floor (k = 1e6, no damping):
    normal force = k delta at every sample; the deepest penetration is the root of
    k delta^2 / 2 = m g (1 + delta) (energy, closed form), to the sampling's 1e-5 s; no
    friction element, no friction force; the energy with the contact's potential k delta^2 / 2
    is conserved but for the step that straddles the contact's start (a kink of the force that
    a fixed step does not locate): 2e-6 of E here."""
    m, k = 1.0, 1e6
    sc = ball(k=k, v0=0.0, r=0.1, m=m, gravity=True)
    sc.bodies[0].y = 1.1
    r = mbdk.simulate(sc, "rk4", h=1e-5, t_end=0.5, every=1, outputs=("energy",))
    c = r.contacts["floor"]
    delta = np.maximum(c["penetration"], 0.0)
    assert np.allclose(c["normal_force"], k * delta, rtol=1e-12, atol=1e-9)
    exact = (m * G + math.sqrt((m * G) ** 2 + 2 * k * m * G * 1.0)) / k
    assert c["penetration"].max() == pytest.approx(exact, rel=1e-4)
    assert np.all(c["friction_force"] == 0.0)
    e = 0.5 * m * r.v[:, 1] ** 2 + m * G * r.q[:, 1] + 0.5 * k * delta ** 2
    assert np.abs(e - e[0]).max() < 1e-5 * abs(e[0])


def test_the_energy_balance_of_bouncing_converges_with_the_tolerance():
    """A damped ball bouncing under gravity (Kelvin-Voigt, c = 20 N s/m), dopri54: between
    letting go (k delta + c delta' = 0) and parting (delta = 0) the contact dissipates its
    potential, a power with a kink at the parting; with the parting as an event of its own
    (as spatial contacts have it) no step holds that kink, and the run's energy balance
    |E - E0 - W| (W the work integrated at every step) falls with rtol: at 1e-10 within 1e-8
    of E0 (with the kink inside a step it stayed near 1e-4 of E0 at every rtol)."""
    sc = ball(1e5, 20.0, v0=2.0, gravity=True)
    worst = {}
    for rtol in (1e-8, 1e-10):
        r = mbdk.simulate(sc, "dopri54", rtol=rtol, atol=1e-14, t_end=1.0, dt_out=1e-4)
        assert np.sum(np.diff(np.sign(0.1 - r.q[:, 1])) > 0) >= 3      # three bounces at least
        worst[rtol] = np.abs(r.energy_balance()).max() / r.energy[0]
    assert worst[1e-10] < 1e-8 and worst[1e-10] < worst[1e-8] / 100, worst
