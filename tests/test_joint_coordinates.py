"""Joint coordinates for spatial scenes (simulate(..., coordinates="joint"),
kernel/src/spatial/mbdk_joint_coords.f90): the same motion as the absolute coordinates, the
tree's joints held to roundoff, a closed loop's cut rows kept, the published references, and
the refusals by name.

The absolute model (mbdk_spatial_model) is the independent reference here: it shares the
forces and the cut joints' rows with the joint model but not its kinematics, mass matrix,
bias accelerations or solve, so that an error in any of those moves the two runs apart by far
more than their difference (rk4 at the same small h; both errors are far below it).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import mbdk
from mbdk.errors import Status
from mbdk.plan import Request, make_plan
from mbdk.run_spatial import run_spatial
from mbdk.scene_file import scene_from_dict

G = 9.81


def body(name, mass=1.0, inertia=(0.1, 0.2, 0.25), **kw):
    return {"name": name, "kind": "spatial", "mass": mass, "inertia": list(inertia), **kw}


def tree_scene(closed: bool):
    """A chain from the ground over every kind of tree joint, in general directions: a
    revolute (a), a cylindrical (b on a), a prismatic (c on b), a fixed joint (d on c) and a
    revolute (e on d), loaded by gravity, a spring-damper, a point force and a torque, from
    rest. closed: e is also held to the ground by a spherical joint at its far end, a loop
    whose three rows the joint coordinates keep as cut rows (two coordinates are left)."""
    joints = [
        {"name": "ra", "type": "revolute", "body1": "a", "at": [0.0, 0.0, 0.0],
         "axis": [0.0, 0.6, 0.8]},
        {"name": "cb", "type": "cylindrical", "body1": "b", "body2": "a",
         "at": [0.4, 0.1, 0.0], "axis": [1.0, 0.0, 0.0]},
        {"name": "pc", "type": "prismatic", "body1": "c", "body2": "b",
         "at": [0.6, 0.3, 0.1], "axis": [0.0, 0.0, 1.0]},
        {"name": "fd", "type": "fixed", "body1": "d", "body2": "c", "at": [0.7, 0.5, 0.2]},
        {"name": "re", "type": "revolute", "body1": "e", "body2": "d",
         "at": [0.9, 0.6, 0.1], "axis": [0.3, 0.0, 0.954]}]
    if closed:
        joints.append({"name": "tip", "type": "spherical", "body1": "e",
                       "at": [1.2, 0.9, -0.2]})
    return scene_from_dict({
        "scene": {"name": "tree_closed" if closed else "tree"},
        "body": [body("a", 1.5, (0.02, 0.05, 0.06), position=[0.2, 0.05, 0.0],
                      cardan123=[0.1, 0.2, 0.3]),
                 body("b", 2.0, (0.03, 0.02, 0.04), position=[0.5, 0.2, 0.05],
                      cardan123=[-0.2, 0.1, 0.4]),
                 body("c", 0.8, (0.01, 0.01, 0.02), position=[0.6, 0.35, 0.15],
                      cardan123=[0.3, -0.1, 0.2]),
                 body("d", 1.2, (0.02, 0.03, 0.02), position=[0.8, 0.5, 0.15],
                      cardan123=[0.0, 0.4, -0.2]),
                 body("e", 1.0, (0.01, 0.04, 0.04), position=[1.05, 0.75, -0.05],
                      cardan123=[0.5, 0.0, 0.1])],
        "joint": joints,
        "force": [{"type": "gravity", "g": [0.0, 0.0, -G]},
                  {"type": "spring_damper", "body1": "e", "point1": [0.1, 0.0, 0.0],
                   "at2": [1.5, 0.2, 0.4], "stiffness": 40.0, "damping": 0.5,
                   "rest_length": 0.3},
                  {"type": "point_force", "body": "c", "point": [0.0, 0.1, 0.0],
                   "force": [1.0, -2.0, 0.5]},
                  {"type": "torque", "body": "b", "torque": [0.2, 0.3, -0.1]}]},
        "tree.toml")


def four_bar_3d(rocker_mass_factor=1.0, doubled=False):
    """The built-in planar four-bar as spatial bars turning about z (gravity along -y): the
    tree takes A (crank on the ground), B (coupler on the crank) and C, whose table lists the
    coupler, the rocker's parent on the tree, as body1; D is cut, its three rows out of the
    plane held by the tree itself (no gradient in joint coordinates) and its two in the plane
    kept. rocker_mass_factor scales the rocker's mass (and so its inertia); doubled adds a
    second revolute joint on A's axis, whose five cut rows the tree holds."""
    planar = mbdk.scene("four_bar")
    q0 = planar.q0()
    bodies = []
    for k, b in enumerate(planar.bodies):
        bodies.append(body(b.name, b.mass * (rocker_mass_factor if b.name == "rocker" else 1.0),
                           position=[q0[3 * k], q0[3 * k + 1], 0.0],
                           cardan123=[0.0, 0.0, q0[3 * k + 2]]))
        del bodies[-1]["inertia"]
        bodies[-1]["shape"] = {"type": "bar", "length": math.sqrt(12 * b.inertia / b.mass)}
    joints = [{"name": j.name, "type": "revolute", "body1": j.body1, "body2": j.body2,
               "point1": [*j.point1, 0.0], "point2": [*j.point2, 0.0], "axis": [0, 0, 1]}
              for j in planar.joints]
    if doubled:
        joints.append(dict(joints[0], name="A2"))
    return scene_from_dict({"body": bodies, "joint": joints,
                            "force": [{"type": "gravity", "g": [0.0, -G, 0.0]}]},
                           "four_bar_3d.toml")


def state_gap(ra, rj, nb):
    """The largest difference of two runs' samples: positions, quaternions (either sign) and
    velocities."""
    qa, qj = ra.q.reshape(len(ra.t), nb, 7), rj.q.reshape(len(rj.t), nb, 7)
    dquat = np.minimum(np.abs(qa[..., 3:] - qj[..., 3:]).max(axis=-1),
                       np.abs(qa[..., 3:] + qj[..., 3:]).max(axis=-1))
    return max(np.abs(qa[..., :3] - qj[..., :3]).max(), dquat.max(),
               np.abs(ra.v - rj.v).max())


@pytest.mark.parametrize("closed", [False, True])
def test_every_tree_joint_moves_as_in_absolute_coordinates(closed):
    """The chain of every tree joint kind (tree_scene), open and closed by a spherical joint:
    rk4 at h = 1e-4 over 0.5 s in joint and in absolute coordinates, a motion of tenths of a
    metre and radian: both runs' truncation errors lie far below the bound, and a sign or term
    wrong in a turn's, slide's or fixed joint's kinematics, bias, column or mass term parts
    them by far more. The tree's joints hold at every sample to roundoff, where the
    absolute run's drift by its truncation."""
    sc = tree_scene(closed)
    kw = dict(h=1e-4, t_end=0.5, every=500)
    ra = mbdk.simulate(sc, "rk4", **kw)
    rj = mbdk.simulate(sc, "rk4", coordinates="joint", **kw)
    assert rj.success and rj.manifest["coordinates"] == "joint"
    # the motion is not small: a wrong term shows
    assert np.abs(ra.q[-1] - ra.q[0]).max() > 0.05
    assert state_gap(ra, rj, 5) < 1e-11
    tree = rj.manifest["joint_tree"]
    assert tree["joint_coordinates"] == 5
    assert tree["cut"] == (["tip"] if closed else [])
    if not closed:
        # no cut row: every row is a tree joint's, held by construction
        assert np.max(rj.residuals[:, 0]) < 1e-13
        assert np.max(rj.residuals[:, 1]) < 1e-13
    # the energy balance (kinetic + potential - work of the damper and loads, 8.3 J), kept to
    # the watch's second-order quadrature of the work (it falls fourfold as h halves), and the
    # same as the absolute run's
    e_j = rj.energy - rj.energy_parts["work"]
    e_a = ra.energy - ra.energy_parts["work"]
    assert np.max(np.abs(e_j - e_j[0])) < 3e-8
    assert np.max(np.abs(e_j - e_a)) < 1e-11


@pytest.mark.parametrize("name, t_end, tol, lam_tol", [("flyball_governor", 0.5, 1e-9, 1e-7),
                                                       ("bricard", 2.0, 1e-11, 1e-9)])
def test_the_iftomm_mechanisms_move_as_in_absolute_coordinates(name, t_end, tol, lam_tol):
    """The governor (a tree: four coordinates, its start spinning at 2 pi rad/s, which the
    joint rates are fitted to) and Bricard's linkage (five turns and the cut joint F, whose
    five rows have rank four in joint coordinates: one is left out at the start): rk4 at
    h = 2e-5 in both coordinates. The governor's bound is wider: its stiff spring-dampers (8e5
    N/m and 4e4 N s/m) amplify the velocities' roundoff, and its multipliers (solved at the
    samples on the absolute state) take the dampers' forces of those velocities."""
    sc = mbdk.scene(name)
    kw = dict(h=2e-5, t_end=t_end, every=5000)
    ra = mbdk.simulate(sc, "rk4", **kw)
    rj = mbdk.simulate(sc, "rk4", coordinates="joint", **kw)
    assert state_gap(ra, rj, len(sc.bodies)) < tol
    scale = np.abs(ra.multipliers).max()
    assert np.abs(ra.multipliers - rj.multipliers).max() < lam_tol * scale
    if name == "bricard":
        assert rj.manifest["joint_tree"]["cut"] == ["F"]
        assert np.max(rj.residuals[:, 0]) < 1e-12     # the cut rows' drift


def test_the_iftomm_mechanisms_in_joint_coordinates_meet_the_exudyn_reference():
    """Bricard's P3 and the governor's sleeve against the Exudyn values that
    tests/test_spatial.py keeps (converged to about 2e-8 and 1e-8), error-controlled in joint
    coordinates; and rk4's order in joint coordinates: its error on Bricard at 2 s, against
    dopri54 at rtol 1e-12, falls sixteenfold per halving of h from 0.04 s."""
    r = mbdk.simulate(mbdk.scene("bricard"), "dopri54", rtol=1e-10, atol=1e-12, t_end=2.0,
                      dt_out=2.0, coordinates="joint")
    p3 = r.position("rod2") + np.einsum("kij,j->ki", r.orientation("rod2"), [0.0, -0.5, 0.0])
    assert np.max(np.abs(p3[-1] - (-0.778135373, -0.980352683, -0.197252671))) < 5e-8
    r = mbdk.simulate(mbdk.scene("flyball_governor"), "bdf", rtol=1e-10, atol=1e-12,
                      t_end=0.5, dt_out=0.5, coordinates="joint")
    assert abs(r.position("slider")[-1, 2] - 0.7432494260) < 3e-8
    sc = mbdk.scene("bricard")
    ref = mbdk.simulate(sc, "dopri54", rtol=1e-12, atol=1e-14, t_end=2.0, dt_out=2.0,
                        coordinates="joint")
    errs = [np.abs(mbdk.simulate(sc, "rk4", h=h, t_end=2.0, every=round(2.0 / h),
                                 coordinates="joint").q[-1] - ref.q[-1]).max()
            for h in (0.04, 0.02, 0.01)]
    assert 13 < errs[0] / errs[1] < 19 and 13 < errs[1] / errs[2] < 19, errs


def test_euler_cromer_takes_the_joint_coordinates_state():
    """[theta, theta'] is Euler-Cromer's layout (absolute coordinates refuse it): on the
    governor, first order, its error halving with h against a tight dopri54 run."""
    sc = mbdk.scene("flyball_governor")
    with pytest.raises(mbdk.NotApplicableError, match="coordinates='joint'"):
        mbdk.simulate(sc, "euler_cromer", h=1e-4, t_end=0.1)
    ref = mbdk.simulate(sc, "dopri54", rtol=1e-11, atol=1e-13, t_end=0.1, dt_out=0.1,
                        coordinates="joint")
    errs = [np.abs(mbdk.simulate(sc, "euler_cromer", h=h, t_end=0.1, every=int(0.1 / h),
                                 coordinates="joint").q[-1] - ref.q[-1]).max()
            for h in (2e-5, 1e-5)]
    assert 1.7 < errs[0] / errs[1] < 2.3, errs


def test_a_driven_loop_in_joint_coordinates_follows_its_driver():
    """The parallelogram in 3D with its third crank (31 rows, rank 24 in absolute
    coordinates), its crank's angle driven at -1 rad/s: three turns on the tree, the coupler's
    hinge to crank 2, crank 3's two hinges and the driver cut. The driver is a rheonomic cut
    row (Phi_t, and its f'' in gamma); the crank's angle is pi/3 - t (analytic) while the run
    stays clear of the flat pose at pi/3."""
    from test_spatial import driven_parallelogram
    sc = driven_parallelogram(True)
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.8, every=100, coordinates="joint")
    ang = [math.atan2(rot[1, 0], rot[0, 0]) for rot in r.orientation("crank1")]
    assert np.max(np.abs(np.array(ang) - (math.pi / 3 - r.t))) < 1e-9
    assert "drive" in r.manifest["joint_tree"]["cut"]


def test_the_reduced_form_in_joint_coordinates_names_a_singular_pose():
    """The same driven parallelogram run into its flat pose (t = pi/3): its cut rows lose a
    rank there, and the reduced form stops by name (SingularMatrixError) before it, as in
    absolute coordinates, rather than jump to another branch."""
    from test_spatial import driven_parallelogram
    sc = driven_parallelogram(True)
    with pytest.raises(mbdk.SingularMatrixError) as err:
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.5, coordinates="joint")
    t_stop = err.value.result.t[-1]
    assert 0.9 < t_stop < math.pi / 3


def test_joint_coordinates_refuse_what_they_do_not_take_by_name():
    """Each refusal names what to change: a body on a universal joint alone, a planar scene,
    the index-3 and DAE methods, the penalty and projection formulations, Euler-Cromer with a
    spherical joint on the tree, an angle set, an unknown coordinates name."""
    cross = scene_from_dict({
        "body": [body("a", position=[0.5, 0.0, 0.0])],
        "joint": [{"name": "u", "type": "universal", "body1": "a", "at": [0.0, 0.0, 0.0],
                   "axis1": [0.0, 0.0, 1.0], "axis2": [0.0, 1.0, 0.0]}],
        "force": [{"type": "gravity", "g": [0.0, 0.0, -G]}]}, "cross.toml")
    with pytest.raises(mbdk.NotApplicableError, match="body 'a'.*u \\(universal\\)"):
        mbdk.simulate(cross, "rk4", h=1e-3, t_end=0.01, coordinates="joint")
    with pytest.raises(mbdk.NotApplicableError, match="euler_cromer.*spherical"):
        mbdk.simulate(mbdk.scene("heavy_top"), "euler_cromer", h=1e-3, t_end=0.01,
                      coordinates="joint")
    with pytest.raises(mbdk.NotApplicableError, match="spatial scenes"):
        mbdk.simulate(mbdk.scene("four_bar"), "rk4", h=1e-3, t_end=0.01,
                      coordinates="joint")
    sc = mbdk.scene("bricard")
    for method, kw in (("trapezoidal_index3", {}), ("bdf", dict(formulation="si2")),
                       ("rk4", dict(formulation="penalty")),
                       ("rk4", dict(formulation="projection"))):
        with pytest.raises(mbdk.NotApplicableError, match="coordinates='joint'"):
            mbdk.simulate(sc, method, h=1e-3, t_end=0.01, coordinates="joint", **kw)
    with pytest.raises(mbdk.InvalidInputError, match="coordinates = 'relative'"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01, coordinates="relative")
    angles = tree_scene(False)
    angles.rotation = "cardan123"
    with pytest.raises(mbdk.NotApplicableError, match="rotation"):
        mbdk.simulate(angles, "rk4", h=1e-3, t_end=0.01, coordinates="joint")


def test_the_cut_rows_drift_is_watched():
    """The watch sees the absolute state of a joint run: Bricard's cut rows drift on the
    reduced form, and a watch tolerance below that drift stops the run by name
    (ConstraintDriftError) at a check, where the default tolerance lets it finish."""
    sc = mbdk.scene("bricard")
    r = mbdk.simulate(sc, "rk4", h=1e-2, t_end=2.0, coordinates="joint")
    drift = np.max(r.residuals[:, 0])
    assert drift > 1e-9
    with pytest.raises(mbdk.ConstraintDriftError):
        mbdk.simulate(sc, "rk4", h=1e-2, t_end=2.0, coordinates="joint",
                      watch={"position": drift / 10})


def test_an_fmu_refuses_joint_coordinates(tmp_path):
    """An FMU steps its scene by the C stepper, which keeps absolute coordinates (and refuses
    mbdk_spatial_options.coordinates = 1 with MBDK_ERR_NOT_APPLICABLE: kernel/examples/
    c_spatial.c checks it): export_fmu refuses coordinates='joint' by name and writes
    nothing."""
    out = tmp_path / "gov.fmu"
    with pytest.raises(mbdk.NotApplicableError, match="coordinates = 'joint'"):
        mbdk.export_fmu(mbdk.scene("flyball_governor"), out, "rk4", h=1e-3,
                        coordinates="joint")
    assert not out.exists()


@pytest.mark.parametrize("factor", [1.0, 1e-6])
def test_a_light_body_in_a_loop_is_no_singular_pose(factor):
    """The four-bar in 3D (four_bar_3d), its rocker a millionth as heavy: S = G (J^T M J)^-1
    G^T then has a pivot far below MBDK_SPATIAL_NEAR_PIVOT of its diagonal at every pose,
    while the geometry's rows are far from dependent. The reduced form's near test is the
    geometry's (as in absolute coordinates), so the run goes on and moves as the absolute one,
    whose own test is the geometry's too; a test on S would stop it at its first evaluation."""
    sc = four_bar_3d(factor)
    kw = dict(h=1e-3, t_end=1.0, every=100)
    ra = mbdk.simulate(sc, "rk4", **kw)
    rj = mbdk.simulate(sc, "rk4", coordinates="joint", **kw)
    tree = rj.manifest["joint_tree"]
    assert tree["cut"] == ["D"] and tree["tree"][2] == "rocker on C (turn, from coupler)"
    assert np.abs(ra.q[-1] - ra.q[0]).max() > 1.0
    assert state_gap(ra, rj, 3) < 1e-8


def test_a_joint_doubled_on_the_tree_leaves_no_row_to_solve():
    """A second revolute joint on the crank's axis: its five rows are held by the tree at every
    pose (no gradient in joint coordinates at the start, nor at a second pose), so none is
    solved, and the run is the undoubled one's, while the absolute coordinates carry five
    redundant rows."""
    kw = dict(h=1e-3, t_end=0.5, every=100, coordinates="joint")
    r1 = mbdk.simulate(four_bar_3d(), "rk4", **kw)
    r2 = mbdk.simulate(four_bar_3d(doubled=True), "rk4", **kw)
    assert r2.manifest["joint_tree"]["cut"] == ["D", "A2"]
    assert np.abs(r1.q - r2.q).max() < 1e-14 and np.abs(r1.v - r2.v).max() < 1e-13


def test_baumgarte_in_joint_coordinates_acts_on_the_cut_rows():
    """Bricard by rk4 at h = 1e-2 on the baumgarte form: with alpha = beta = 0 it is the
    reduced form's run exactly; with alpha = beta = 5 1/s the cut rows' drift stays at the
    size of the reduced form's, where a sign of the terms turned would make it grow as
    exp(5 t)."""
    sc = mbdk.scene("bricard")
    kw = dict(h=1e-2, t_end=2.0, coordinates="joint")
    red = mbdk.simulate(sc, "rk4", **kw)
    zero = mbdk.simulate(sc, "rk4", formulation="baumgarte", alpha=0.0, beta=0.0, **kw)
    assert np.array_equal(red.q, zero.q)
    r = mbdk.simulate(sc, "rk4", formulation="baumgarte", alpha=5.0, beta=5.0, **kw)
    assert np.max(r.residuals[:, 0]) < 1e-6
    assert np.max(r.residuals[:, 1]) < 1e-5
    assert 0 < np.abs(r.q[-1] - red.q[-1]).max() < 1e-5


def test_the_kernel_refuses_a_start_off_a_tree_joint():
    """The tree is built from the start's pose, so a start off a tree joint would become a
    rigid offset of the motion: the kernel refuses it (MBDK_ERR_INCONSISTENT_INITIAL) even
    when called past the Python layer's own check of the start, which the absolute
    coordinates' run, past the same check, does not."""
    sc = four_bar_3d()
    sc.bodies[2].position = np.asarray(sc.bodies[2].position) + [1e-6, 0.0, 0.0]
    for coords, want in (("absolute", Status.SUCCESS), ("joint", Status.ERR_INCONSISTENT_INITIAL)):
        plan = make_plan(sc, Request(method="rk4", t_end=0.01, h=1e-3, coordinates=coords,
                                     assemble_initial=False))
        assert run_spatial(sc, plan).result.status == want, coords


@pytest.mark.parametrize("name, t_end, tol", [("heavy_top", 1.0, 1e-11),
                                              ("spatial_double_pendulum", 1.0, 1e-11),
                                              ("chain", 0.2, 1e-7)])
def test_spherical_joints_on_the_tree_move_as_in_absolute_coordinates(name, t_end, tol):
    """A spherical joint on the tree turns its body by a quaternion relative to its parent,
    with the body-frame relative angular velocity as its three rates: the heavy top (one ball
    on the ground, spinning), the spatial double pendulum (two) and the spatial chain of 8 bars
    released from a zigzag out of its plane (eight; its large accelerations make the two runs'
    truncation errors larger). rk4 at h = 1e-4 in both coordinates; every joint held to
    roundoff; and the relative quaternions' norm plays no part (the orientations sampled are
    unit quaternions)."""
    from mbdk.benchmarks import spatial_chain
    sc = spatial_chain(8) if name == "chain" else mbdk.scene(name)
    nb = len(sc.bodies)
    kw = dict(h=1e-4, t_end=t_end, every=int(round(t_end / 1e-3)))
    ra = mbdk.simulate(sc, "rk4", **kw)
    rj = mbdk.simulate(sc, "rk4", coordinates="joint", **kw)
    assert all(t.split(" (")[1].startswith("ball") for t in rj.manifest["joint_tree"]["tree"])
    assert state_gap(ra, rj, nb) < tol
    assert np.max(rj.residuals[:, 0]) < 1e-13
    quat = rj.q.reshape(len(rj.t), nb, 7)[..., 3:]
    assert np.max(np.abs(np.linalg.norm(quat, axis=-1) - 1.0)) < 1e-14


def test_cvode_takes_a_spherical_joint_in_joint_coordinates():
    """No step changes a joint run's state (its relative quaternion's norm is held by the
    stabilisation term), so CVODE runs the heavy top in joint coordinates, where absolute
    coordinates with quaternion_norm = 'project' refuse it; against rk4 at h = 1e-4."""
    sc = mbdk.scene("heavy_top")
    with pytest.raises(mbdk.NotApplicableError, match="quaternion_norm"):
        mbdk.simulate(sc, "cvode_bdf", rtol=1e-8, atol=1e-10, t_end=0.5)
    r = mbdk.simulate(sc, "cvode_bdf", rtol=1e-9, atol=1e-11, t_end=0.5, dt_out=0.5,
                      coordinates="joint")
    ref = mbdk.simulate(sc, "rk4", h=1e-4, t_end=0.5, every=5000, coordinates="joint")
    assert state_gap(r, ref, 1) < 1e-6


def test_a_contact_in_joint_coordinates_strikes_as_in_absolute_coordinates():
    """A bar swinging on a hinge strikes the floor with a sphere at its tip (the IMPACT law
    with Hertz's exponent, damping and friction): the contact's forces and its events are the
    absolute model's own, on the absolute state of the joint run. rk4 at h = 2e-5 through the
    strike in both coordinates, and dopri54 at rtol 1e-9 (their steps differ, so their states
    agree to the tolerance's effect through the strike). This law's force is smooth enough
    that dopri54 takes about as many steps with its events located as without, so the events
    themselves (the absolute model's function at the joint run's absolute state) are not what
    this test tells apart."""
    sc = scene_from_dict({
        "scene": {"name": "hammer"},
        "body": [body("bar", 2.0, (0.01, 0.17, 0.17), position=[0.5, 0.0, 0.3])],
        "joint": [{"name": "hinge", "type": "revolute", "body1": "bar", "at": [0.0, 0.0, 0.3],
                   "axis": [0.0, 1.0, 0.0]}],
        "force": [{"type": "gravity", "g": [0.0, 0.0, -G]},
                  {"type": "contact", "name": "floor", "body1": "bar", "body2": "ground",
                   "shape1": {"type": "sphere", "radius": 0.05, "centre": [0.5, 0.0, 0.0]},
                   "shape2": {"type": "plane", "normal": [0, 0, 1]}, "stiffness": 1e5,
                   "exponent": 1.5, "damping": 50.0, "friction": {"static": 0.3}}]},
        "hammer.toml")
    ra = mbdk.simulate(sc, "rk4", h=2e-5, t_end=0.6, every=500)
    rj = mbdk.simulate(sc, "rk4", h=2e-5, t_end=0.6, every=500, coordinates="joint")
    assert ra.contacts["floor"]["normal_force"].max() > 100.0      # it strikes
    assert state_gap(ra, rj, 1) < 1e-9
    kw = dict(rtol=1e-9, atol=1e-11, t_end=0.6, dt_out=0.01)
    ra = mbdk.simulate(sc, "dopri54", **kw)
    rj = mbdk.simulate(sc, "dopri54", coordinates="joint", **kw)
    assert rj.manifest["locate_events"] and state_gap(ra, rj, 1) < 1e-5
