"""Contacts, friction and wear between spatial bodies (kernel/src/spatial/mbdk_contact3d.f90 over
the laws of kernel/src/model/mbdk_contact_law.f90, wear by kernel/src/model/mbdk_wear.f90's laws)
against closed forms: a sphere's restitution and Hertz contact time on a plane and on another
sphere, a sphere launched sliding that rolls at 5/7 of its speed, and its Archard wear, a ball
spun against a fixed sphere until friction stops it, and the wear it leaves, a top spinning on
its rounded tip that precesses as the heavy top on its fixed point, and the energy and momentum
balances."""
import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import beta

import mbdk
from mbdk import _kernel
from mbdk.errors import EnergyDriftError
from mbdk.scene import SceneError
from mbdk.scene_file import scene_from_dict
from mbdk.spatial_model import evaluate_spatial, spatial_tables

G = 9.81


def contact(body1="ball", shape1=None, body2="ground", shape2=None, **law):
    return {"type": "contact", "name": "floor", "body1": body1, "body2": body2,
            "shape1": shape1 or {"type": "sphere", "radius": 0.1},
            "shape2": shape2 or {"type": "plane", "normal": [0, 0, 1]}, **law}


def ball(k=1e5, c=0.0, e=1.0, v0=2.0, r=0.1, m=1.0, depth=0.0, gravity=False, v=None,
         omega=(0.0, 0.0, 0.0), z0=None, friction=None):
    """A solid sphere (I = 2/5 m r^2) above the plane z = 0, coming down at v0."""
    law = {"stiffness": k, "exponent": e, "damping": c, "damping_depth": depth}
    if friction:
        law["friction"] = friction
    d = {"scene": {"name": "ball3d"},
         "body": [{"name": "ball", "kind": "spatial", "mass": m,
                   "shape": {"type": "sphere", "radius": r},
                   "position": [0.0, 0.0, r + 0.01 if z0 is None else z0],
                   "velocity": list(v) if v is not None else [0.0, 0.0, -v0],
                   "omega_body": list(omega)}],
         "force": [contact(shape1={"type": "sphere", "radius": r}, **law)]}
    if gravity:
        d["force"].append({"type": "gravity", "g": [0.0, 0.0, -G]})
    return scene_from_dict(d)


def kelvin_voigt(m, k, c, v0):
    """The linear spring-dashpot m x'' + c x' + k x = 0 from x = 0, x' = v0 (x the
    penetration): x = v0/wd exp(-z w t) sin(wd t), w = sqrt(k/m), z = c/(2 sqrt(k m)),
    wd = w sqrt(1 - z^2). The IMPACT law does not pull: the ball leaves where the force
    k x + c x' returns to zero, at ts, with the speed -x'(ts)."""
    w, z = math.sqrt(k / m), c / (2 * math.sqrt(k * m))
    wd = w * math.sqrt(1 - z * z)

    def x(t):
        return v0 / wd * math.exp(-z * w * t) * math.sin(wd * t)

    def xd(t):
        return v0 / wd * math.exp(-z * w * t) * (wd * math.cos(wd * t) - z * w * math.sin(wd * t))
    ts = brentq(lambda t: k * x(t) + c * xd(t), 0.5 * math.pi / wd, math.pi / wd, xtol=1e-15)
    return -xd(ts) / v0, z


def test_restitution_of_a_damped_sphere():
    """A linear spring-dashpot contact without gravity, the sphere coming down obliquely and
    spinning: its normal speed leaves at the closed-form restitution of kelvin_voigt (the
    contact lets go where k x + c x' = 0). That is not the textbook exp(-z pi / sqrt(1 - z^2))
    (e.g. Goldsmith, Impact (1960), for a dashpot that holds on until x returns to 0, pulling
    at the end); the two differ by the clip's share, 2 z^2 e to first order. Without friction
    the tangential velocity and the spin are untouched."""
    m, k, c, v0 = 1.0, 1e5, 20.0, 2.0
    r = mbdk.simulate(ball(k, c, v=(0.3, -0.2, -v0), omega=(5.0, -3.0, 40.0)), "rk4", h=2e-6,
                      t_end=0.03, every=50)
    e_closed, z = kelvin_voigt(m, k, c, v0)
    e_sim = r.v[-1, 2] / v0
    assert abs(e_sim - e_closed) < 2e-5, (e_sim, e_closed)
    textbook = math.exp(-z * math.pi / math.sqrt(1 - z * z))
    assert abs((e_sim - textbook) / (2 * z * z * textbook) - 1) < 0.1
    assert np.allclose(r.v[-1, [0, 1]], [0.3, -0.2], rtol=0, atol=1e-12)
    assert np.allclose(r.v[-1, 3:], [5.0, -3.0, 40.0], rtol=0, atol=1e-9)


@pytest.mark.parametrize("shape", ["plane", "sphere"])
def test_hertz_contact_time(shape):
    """F = k delta^(3/2) without damping. Energy gives the deepest penetration
    delta_max = (5 m* v0^2 / (4 k))^(2/5) and the contact time t_c = 2 delta_max/v0 * (2/5)
    B(2/5, 1/2) (the time integral of d delta / sqrt(v0^2 - (4 k / (5 m*)) delta^(5/2));
    Johnson, Contact Mechanics (1985) 11.1), m* the reduced mass: the sphere's own on the plane,
    m/2 for two equal spheres head-on, which then exchange their velocities."""
    m, k, v0, rad = 1.0, 1e8, 1.0, 0.05
    if shape == "plane":
        sc, ms = ball(k, e=1.5, v0=v0, r=rad, z0=rad + 0.002), m
    else:
        sc = scene_from_dict({
            "scene": {"name": "spheres"},
            "body": [{"name": "a", "kind": "spatial", "mass": m, "position": [-rad - 0.002, 0, 0],
                      "shape": {"type": "sphere", "radius": rad}, "velocity": [v0, 0, 0]},
                     {"name": "b", "kind": "spatial", "mass": m, "position": [rad, 0, 0],
                      "shape": {"type": "sphere", "radius": rad}}],
            "force": [contact("a", {"type": "sphere", "radius": rad}, "b",
                              {"type": "sphere", "radius": rad}, stiffness=k, exponent=1.5)]})
        ms = m / 2
    r = mbdk.simulate(sc, "rk4", h=1e-6, t_end=0.006, every=1)
    if shape == "plane":
        pen = rad - r.q[:, 2]
    else:
        pen = 2 * rad - np.linalg.norm(r.position("a") - r.position("b"), axis=1)
    dmax = (5 * ms * v0 ** 2 / (4 * k)) ** 0.4
    tc = 2 * dmax / v0 * 0.4 * beta(0.4, 0.5)
    inside = r.t[pen > 0]
    assert abs((inside[-1] - inside[0]) - tc) < 3e-6, (inside[-1] - inside[0], tc)
    assert abs(pen.max() - dmax) < 1e-3 * dmax
    if shape == "plane":
        assert abs(r.v[-1, 2] - v0) < 1e-8
    else:
        assert np.allclose(r.v[-1, [0, 6]], [0.0, v0], rtol=0, atol=1e-8)


def tilted(v0=2.0, mu=0.3, r=0.1, m=1.0, k=1e6, vs=1e-3, wear=None):
    """A solid sphere resting (at its static penetration m g / k) on a plane through p with the
    normal n = (1, 2, 2)/3, gravity along -n, launched along the plane at v0 without spin; wear:
    the [[wear]] entries of its contact "floor"."""
    n = np.array([1.0, 2.0, 2.0]) / 3
    t = np.array([2.0, -2.0, 1.0]) / 3           # along the plane
    p = np.array([0.3, -0.1, 0.2])
    d = {"scene": {"name": "sliding"},
         "body": [{"name": "ball", "kind": "spatial", "mass": m,
                   "shape": {"type": "sphere", "radius": r},
                   "position": (p + (r - m * G / k) * n).tolist(),
                   "velocity": (v0 * t).tolist()}],
         "force": [{"type": "gravity", "g": (-G * n).tolist()},
                   contact(shape1={"type": "sphere", "radius": r},
                           shape2={"type": "plane", "point": p.tolist(), "normal": n.tolist()},
                           stiffness=k, damping=2 * math.sqrt(k * m),
                           friction={"static": mu, "dynamic": mu, "stiction_speed": vs,
                                     "transition_speed": 2 * vs})]}
    if wear:
        d["wear"] = wear
    return scene_from_dict(d), n, t


@pytest.mark.parametrize("method, kw", [("rk4", dict(h=1e-4, every=10)),
                                        ("dopri54", dict(rtol=1e-9, atol=1e-12, dt_out=1e-3))])
def test_sliding_sphere_rolls_at_five_sevenths(method, kw):
    """Sliding, Coulomb friction mu m g decelerates the centre, v = v0 - mu g t, and spins the
    sphere up, omega = (5/2) mu g t / r (I = 2/5 m r^2); the slip v - omega r falls at
    (7/2) mu g and reaches the law's transition speed vd at (v0 - vd) / ((7/2) mu g), just
    before the Coulomb rolling time 2 v0 / (7 mu g). Friction acting at the contact point keeps
    the angular momentum about it, m v r + I omega = m v0 r, so the sphere rolls on at 5/7 v0
    (any law that ends the slip), having lost m v0^2/7 to friction, which the energy balance
    books (Routh, Dynamics of a System of Rigid Bodies (1905) 223; Goldstein's exercise)."""
    v0, mu, rad, vd = 2.0, 0.3, 0.1, 2e-3
    sc, n, t = tilted(v0, mu, rad)
    r = mbdk.simulate(sc, method, t_end=0.4, **kw)
    v = r.v[:, :3] @ t
    axis = np.cross(n, t)            # rolling along t turns the sphere about n x t
    om = np.einsum("nij,nj->ni", r.orientation("ball"), r.omega_body("ball")) @ axis
    slip = v - om * rad
    t_vd = (v0 - vd) / (3.5 * mu * G)
    sliding = r.t < t_vd - 2e-3
    om_ref = 2.5 * mu * G * r.t[sliding] / rad
    assert np.abs(v[sliding] - (v0 - mu * G * r.t[sliding])).max() < 1e-9 * v0
    assert np.abs(om[sliding] - om_ref).max() < 2e-9 * om_ref.max()
    crossed = r.t[np.argmax(slip < vd)]
    assert t_vd <= crossed < t_vd + 2e-3 and t_vd < 2 * v0 / (7 * mu * G)
    assert abs(v[-1] - 5 / 7 * v0) < 1e-6 and abs(slip[-1]) < 1e-6
    assert np.abs(r.v[:, :3] @ n).max() < 1e-8 * v0       # no bounce
    lost = r.energy[0] - r.energy[-1]
    assert abs(lost - v0 ** 2 / 7) < 1e-6
    assert np.abs(r.energy_balance()).max() < 1e-6 * lost


@pytest.mark.parametrize("method, kw", [("bs32", dict(rtol=1e-7)), ("bdf", dict(rtol=1e-7)),
                                        ("ida", dict(rtol=1e-7)),
                                        ("trapezoidal_index3", dict(h=1e-4))])
def test_every_method_rolls_the_sphere(method, kw):
    """The contact is a force of the spatial model: the DAE and index-3 integrators reach the
    rolling speed 5/7 v0 as the ODE methods do."""
    sc, n, t = tilted()
    r = mbdk.simulate(sc, method, t_end=0.4, **kw)
    assert abs(r.v[-1, :3] @ t - 5 / 7 * 2.0) < 1e-6


def top_on_its_tip(tip=1e-5, k=1e6, vs=1e-4):
    """The built-in heavy top (mass 1, J = (0.005, 0.005, 0.01) about the centre, the centre
    l = 0.1 up its axis, tilted 0.3 rad, spun at 50 rad/s) without its spherical joint: a
    sphere of radius tip centred on the joint's point holds it on the plane z = 0 (at the
    static penetration), with friction mu = 0.5."""
    top = mbdk.scene("heavy_top").bodies[0]
    rot, l = top.rotation, 0.1
    base = np.array([0.0, 0.0, tip - G / k])     # the tip sphere's centre
    d = {"scene": {"name": "top_on_plane"},
         "body": [{"name": "top", "kind": "spatial", "mass": top.mass,
                   "inertia": np.diag(top.inertia).tolist(),
                   "position": (base + rot @ [0.0, 0.0, l]).tolist(),
                   "quaternion": [0.9887710779360422, 0.14943813247359922, 0.0, 0.0],
                   "velocity": (rot @ np.cross(top.omega_body, [0.0, 0.0, l])).tolist(),
                   "omega_body": top.omega_body.tolist()}],
         "force": [{"type": "gravity", "g": [0.0, 0.0, -G]},
                   contact("top", {"type": "sphere", "radius": tip, "centre": [0.0, 0.0, -l]},
                           stiffness=k, damping=math.sqrt(k * top.mass),
                           friction={"static": 0.5, "dynamic": 0.5, "stiction_speed": vs,
                                     "transition_speed": 2 * vs})]}
    return scene_from_dict(d)


def test_top_spinning_on_its_tip_precesses_as_the_heavy_top():
    """The top held by the contact alone against the heavy top on its spherical joint
    (scenes/spatial/heavy_top.toml, same mass, inertia and tip distance): their figure axes
    R e3 agree over 2 s, in which the axis precesses by 4.3 rad about the vertical and nods
    between 16 and 21 degrees of tilt (the nutation the initial omega of 1 rad/s across the
    axis starts). The regularised friction holds the tip by letting it
    creep at a speed proportional to the stiction speed vs, so the contact top converges to the
    fixed-point one in vs, to first order (the contact's stiffness, 1e6 or 1e7 N/m, and the tip
    radius of 1e-5 m change the difference by less than a tenth of it); and the
    dissipation of the contact's damping and friction closes the energy balance."""
    t_end = 2.0
    ref = mbdk.simulate(mbdk.scene("heavy_top"), "dopri54", rtol=1e-10, atol=1e-12, t_end=t_end,
                        dt_out=0.01)
    axis_ref = ref.orientation("top")[:, :, 2]
    err = {}
    for vs in (1e-3, 1e-4):
        r = mbdk.simulate(top_on_its_tip(vs=vs), "dopri54", rtol=1e-8, atol=1e-10, t_end=t_end,
                          dt_out=0.01)
        err[vs] = np.abs(r.orientation("top")[:, :, 2] - axis_ref).max()
        e_scale = np.abs(r.energy).max()
        assert np.abs(r.energy_balance()).max() < 1e-7 * e_scale
    # the axis has moved: the agreement is no accident
    precession = np.unwrap(np.arctan2(axis_ref[:, 1], axis_ref[:, 0]))
    assert abs(precession[-1] - precession[0]) > 4.0
    assert err[1e-4] < 2e-3, err
    assert err[1e-3] / err[1e-4] > 5, err


def test_located_events_and_the_energy_balance_of_a_damped_bounce():
    """dopri54 ends a step where the sphere touches (where the damping force jumps in), where
    the clipped force lets go and where the surfaces part (delta = 0 on the way out). At rtol
    1e-10 the restitution is then within 1e-9 of the closed form (kelvin_voigt), several times
    closer than with the kinks inside steps, and the energy balance E - E0 - W (the contact's
    potential, the work of its damping) stays below 1e-7 of the loss; without the events the
    potential a clipped contact still holds is dissipated inside a long step of the flight that
    follows, and its work is missed by a part in ten thousand or more, which a watch on the
    energy at 1e-6 reports."""
    m, k, c, v0 = 1.0, 1e5, 20.0, 2.0
    e_closed, _ = kelvin_voigt(m, k, c, v0)
    err, bal = {}, {}
    for located in (True, False):
        r = mbdk.simulate(ball(k, c, v0=v0), "dopri54", rtol=1e-10, atol=1e-12, t_end=0.03,
                          dt_out=1e-3, locate_events=located)
        assert r.manifest["locate_events"] is located
        lost = r.energy[0] - r.energy[-1]
        err[located] = abs(r.v[-1, 2] / v0 - e_closed)
        bal[located] = np.abs(r.energy_balance()).max() / lost
    assert err[True] < 1e-9 and err[True] < err[False] / 5, err
    assert bal[True] < 1e-7 < 1e-4 < bal[False], bal
    watch = {"energy": 1e-6, "every": 1}
    mbdk.simulate(ball(k, c, v0=v0), "dopri54", rtol=1e-10, atol=1e-12, t_end=0.03, watch=watch)
    with pytest.raises(EnergyDriftError):
        mbdk.simulate(ball(k, c, v0=v0), "dopri54", rtol=1e-10, atol=1e-12, t_end=0.03,
                      watch=watch, locate_events=False)


def test_bouncing_with_gravity_keeps_its_energy_balance():
    """Dropped from 0.2 m onto a damped contact whose damping ramps in over 1e-4 m: bounce
    after bounce, each apex lower than the one before; the balance E - E0 - W holds to 5e-7 of
    the energy lost with rk4 (fixed steps, its work by the trapezoidal rule; 1.2e-7 at this
    step, 4e-8 at half of it) and dopri54 (located events; 8e-8 at these tolerances)."""
    sc = ball(1e5, 30.0, v0=0.0, z0=0.3, gravity=True, depth=1e-4)
    for method, kw in (("rk4", dict(h=2e-6, every=500)),
                       ("dopri54", dict(rtol=1e-10, atol=1e-12, dt_out=1e-3))):
        r = mbdk.simulate(sc, method, t_end=1.5, **kw)
        z = r.q[:, 2]
        apex = z[1:-1][(z[1:-1] > z[:-2]) & (z[1:-1] > z[2:])]
        assert len(apex) >= 4 and np.all(np.diff(apex) < 0), apex
        lost = r.energy[0] - r.energy[-1]
        assert np.abs(r.energy_balance()).max() < 5e-7 * lost, method


def test_two_spheres_with_friction_keep_their_momenta():
    """An oblique hit of a spinning sphere on a resting one, with damping and friction: the
    contact's forces are equal and opposite at one point, so the momentum and the angular
    momentum of the pair stay as they were (the watch tests both: the contact between two
    bodies leaves all six components conserved), while friction passes spin from one to the
    other and the energy lost is the work of damping and friction."""
    rad, m = 0.05, 1.0
    sc = scene_from_dict({
        "scene": {"name": "spheres"},
        "body": [{"name": "a", "kind": "spatial", "mass": m, "position": [-rad - 0.005, 0.025, 0],
                  "shape": {"type": "sphere", "radius": rad}, "velocity": [1.0, 0, 0],
                  "omega_body": [0, 0, 50.0]},
                 {"name": "b", "kind": "spatial", "mass": m, "position": [rad + 0.005, -0.025, 0],
                  "shape": {"type": "sphere", "radius": rad}}],
        "force": [contact("a", {"type": "sphere", "radius": rad}, "b",
                          {"type": "sphere", "radius": rad}, stiffness=1e7, damping=100.0,
                          friction={"static": 0.4, "dynamic": 0.3})]})
    r = mbdk.simulate(sc, "dopri54", rtol=1e-10, atol=1e-12, t_end=0.06, dt_out=1e-4,
                      watch={"momentum": 1e-10})
    assert len(r.manifest["invariants"]) == 6
    inertia = 0.4 * m * rad ** 2
    p = r.v[:, 0:3] + r.v[:, 6:9]
    h = sum(m * np.cross(r.position(b), r.v[:, 6 * i:6 * i + 3]) + inertia * np.einsum(
        "nij,nj->ni", r.orientation(b), r.omega_body(b)) for i, b in enumerate("ab"))
    assert np.abs(p - p[0]).max() < 1e-12 and np.abs(h - h[0]).max() < 1e-12
    assert r.omega_body("b")[-1, 2] < -5.0           # friction spun b the other way
    lost = r.energy[0] - r.energy[-1]
    assert lost > 0.1 * r.energy[0]
    assert np.abs(r.energy_balance()).max() < 1e-8 * lost


def test_sphere_hits_a_plane_on_a_free_body():
    """A plane on a body (a free slab, no gravity) struck off-centre by a sphere, undamped and
    frictionless: the contact's normal turns with the slab (n = R n2), the pair's momenta are
    conserved, the slab takes spin, and the energy is conserved (the forces are the potential's
    exact gradient: delta' = -n . u at the contact point)."""
    sc = scene_from_dict({
        "scene": {"name": "slab"},
        "body": [{"name": "ball", "kind": "spatial", "mass": 0.5, "position": [0.15, 0.05, 0.12],
                  "shape": {"type": "sphere", "radius": 0.05}, "velocity": [0.0, 0.0, -1.0]},
                 {"name": "slab", "kind": "spatial", "mass": 2.0, "position": [0, 0, 0],
                  "shape": {"type": "box", "size": [0.6, 0.4, 0.1]},
                  "euler313_deg": [10.0, 5.0, 0.0]}],
        "force": [contact("ball", {"type": "sphere", "radius": 0.05}, "slab",
                          {"type": "plane", "point": [0, 0, 0.05], "normal": [0, 0, 1]},
                          stiffness=1e6, exponent=1.5)]})
    r = mbdk.simulate(sc, "dopri54", rtol=1e-10, atol=1e-12, t_end=0.15, dt_out=1e-3)
    p = 0.5 * r.v[:, 0:3] + 2.0 * r.v[:, 6:9]
    assert np.abs(p - p[0]).max() < 1e-12
    assert np.linalg.norm(r.omega_body("slab")[-1]) > 0.5
    assert r.v[-1, 2] > 0                             # the ball bounced off
    assert np.abs(r.energy - r.energy[0]).max() < 1e-8 * r.energy[0]


@pytest.mark.parametrize("change, field", [
    (lambda f: f.update(stiffness=-1.0), "stiffness"),
    (lambda f: f.update(exponent=0.5), "exponent"),
    (lambda f: f.update(damping=-2.0), "damping"),
    (lambda f: f.update(friction={"static": -0.1}), "static"),
    (lambda f: f.update(friction={"static": 0.2, "stiction_speed": 1e-2,
                                  "transition_speed": 1e-3}), "transition_speed"),
    (lambda f: f.update(shape1={"type": "sphere", "radius": -0.1}), "radius"),
    (lambda f: f.update(shape1={"type": "sphere", "radius": 0.1, "center": [0, 0, 0]}),
     "'center' is not a field of a sphere"),
    (lambda f: f.update(shape1={"type": "plane", "normal": [0, 0, 1]}), "shape1"),
    (lambda f: f.update(shape2={"type": "plane", "normal": [0, 0, 0]}), "normal"),
    (lambda f: f.update(shape2={"type": "cube"}), "shape2"),
    (lambda f: f.update(body2="ball"), "body2"),
    (lambda f: f.update(body1="ghost"), "ghost"),
    (lambda f: f.update(shape1={"type": "point"}, shape2={"type": "sphere", "radius": 0.0}),
     "radius"),
    (lambda f: f.update(size=3), "size"),
])
def test_bad_spatial_contacts_are_named(change, field):
    d = {"scene": {"name": "bad"},
         "body": [{"name": "ball", "kind": "spatial", "mass": 1.0, "inertia": [0.01] * 3,
                   "position": [0, 0, 0.2]}],
         "force": [contact(stiffness=1e5)]}
    change(d["force"][0])
    with pytest.raises(SceneError) as exc:
        scene_from_dict(d, "bad.toml")
    msg = str(exc.value)
    assert "bad.toml" in msg and field in msg and "floor" in msg, msg


def test_contacts_changed_in_python_are_checked_by_name():
    """A SpatialForce edited after reading meets the reader's checks before the kernel does."""
    sc = ball()
    f = sc.forces[0]
    reals = list(f.reals)
    reals[12] = 0.5                                   # exponent
    f.reals = tuple(reals)
    with pytest.raises(SceneError, match="floor.*exponent"):
        mbdk.simulate(sc, "rk4", h=1e-4, t_end=0.01)


# ---- wear of spatial contacts ---------------------------------------------------------------

#: Archard's law V' = K F |s| / H (K dimensionless, H the hardness): mbdk_wear's archard takes
#: k = K / H, m^3/(N m); a steel-like pair
ARCHARD_K, HARDNESS = 1e-3, 2e9


def slip_bounds(s0, a0, vs, t_end):
    """Bounds on the slip distance int |s| dt over [0, t_end] of a contact whose slip speed
    falls from s0 at a0 = (friction force / mu) x mu / (effective mass), Coulomb's mu
    regularised below vs (mbdk_contact_law with static = dynamic: mu(s) = mu phi(s / vs),
    phi(x) = 3 x^2 - 2 x^3 for s < vs, mu above), t_end after s has reached vs. Down to vs the
    slip falls linearly, int s dt = (s0^2 - vs^2) / (2 a0) (lo). Below vs, ds/dt = -a0 phi(x):
    int s dt = (vs^2 / a0) int x dx / phi(x) = (vs^2 / (3 a0)) ln((3 - 2 x_e) / x_e) from x = 1
    down to x_e = s(t_end) / vs, and phi(x) >= x^2 gives x(t) >= 1 / (1 + 3 a0 t / vs), so the
    zone adds at most zone = (vs^2 / (3 a0)) ln(3 (1 + 3 a0 t_end / vs)). The unregularised
    closed form s0^2 / (2 a0) lies in [lo, lo + zone]; (lo, zone, t_vs the time s reaches vs)."""
    lo = (s0 * s0 - vs * vs) / (2 * a0)
    zone = vs * vs / (3 * a0) * math.log(3 * (1 + 3 * a0 * t_end / vs))
    return lo, zone, (s0 - vs) / a0


def test_sliding_sphere_wears_as_archard_says():
    """The sphere of test_sliding_sphere_rolls_at_five_sevenths (m, r, I = 2/5 m r^2, on a plane
    with gravity along its normal: F = m g) with two wear elements on its contact, solved by
    hand (Newton-Euler with Coulomb friction mu m g at the contact point; Routh, Dynamics of a
    System of Rigid Bodies (1905) 223): its slip falls as v0 - (7/2) mu g t (a0 = mu g (1 +
    m r^2 / I)), so until it rolls at t* = 2 v0 / (7 mu g) it slides S = v0^2 / (7 mu g), and
    then slides no more:
      archard on the normal force: V = k F S, k = K / H, and V(t) = k F (v0 t - 7/4 mu g t^2)
        while it slides;
      knee on the friction force mu F with S/R(t) = c0 + c1 t: V = k mu F (c0 S + c1 v0^3 /
        (6 a0^2)) (int (v0 - a0 t) t dt over [0, t*]).
    The regularisation (slip_bounds) moves the volumes by what it allows and no more; the
    quadrature's own error is bounded by the change from h to h/2. After t* the volumes stay
    put to the regularisation's share. Wear takes no energy: the balance E - E0 - W holds as
    without it (the contact's friction dissipates m v0^2 / 7)."""
    v0, mu, rad, m, vs = 2.0, 0.3, 0.1, 1.0, 1e-3
    k, c0, c1 = ARCHARD_K / HARDNESS, 1.0, 0.5
    wear = [{"name": "archard", "law": "archard", "load": "floor.normal_force",
             "coefficient": k},
            {"name": "knee", "law": "knee", "load": "floor.friction_force", "coefficient": k,
             "slide_roll": [c0, c1, 0.0, 0.0]}]
    sc, _n, t = tilted(v0, mu, rad, m, vs=vs, wear=wear)
    t_end, f = 0.4, m * G
    runs = [mbdk.simulate(sc, "rk4", h=h, t_end=t_end, every=every)
            for h, every in ((1e-4, 10), (5e-5, 20))]
    r = runs[1]
    assert np.array_equal(r.t, runs[0].t)
    a0 = 3.5 * mu * G
    t_star, s_star = 2 * v0 / (7 * mu * G), v0 * v0 / (7 * mu * G)
    lo, zone, t_vs = slip_bounds(v0, a0, vs, t_end)
    assert lo < s_star < lo + zone
    w = r.wear["archard"]
    quad = abs(w[-1] - runs[0].wear["archard"][-1])
    sliding = r.t < t_vs - 1e-3
    closed = k * f * (v0 * r.t[sliding] - 1.75 * mu * G * r.t[sliding] ** 2)
    assert np.abs(w[sliding] - closed).max() < 1e-9 * w[-1]
    assert k * f * lo - quad <= w[-1] <= k * f * (lo + zone) + quad
    print(f"archard: V = {w[-1]:.10e} m^3, k F S = {k * f * s_star:.10e} "
          f"(relative {w[-1] / (k * f * s_star) - 1:.2e}; the regularisation allows "
          f"{max(s_star - lo, lo + zone - s_star) / s_star:.2e}, the quadrature "
          f"{quad / w[-1]:.1e})")
    # rolling from t*: the volume no longer grows, but for the regularised tail of the slip
    # (from the first sample at or after t*: the volume never falls)
    after = w[-1] - w[np.searchsorted(r.t, t_star)]
    assert -quad <= after <= k * f * zone + quad
    v = r.v[:, :3] @ t
    # m v r + I omega = m v0 r: v = 5/7 v0 + 2/7 s, the slip s below vs / (1 + a0 (t - t_vs) / vs)
    tail = vs / (1 + a0 * (t_end - t_vs) / vs)
    assert -1e-9 <= v[-1] - 5 / 7 * v0 <= 2 / 7 * tail + 1e-9
    cw = r.wear["knee"]
    quad_k = abs(cw[-1] - runs[0].wear["knee"][-1])
    knee_lo = k * mu * f * (c0 * lo + c1 * (v0 * t_vs ** 2 / 2 - a0 * t_vs ** 3 / 3))
    knee_closed = k * mu * f * (c0 * s_star + c1 * v0 ** 3 / (6 * a0 ** 2))
    assert knee_lo - quad_k <= cw[-1] <= knee_lo + k * mu * f * (c0 + c1 * t_end) * zone + quad_k
    assert knee_lo <= knee_closed
    print(f"knee: V = {cw[-1]:.10e} m^3, closed form {knee_closed:.10e} "
          f"(relative {cw[-1] / knee_closed - 1:.2e})")
    lost = r.energy[0] - r.energy[-1]
    assert abs(lost - m * v0 ** 2 / 7) < 1e-6
    assert np.abs(r.energy_balance()).max() < 1e-6 * lost


def brake(mu=0.3, omega0=20.0, k=1e5, delta0=1e-4, vs=1e-3, wear=None):
    """A solid ball (m = 1, r = 0.05) held at its centre by a spherical joint, spinning at
    omega0 about x, pressed into a ground sphere (R = 0.1) below it by delta0: a constant normal
    force k delta0 through the centres (the joint takes it), and the friction at the contact
    point brakes the spin."""
    m, rad, big = 1.0, 0.05, 0.1
    d = {"scene": {"name": "brake"},
         "body": [{"name": "ball", "kind": "spatial", "mass": m,
                   "shape": {"type": "sphere", "radius": rad}, "omega_body": [omega0, 0, 0]}],
         "joint": [{"type": "spherical", "name": "pivot", "body1": "ball", "at": [0, 0, 0]}],
         "force": [contact(shape1={"type": "sphere", "radius": rad},
                           shape2={"type": "sphere", "radius": big,
                                   "centre": [0, 0, -(rad + big - delta0)]},
                           stiffness=k, friction={"static": mu, "dynamic": mu,
                                                  "stiction_speed": vs,
                                                  "transition_speed": 2 * vs})]}
    if wear:
        d["wear"] = wear
    return scene_from_dict(d, "brake.toml")


@pytest.mark.parametrize("formulation", ["reduced", "projection", "baumgarte"])
def test_a_braked_ball_wears_the_energy_it_loses(formulation):
    """Two spheres (sphere_sphere): the ball's slip speed at the contact is omega r, braked by
    the friction moment mu F r: omega = omega0 - mu F r t / I until it stops (a0 = mu F r^2 /
    I), having slid S = I omega0^2 / (2 mu F), where friction has taken its kinetic energy
    I omega0^2 / 2 (= mu F S). Archard's volume is k F S; the bounds are slip_bounds'. The
    formulations differ in how they keep the joint, not in the wear state they carry."""
    mu, omega0, kc, delta0, vs = 0.3, 20.0, 1e5, 1e-4, 1e-3
    m, rad = 1.0, 0.05
    k = ARCHARD_K / HARDNESS
    sc = brake(mu, omega0, kc, delta0, vs, [{"name": "pad", "law": "archard",
                                             "load": "floor.normal_force", "coefficient": k}])
    t_end = 0.3
    runs = [mbdk.simulate(sc, "rk4", h=h, t_end=t_end, every=every, formulation=formulation)
            for h, every in ((1e-4, 10), (5e-5, 20))]
    r = runs[1]
    f, inertia = kc * delta0, 0.4 * m * rad * rad
    a0 = mu * f * rad * rad / inertia
    lo, zone, t_vs = slip_bounds(omega0 * rad, a0, vs, t_end)
    s_star = inertia * omega0 ** 2 / (2 * mu * f)
    assert lo < s_star < lo + zone
    braking = r.t < t_vs - 1e-3
    om = r.omega_body("ball")[:, 0]
    assert np.abs(om[braking] - (omega0 - mu * f * rad * r.t[braking] / inertia)).max() < 1e-9
    w = r.wear["pad"]
    quad = abs(w[-1] - runs[0].wear["pad"][-1])
    assert k * f * lo - quad <= w[-1] <= k * f * (lo + zone) + quad
    print(f"{formulation}: V = {w[-1]:.10e} m^3, k F S = {k * f * s_star:.10e} "
          f"(relative {w[-1] / (k * f * s_star) - 1:.2e})")
    lost = r.energy[0] - r.energy[-1]
    assert abs(lost - inertia * omega0 ** 2 / 2) < 1e-3 * lost
    assert np.abs(r.energy_balance()).max() < 1e-6 * lost


def test_wear_is_a_state_of_its_own():
    """The wear states do not act back: the same scene without them runs to the same bits
    (fixed steps: the error-controlled methods' error norm counts the states, so their steps
    may differ), its state is the body's 13 values and its result has no wear. The rate at a
    state is the law's: at the start the sphere slides at v0 under F = m g, V' = k m g v0 (the
    kernel's y', mbdk.spatial_model.evaluate_spatial, to the roundoff of the contact's
    penetration); the scene report lists the effect."""
    k, v0 = ARCHARD_K / HARDNESS, 2.0
    wear = [{"name": "w", "law": "archard", "load": "floor.normal_force", "coefficient": k}]
    with_wear, _n, _t = tilted(v0, wear=wear)
    without, _n, _t = tilted(v0)
    a = mbdk.simulate(with_wear, "rk4", h=1e-4, t_end=0.05)
    b = mbdk.simulate(without, "rk4", h=1e-4, t_end=0.05)
    assert np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v)
    assert b.wear == {} and b.q.shape[1] + b.v.shape[1] == 13 and a.wear["w"][0] == 0.0
    assert a.manifest["wear"]["w"].startswith("archard on floor.normal_force")
    rate = evaluate_spatial(with_wear)["ydot"][-1]
    # the normal force k_c d comes from a penetration d = m g / k_c = 9.81e-6 m taken between
    # coordinates of about 0.5 m: its roundoff, and the rate's, is some eps 0.5 / d (1e-11)
    pen = 1.0 * G / 1e6
    assert abs(rate - k * G * v0) < 16 * np.finfo(float).eps * 0.5 / pen * k * G * v0
    assert mbdk.scene_report(with_wear).effects == ["w"]


@pytest.mark.parametrize("method, kw", [
    ("trapezoidal_index3", dict(h=1e-4)), ("generalized_alpha", dict(h=1e-4)),
    ("ida", dict(rtol=1e-6)), ("ida", dict(rtol=1e-6, formulation="ggl")),
    ("bdf", dict(rtol=1e-6, formulation="i3")), ("bdf", dict(rtol=1e-6, formulation="si2"))])
def test_forms_without_a_place_for_wear_refuse_it_by_name(method, kw):
    """The index-3 family's state [q, v] and the DAE's [q, v, lambda] have no place for the
    volumes: each refuses the scene naming its wear elements (as on planar scenes), before the
    kernel, which would refuse it too (MBDK_ERR_NOT_APPLICABLE)."""
    sc = brake(wear=[{"name": "pad", "law": "archard", "load": "floor.normal_force",
                      "coefficient": 1e-13}])
    with pytest.raises(mbdk.NotApplicableError, match=r"no place for the wear states \(pad\)"):
        mbdk.simulate(sc, method, t_end=0.01, **kw)


@pytest.mark.parametrize("wear, field", [
    ({"law": "gear", "load": "floor.normal_force", "coefficient": 1.0, "radius": 1e-3,
      "temperature": 300.0}, "field 'law' = 'gear'"),
    ({"law": "paris", "load": "floor.normal_force", "coefficient": 1.0}, "law"),
    ({"law": "archard", "load": "wall.normal_force", "coefficient": 1.0},
     "'wall.normal_force' names no contact; contacts: floor"),
    ({"law": "archard", "load": "floor.friction_force", "coefficient": 1.0}, "has no friction"),
    ({"law": "archard", "load": "floor", "coefficient": 1.0}, "CONTACT.normal_force"),
    ({"law": "archard", "load": "floor.normal_force", "coefficient": -1.0}, "coefficient"),
    ({"law": "knee", "load": "floor.normal_force", "coefficient": 1.0,
      "slide_roll": [1.0, 2.0]}, "slide_roll"),
])
def test_bad_spatial_wear_is_named(wear, field):
    """The planar reader's fields and errors (tests/test_contact.py), each naming the file,
    the element and the field; and the gear law, whose speed is a planar gear pair's."""
    d = {"scene": {"name": "bad"},
         "body": [{"name": "ball", "kind": "spatial", "mass": 1.0, "inertia": [0.01] * 3,
                   "position": [0, 0, 0.2]}],
         "force": [contact(stiffness=1e5)], "wear": [{"name": "w", **wear}]}
    with pytest.raises(SceneError) as exc:
        scene_from_dict(d, "bad.toml")
    msg = str(exc.value)
    assert "bad.toml" in msg and "wear 'w'" in msg and field in msg, msg


def test_wear_changed_in_python_is_checked_by_name():
    """A Wear edited after reading meets the reader's checks before the kernel does."""
    sc = brake(wear=[{"name": "pad", "law": "archard", "load": "floor.normal_force",
                      "coefficient": 1e-13}])
    sc.wear[0].coefficient = -1.0
    with pytest.raises(SceneError, match="wear 'pad': field 'coefficient'"):
        mbdk.simulate(sc, "rk4", h=1e-4, t_end=0.01)
    sc.wear[0].coefficient = 1e-13
    sc.wear[0].load = "floor.friction_force"
    sc.forces[0].reals = sc.forces[0].reals[:15] + (0.0, 0.0) + sc.forces[0].reals[17:]
    with pytest.raises(SceneError, match="contact 'floor' has no friction"):
        mbdk.simulate(sc, "rk4", h=1e-4, t_end=0.01)


def test_the_kernel_refuses_bad_wear_entries():
    """The tables from another door (a C embedder's): a wear entry whose column is not a
    contact, whose law is gear or unknown, whose load code is neither 1 nor 2, whose friction
    load has no friction, or whose k is negative, is invalid input; the scene's own entry
    evaluates."""
    sc = brake(wear=[{"name": "pad", "law": "archard", "load": "floor.normal_force",
                      "coefficient": 1e-13}])
    tab = spatial_tables(sc)
    nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = tab
    y0 = np.concatenate([sc.state0(), [0.0]])

    def status(fb=fbody, fr=freal):
        *_, st = _kernel.spatial_residuals(mass, inertia, nj, jtype, jbody, jreal, nf, ftype,
                                           fb, fr, 1, y0, 0.0, y0, max(sc.rows, 1))
        return st

    assert status() == mbdk.Status.SUCCESS
    w = nf - 1
    for row, value in ((0, 0), (0, 2), (0, w + 1), (1, 2), (1, 4)):
        fb = fbody.copy()
        fb[row, w] = value
        assert status(fb=fb) == mbdk.Status.ERR_INVALID_INPUT, (row, value)
    smooth = freal.copy()
    smooth[5, w] = 2.0
    smooth[15:17, 0] = 0.0
    for fr_row, value, fr in ((5, 3.0, freal), (5, 1.5, freal), (0, -1e-13, freal)):
        bad = fr.copy()
        bad[fr_row, w] = value
        assert status(fr=bad) == mbdk.Status.ERR_INVALID_INPUT, (fr_row, value)
    assert status(fr=smooth) == mbdk.Status.ERR_INVALID_INPUT


def test_switching_angle_sets_carries_the_wear():
    """A sliding sphere in 1-2-3 angles rolls its beta through the set's lock: the run goes on
    in the 3-1-3 set (switch_angles) and its volume goes on from where it was, ending where the
    quaternion run's does (the same motion in other coordinates: to the integration's
    accuracy)."""
    k = ARCHARD_K / HARDNESS
    wear = [{"name": "w", "law": "archard", "load": "floor.normal_force", "coefficient": k}]
    sc, _n, _t = tilted(2.0, wear=wear)
    quat = mbdk.simulate(sc, "rk4", h=1e-4, t_end=0.4, every=10)
    angles = mbdk.simulate(replace(sc, rotation="cardan123"), "rk4", h=1e-4, t_end=0.4,
                           every=10, switch_angles=0.1)
    assert angles.manifest["switches"]
    assert angles.t.shape == quat.t.shape and np.abs(angles.t - quat.t).max() < 1e-12
    assert np.abs(angles.wear["w"] - quat.wear["w"]).max() < 1e-8 * quat.wear["w"][-1]
    # the contact outputs go on across the switches too: the same as the quaternion run's at
    # every sample (they depend on the motion, not on its coordinates), to the integration's
    # accuracy on each field's scale: the static penetration, the sliding speed v0 for its rate
    # (roundoff in both runs: the sphere stays on the plane), m g for the forces
    scale = {"penetration": 1e-5, "penetration_rate": 2.0, "normal_force": 9.81,
             "friction_force": 9.81}
    assert angles.contacts.keys() == quat.contacts.keys()
    for name, c in quat.contacts.items():
        assert c.keys() == scale.keys()
        for field, v in c.items():
            assert angles.contacts[name][field].shape == v.shape, (name, field)
            assert np.abs(angles.contacts[name][field] - v).max() < 1e-7 * scale[field], field
    with pytest.raises(mbdk.NotApplicableError, match="t_eval with switch_angles"):
        mbdk.simulate(replace(sc, rotation="cardan123"), "rk45", t_end=0.4,
                      t_eval=[0.1, 0.2], switch_angles=0.1)


def test_contact_outputs_of_the_sliding_sphere():
    """SceneResult.contacts on a spatial contact (the sphere sliding to its rolling speed, the
    test above): the normal force is m g (the sphere rests on the plane at its static
    penetration) and, while it slides, the friction force is mu m g; once it rolls the friction
    falls to what keeps it rolling (none on a level plane: below 1e-3 of mu m g at the end)."""
    v0, mu, rad = 2.0, 0.3, 0.1
    sc, n, t = tilted(v0, mu, rad)
    r = mbdk.simulate(sc, "rk4", t_end=0.4, h=1e-4, every=10)
    (name, c), = r.contacts.items()
    m = sc.bodies[0].mass
    assert np.allclose(c["normal_force"], m * G, rtol=1e-6)
    sliding = r.t < (v0 - 2e-3) / (3.5 * mu * G) - 2e-3
    assert np.allclose(c["friction_force"][sliding][1:], mu * m * G, rtol=1e-6)
    assert c["friction_force"][-1] < 1e-3 * mu * m * G
    assert np.all(c["penetration"] > 0)


def test_contact_outputs_name_a_sample_without_frames_as_nan():
    """A sample whose frames cannot be built (a NaN quaternion, as a blown-up run's last
    sample) has NaN contact outputs; the samples around it keep theirs (the static normal
    force m g of the sliding sphere): one bad sample loses nothing else."""
    from mbdk.plan import Request, make_plan
    from mbdk.run_spatial import _contacts
    sc, _n, _t = tilted(2.0)
    r = mbdk.simulate(sc, "rk4", h=1e-4, t_end=0.01, every=10)
    y = np.concatenate([r.q, r.v], axis=1).T.copy()
    y0 = y[:, 0].copy()
    y[3:7, 2] = np.nan
    plan = make_plan(sc, Request(method="rk4", t_end=0.01, h=1e-4))
    (_name, c), = _contacts(sc, plan, y0, y, 0.0).items()
    assert np.all(np.isnan([v[2] for v in c.values()]))
    keep = np.arange(y.shape[1]) != 2
    assert np.allclose(c["normal_force"][keep], sc.bodies[0].mass * G, rtol=1e-6)
