"""Bad input that got through before (issue 36): each case gets a named error that names the
argument or the element and field, its value, and what to change; before the fix each one ended
in a generic Python exception, a run of minutes, a run on a wrong value, or a read without end."""
import math
import os
import sys
from pathlib import Path

import numpy as np
import pytest

import mbdk
from mbdk import checks, stability
from mbdk.scene_file import scene_from_dict, scene_or_file, scene_to_dict

SIM = sys.modules["mbdk.simulate"]
ODE = sys.modules["mbdk.ode"]


def edited(tmp_path, name, old, new):
    """A built-in scene's file with one text replaced (the replacement must happen)."""
    text = Path(mbdk.scene(name).source).read_text()
    assert old in text
    path = tmp_path / f"{name}.toml"
    path.write_text(text.replace(old, new, 1))
    return path


# ---- numbers out of floating-point range -----------------------------------------------------

@pytest.mark.parametrize("name, old, field", [
    ("double_pendulum", "mass = 1.0", "mass"),
    ("heavy_top", "mass = 1.0", "mass"),
    ("three_link_pendulum", "x = 0.2500000000", "x"),
    ("heavy_top", "inertia = [0.005, 0.005, 0.01]", "inertia"),
])
@pytest.mark.parametrize("digits", [400, 5000])
def test_a_huge_integer_in_a_scene_file_is_out_of_range(tmp_path, name, old, field, digits):
    """A 400-digit integer used to raise OverflowError; one of 5000 digits is beyond what Python
    converts at all (ValueError inside the TOML reader)."""
    big = "9" * digits
    new = (f"{field} = {big}" if field != "inertia" else f"inertia = [{big}, 0.005, 0.01]")
    path = edited(tmp_path, name, old, new)
    with pytest.raises(mbdk.SceneError) as exc:
        mbdk.load_scene(path)
    msg = str(exc.value)
    assert str(path) in msg and "out of range" in msg, msg
    if digits == 400:
        assert f"field {field!r}" in msg and "401 digits" not in msg and "400 digits" in msg, msg


@pytest.mark.parametrize("call", [
    lambda: mbdk.simulate(mbdk.scene("double_pendulum"), "dopri54", t_end=0.01, rtol=10**400),
    lambda: mbdk.simulate(mbdk.scene("heavy_top"), "dopri54", t_end=0.01, rtol=10**400),
    lambda: mbdk.solve_ode("pendulum", "dopri54", t_end=0.01, rtol=10**400),
    lambda: mbdk.solve_ode("pendulum", "rk4", h=1e-3, t_end=10**400),
    lambda: mbdk.simulate(mbdk.scene("four_bar"), "rk4", h=1e-3, t_end=0.01,
                          watch={"energy": 10**400}),
    lambda: mbdk.simulate(mbdk.scene("four_bar"), "rk4", h=1e-3, t_end=0.01,
                          formulation="penalty", penalty=(10**400, 10.0, 1.0)),
    lambda: mbdk.solve_ode("pendulum", "rk4", h=1e-3, t_end=0.01, params={"g": 10**400}),
])
def test_a_huge_integer_argument_is_named(call):
    with pytest.raises(mbdk.InvalidInputError) as exc:
        call()
    msg = str(exc.value)
    assert "an integer of 401 digits" in msg or "floating-point range" in msg, msg
    assert "OverflowError" not in msg


@pytest.mark.parametrize("inertia, mass", [
    ("[1e308, 1e308, 1e308]", "1.0"),       # LinAlgError: Eigenvalues did not converge
    ("[1e200, 1e200, 1e200]", "1.0"),       # its square overflows
    ("[1e-320, 1e-320, 1e-320]", "1.0"),    # denormal: its inverse overflows
    ("[0.005, 0.005, 0.01]", "1e308"),
    ("[0.005, 0.005, 0.01]", "1e-320"),
])
def test_a_spatial_inertia_or_mass_beyond_range_is_refused_by_the_reader(tmp_path, inertia,
                                                                          mass):
    path = edited(tmp_path, "heavy_top", "inertia = [0.005, 0.005, 0.01]",
                  f"inertia = {inertia}")
    path.write_text(path.read_text().replace("mass = 1.0", f"mass = {mass}", 1))
    with pytest.raises(mbdk.SceneError) as exc:
        mbdk.load_scene(path)
    msg = str(exc.value)
    assert "body 'top'" in msg and "out of range" in msg, msg
    assert ("'inertia'" in msg) == (mass == "1.0"), msg


def test_a_spatial_body_object_with_a_huge_inertia_is_named_not_a_linalg_error():
    sc = mbdk.scene("heavy_top")
    sc.bodies[0].inertia = np.eye(3) * 1e308
    with pytest.raises(mbdk.SceneError, match="body 'top': field 'inertia'"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01)


def test_a_joint_point_of_1e300_is_refused(tmp_path):
    """It used to run on past 20 s (rk4 and bdf on the three-link pendulum)."""
    path = edited(tmp_path, "three_link_pendulum", "point1 = [-0.3, 0.0]", "point1 = [1e300, 0.0]")
    with pytest.raises(mbdk.SceneError) as exc:
        mbdk.load_scene(path)
    msg = str(exc.value)
    assert "joint 'J3'" in msg and "'point1'" in msg and "out of range" in msg, msg


def test_a_point_far_beyond_the_scene_is_named_with_the_value_it_dwarfs(tmp_path):
    """1e100 is a float whose square still fits, but next to it the pendulum's 0.5 m points are
    lost in the roundoff: the message names both."""
    path = edited(tmp_path, "three_link_pendulum", "point1 = [-0.3, 0.0]", "point1 = [1e100, 0.0]")
    with pytest.raises(mbdk.SceneError) as exc:
        mbdk.load_scene(path)
    msg = str(exc.value)
    assert "joint 'J3', field 'point1'" in msg and "length scale 1e+100" in msg, msg


def pendulum(length):
    return {"scene": {"name": "p"},
            "body": [{"name": "bob", "mass": 1.0, "inertia": 1e-3, "x": 0.6, "y": -0.8}],
            "joint": [{"type": "distance", "name": "rod", "body1": "bob", "length": length}],
            "force": [{"type": "gravity", "g": [0.0, -9.81]}]}


@pytest.mark.parametrize("length, words", [
    (1e-300, ["out of range"]),                      # ida took 1.8 million steps for 0.05 s
    (1e-12, ["below 1e-09 of the scene's length scale 1", "body 'bob'"]),
])
def test_a_distance_too_short_for_the_scene_is_refused(length, words):
    with pytest.raises(mbdk.SceneError) as exc:
        scene_from_dict(pendulum(length), "p.toml")
    msg = str(exc.value)
    assert "p.toml: joint 'rod': field 'length'" in msg and all(w in msg for w in words), msg


def test_a_distance_the_scene_resolves_is_accepted():
    """1e-8 of a 1 m scene keeps 8 digits: accepted, and it runs."""
    sc = scene_from_dict(pendulum(1e-6), "p.toml")
    r = mbdk.simulate(sc, "rk4", h=1e-4, t_end=1e-3, watch=False)
    assert np.all(np.isfinite(r.q))


def test_a_contact_radius_too_small_for_the_scene_is_refused():
    d = scene_to_dict(mbdk.scene("particle_in_ring"))
    contact = next(f for f in d["force"] if f["type"] == "contact")
    contact["shape1"]["radius"] = 1e-13
    with pytest.raises(mbdk.SceneError) as exc:
        scene_from_dict(d, "ring.toml")
    assert f"force {contact['name']!r}: field 'shape1 radius'" in str(exc.value), str(exc.value)


# ---- step counts and tolerances --------------------------------------------------------------

@pytest.mark.parametrize("call", [
    lambda h_max: mbdk.solve_ode("pendulum", "dopri54", t_end=1.0, h_max=h_max),
    lambda h_max: mbdk.ODESolver("pendulum", "bdf", t_end=1.0, h_max=h_max),
    lambda h_max: mbdk.simulate(mbdk.scene("double_pendulum"), "dopri54", t_end=1.0,
                                h_max=h_max),
    lambda h_max: mbdk.simulate(mbdk.scene("heavy_top"), "bdf", t_end=1.0, h_max=h_max),
    lambda h_max: mbdk.simulate(mbdk.scene("double_pendulum"), "trapezoidal_index3", h=1e-3,
                                t_end=1.0, adaptive=True, h_max=h_max),
])
@pytest.mark.parametrize("h_max", [1e-300, 1e-9])
def test_an_h_max_that_needs_more_steps_than_allowed_is_refused_before_the_run(call, h_max):
    """It used to count steps up to max_steps (10^8: minutes) and then name the last sample."""
    with pytest.raises(mbdk.InvalidInputError) as exc:
        call(h_max)
    msg = str(exc.value)
    assert f"h_max = {h_max:g}" in msg and "t_end - t0 = 1" in msg and "1e+08" in msg, msg
    assert "give h_max >= 1e-08" in msg, msg


def test_an_h_max_within_max_steps_is_taken():
    r = mbdk.solve_ode("pendulum", "dopri54", t_end=1.0, h_max=1e-3, max_steps=2000)
    assert r.stats.steps >= 1000 and r.t[-1] == 1.0


def test_an_h_min_longer_than_the_interval_is_refused():
    with pytest.raises(mbdk.InvalidInputError, match="h_min = 2 is longer than the interval"):
        mbdk.solve_ode("pendulum", "dopri54", t_end=1.0, h_min=2.0)


@pytest.mark.parametrize("scene", ["double_pendulum", "heavy_top"])
@pytest.mark.parametrize("kw, exc, words", [
    (dict(atol=[-1.0, 1e-9]), mbdk.NotApplicableError, ["atol = [-1.0, 1e-09]",
                                                        "one absolute tolerance"]),
    (dict(atol=-1.0), mbdk.InvalidInputError, ["atol = -1.0", "> 0"]),
    (dict(atol=math.nan), mbdk.InvalidInputError, ["atol = nan"]),
    (dict(rtol=2.0), mbdk.InvalidInputError, ["rtol = 2.0", "below 1"]),
    (dict(rtol=1e-20), mbdk.InvalidInputError, ["rtol = 1e-20", "more digits"]),
    (dict(rtol="x"), mbdk.InvalidInputError, ["rtol = 'x'"]),
])
def test_planar_and_spatial_scenes_check_their_tolerances_alike(scene, kw, exc, words):
    """A spatial scene took atol=[-1.0, 1e-9] without a word and ran at 1e-8."""
    with pytest.raises(exc) as e:
        mbdk.simulate(mbdk.scene(scene), "dopri54", t_end=0.01, **kw)
    assert all(w in str(e.value) for w in words), str(e.value)


# ---- sample memory ---------------------------------------------------------------------------

@pytest.fixture
def little_memory(monkeypatch):
    """The machine said to have 1 MiB available."""
    monkeypatch.setattr(checks, "available_memory", lambda: 2**20)


@pytest.mark.parametrize("call, words", [
    (lambda: mbdk.solve_ode("pendulum", "rk4", h=1e-5, t_end=1.0), ["rk4", "every"]),
    (lambda: mbdk.ODESolver("pendulum", "rk4", h=1e-5, t_end=1.0), ["rk4", "every"]),
    (lambda: mbdk.solve_ode(lambda t, y: -y, "rk4", h=1e-5, t_end=1.0, y0=[1.0]), ["every"]),
    (lambda: mbdk.solve_ode("pendulum", "dopri54", t_end=10.0, dt_out=1e-5), ["dt_out"]),
    (lambda: mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-5, t_end=1.0),
     ["double_pendulum", "outputs"]),
    (lambda: mbdk.simulate(mbdk.scene("heavy_top"), "rk4", h=1e-5, t_end=1.0),
     ["heavy_top", "t_end"]),
])
def test_samples_beyond_the_memory_available_are_refused_before_allocation(little_memory, call,
                                                                            words):
    """100 001 samples need several MiB, more than the 1 MiB the machine is said to have."""
    with pytest.raises(mbdk.NoMemoryError) as exc:
        call()
    msg = str(exc.value)
    assert "MiB for its samples" in msg and "1 MiB of memory available" in msg, msg
    assert all(w in msg for w in words), msg


def test_a_memory_error_while_allocating_samples_becomes_no_memory_error(monkeypatch):
    """Where the allocation itself fails (the estimate said it would fit), the MemoryError is
    named too."""
    def no_memory(*args):
        raise MemoryError()
    monkeypatch.setattr(ODE._kernel, "solve_problem", no_memory)
    monkeypatch.setattr(ODE._kernel, "scene_run", no_memory)
    monkeypatch.setattr(ODE._kernel, "spatial_run", no_memory)
    for call in (lambda: mbdk.solve_ode("pendulum", "rk4", h=1e-3, t_end=1.0),
                 lambda: mbdk.simulate(mbdk.scene("four_bar"), "rk4", h=1e-3, t_end=0.1),
                 lambda: mbdk.simulate(mbdk.scene("heavy_top"), "rk4", h=1e-3, t_end=0.1)):
        with pytest.raises(mbdk.NoMemoryError, match="allocating its samples .* failed"):
            call()


def test_a_real_run_beyond_this_machine_is_refused():
    """2e9 samples of the double pendulum's 4 states: 80 GB, refused on a machine with less
    memory than that (the issue's run needed 7.45 GiB and raised a bare MemoryError)."""
    avail = checks.available_memory()
    if avail is None or avail * checks.MEMORY_SHARE > 8.0 * 2e9 * 5:
        pytest.skip("this machine would hold the samples")
    with pytest.raises(mbdk.NoMemoryError, match="GiB for its samples"):
        mbdk.solve_ode("double_pendulum", "rk4", h=1e-9, t_end=2.0)


# ---- paths that are no scene file ------------------------------------------------------------

@pytest.mark.parametrize("path", ["/dev/zero", "/dev/urandom", "/dev/null"])
def test_a_device_is_refused_at_once(path):
    """/dev/zero used to be read until memory ran out."""
    if not os.path.exists(path):
        pytest.skip(f"no {path} here")
    for read in (mbdk.load_scene, scene_or_file):
        with pytest.raises(mbdk.SceneError, match=f"{path}: is a device, not a regular file"):
            read(path)


def test_a_pipe_and_a_directory_are_refused_without_opening_them(tmp_path):
    pipe = tmp_path / "scene.toml"
    os.mkfifo(pipe)      # opening it for reading would block until a writer came
    with pytest.raises(mbdk.SceneError, match="is a pipe, not a regular file"):
        mbdk.load_scene(pipe)
    with pytest.raises(mbdk.SceneError, match="is a directory"):
        mbdk.load_scene(tmp_path)


def test_a_file_beyond_the_size_limit_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(sys.modules["mbdk.scene_file"], "MAX_SCENE_BYTES", 100)
    path = tmp_path / "big.toml"
    path.write_text("# " + "x" * 200 + "\n")
    with pytest.raises(mbdk.SceneError, match="201 bytes|203 bytes|more than a scene file"):
        mbdk.load_scene(path)


# ---- names of the wrong type -----------------------------------------------------------------

DP = "double_pendulum"


@pytest.mark.parametrize("call, name", [
    (lambda v: mbdk.simulate(mbdk.scene(DP), "rk4", h=1e-3, t_end=0.01, formulation=v),
     "formulation"),
    (lambda v: mbdk.simulate(mbdk.scene(DP), "trapezoidal_index3", h=1e-3, t_end=0.01,
                             formulation=v), "formulation"),
    (lambda v: mbdk.simulate(mbdk.scene(DP), "rk4", h=1e-3, t_end=0.01, solver=v), "solver"),
    (lambda v: mbdk.simulate(mbdk.scene(DP), "bdf2", h=1e-3, t_end=0.01, startup=v),
     "startup"),
    (lambda v: mbdk.simulate(mbdk.scene(DP), "rk4", h=1e-3, t_end=0.01, outputs=[v]),
     "outputs"),
    (lambda v: mbdk.simulate(mbdk.scene("heavy_top"), "ida", t_end=0.01, formulation=v),
     "formulation"),
    (lambda v: mbdk.simulate(mbdk.scene("heavy_top"), "bdf2", h=1e-3, t_end=0.01, startup=v),
     "startup"),
    (lambda v: mbdk.solve_ode("pendulum", "bdf2", h=1e-3, t_end=0.01, startup=v), "startup"),
    (lambda v: mbdk.ODESolver("pendulum", "bdf2", h=1e-3, t_end=0.01, startup=v), "startup"),
    (lambda v: mbdk.solve_ode("pendulum", v, h=1e-3, t_end=0.01), "method"),
    (lambda v: stability.stability_region(v), "method"),
    (lambda v: mbdk.methods(v), "solves"),
    (lambda v: mbdk.methods(step=v), "step"),
    (lambda v: mbdk.scenes(v), "kind"),
])
@pytest.mark.parametrize("value", [["reduced"], {"a": 1}, {"rk4"}])
def test_a_list_or_dict_where_a_name_belongs_is_named(call, name, value):
    """formulation=['x'] used to end in TypeError: unhashable type: 'list'."""
    with pytest.raises(mbdk.InvalidInputError) as exc:
        call(value)
    msg = str(exc.value)
    assert "unhashable" not in msg and (name in msg or "method" in msg), msg
    assert repr(value) in msg or type(value).__name__ in msg, msg


@pytest.mark.parametrize("kw, name", [
    (dict(re=3), "re"), (dict(re="ab"), "re"), (dict(im=[1.0]), "im"), (dict(im=(0, "x")), "im"),
    (dict(re=(1.0, 0.0)), "re"), (dict(im=(0.0, math.inf)), "im"), (dict(n=5.0), "n"),
])
def test_stability_region_windows_of_the_wrong_type_are_named(kw, name):
    """re=3 used to end in TypeError: object of type 'int' has no len()."""
    with pytest.raises(mbdk.InvalidInputError, match=rf"^{name}(\[\d\])? = "):
        stability.stability_region("rk4", **{"n": 5, **kw})


@pytest.mark.parametrize("call, name", [
    (lambda: stability.spectral_radius("rk4", "ab"), "z"),
    (lambda: stability.oscillator_response("rk4", [0.1], zeta="x"), "zeta"),
    (lambda: stability.real_interval("rk4", reach=[1.0]), "reach"),
    (lambda: stability.linear_step_limits("rk4", "x"), "jac"),
    (lambda: stability.largest_stable_step("pendulum", "rk4", t_span=None), "t_span"),
    (lambda: stability.equilibrium("pendulum", y0="x"), "y0"),
])
def test_stability_arguments_of_the_wrong_type_are_named(call, name):
    with pytest.raises(mbdk.InvalidInputError, match=rf"^{name}\b"):
        call()


# ---- quaternions as written ------------------------------------------------------------------

def test_a_unit_quaternion_written_to_7_digits_is_taken(tmp_path):
    """Its norm is 1 to 1.7e-8: it was refused, and one within the old 1e-8 ran into a message
    about a 'rotation' field the file never had."""
    exact = "quaternion = [0.9887710779360422, 0.14943813247359922, 0.0, 0.0]"
    for written in ("quaternion = [0.9887711, 0.1494381, 0.0, 0.0]",
                    "quaternion = [0.98877108, 0.14943813, 0.0, 0.0]"):
        sc = mbdk.load_scene(edited(tmp_path, "heavy_top", exact, written))
        r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01)
        assert np.all(np.isfinite(r.q))
        q = r.q[0, 3:7]
        assert abs(np.linalg.norm(q) - 1) < 1e-14     # the rotation of q / |q|


def test_a_quaternion_off_unit_is_refused_naming_the_field_the_file_has(tmp_path):
    sc_path = edited(tmp_path, "heavy_top",
                     "quaternion = [0.9887710779360422, 0.14943813247359922, 0.0, 0.0]",
                     "quaternion = [0.99, 0.15, 0.0, 0.0]")
    with pytest.raises(mbdk.SceneError) as exc:
        mbdk.load_scene(sc_path)
    msg = str(exc.value)
    assert "field 'quaternion'" in msg and "norm" in msg and "rotation" not in msg.split(
        "field")[1].split("=")[0], msg


# ---- a right-hand side that is not finite ----------------------------------------------------

@pytest.mark.parametrize("method", ["dopri54", "bs32", "bdf"])
def test_a_right_hand_side_turning_nan_is_named_non_finite(method):
    """It used to end dopri54 and bdf with 'step too small' (CVODE already said non-finite)."""
    def f(t, y):
        return np.array([math.nan if t >= 0.55 else -y[0]])
    with pytest.raises(mbdk.NonFiniteSolutionError, match="returned inf or NaN") as exc:
        mbdk.solve_ode(f, method, t_end=1.0, y0=[1.0], dt_out=0.1)
    r = exc.value.result
    assert r.t[-1] == pytest.approx(0.5) and r.y[-1, 0] == pytest.approx(math.exp(-0.5), 1e-4)
