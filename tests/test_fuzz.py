"""Bad input from every door gets a named error or a sound result (issues 18 and 36): a
fixed-seed subset of studies/fuzz.py's generator (broken scene files, Scene objects changed in
Python, bad arguments, paths that are no scene file, the stability and registry functions).
A generic Python exception, a success with inf or NaN, or anything printed by the kernel or
LAPACK (which would print on an illegal argument) fails the test; a crash or a hang
fails the whole run."""
import collections
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "studies"))
import fuzz  # noqa: E402


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory):
    return fuzz.fuzz(tmp_path_factory.mktemp("fuzz"), n_scenes=160, n_args=90)


def test_every_bad_input_gets_a_named_error_or_a_sound_result(outcomes):
    defects = [f"{r['door']}: {r['case']} -> {r['outcome']} {r['detail']}" for r in outcomes
               if r["outcome"] in ("generic", "nonfinite")]
    assert not defects, "\n".join(defects)


def test_the_generator_reaches_every_door_and_both_outcomes(outcomes):
    """A generator that only ever produced errors (or only successes) would prove nothing."""
    c = collections.Counter((r["door"], r["outcome"]) for r in outcomes)
    for door in fuzz.DOORS:
        assert c[(door, "named")] >= 10, c
    assert c[("scene file", "success")] >= 5 and c[("scene objects", "success")] >= 5, c
    assert max(r["seconds"] for r in outcomes) < 30.0   # no case hangs


#: the bad inputs of issue 36, by the text of the fuzz cases that carry them
ISSUE_36 = {
    "a 400-digit integer in a scene file": ("scene file", "10000000000000000000000000000000000"),
    "an integer beyond Python's text limit": ("scene file", "<5000-digit integer>"),
    "a denormal float in a scene file": ("scene file", "5e-324"),
    "a huge integer argument": ("arguments", "=10000000000000000000000000000000"),
    "an h_max of 1e-300": ("arguments", "h_max=1e-300"),
    "a spatial scene's atol list": ("arguments", "atol=[-1.0, 1e-09]"),
    "samples beyond the memory": ("arguments", "2e9 samples"),
    "a device as the scene file": ("scene paths", "/dev/zero"),
    "a named pipe as the scene file": ("scene paths", "pipe.toml"),
    "a list where a formulation belongs": ("arguments", "formulation=['reduced']"),
    "a dict where a method belongs": ("arguments", "simulate(four_bar, {'rk4': 1}"),
    "stability_region's re of a wrong type": ("functions", "stability_region(re)"),
}


def test_the_generator_carries_every_bad_input_of_issue_36(outcomes):
    """Each kind of input the issue found getting through is among the cases (each case is
    then held to a named error or a sound result by the test above); a spatial scene takes the
    tolerance case at least once."""
    missing = [what for what, (door, text) in ISSUE_36.items()
               if not any(r["door"] == door and text in r["case"] for r in outcomes)]
    assert not missing, missing
    spatial = [r for r in outcomes if r["door"] == "arguments" and "atol=" in r["case"]
               and ("heavy_top" in r["case"] or "spatial_double_pendulum" in r["case"])]
    assert spatial and all(r["outcome"] == "named" for r in spatial), spatial


def test_nothing_is_printed(tmp_path, capfd):
    """Neither the kernel nor LAPACK prints, whatever comes in: a fuzz subset, and a NaN state
    handed to the kernel's assembly directly (the door a C caller has; Python's own checks stop
    it earlier): LAPACK's dgelsd, which the assembly's least squares may call, prints "On entry
    to DLASCL parameter number 4 had an illegal value" for one, so the kernel refuses it first."""
    import numpy as np
    import mbdk
    from mbdk import _kernel
    from mbdk.model import build_tables, given_mask
    fuzz.fuzz(tmp_path, n_scenes=60, n_args=0, seed=7)
    sc = mbdk.scene("four_bar")
    tab = build_tables(sc)
    q = np.array(sc.q0(), float)
    q[4] = np.nan
    *_, status = _kernel.model_assemble(*tab.args(), 0.0, q, np.array(sc.v0(), float),
                                        given_mask(sc), max(tab.m, 1))
    assert status == mbdk.Status.ERR_NONFINITE
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_a_scene_is_re_read_only_when_it_changed():
    """simulate() re-reads a Scene through the file reader's checks when any of its fields
    changed since it was read (a field its type does not use included: the tables are built
    from the objects), and takes it as it is otherwise (the check then costs microseconds)."""
    import mbdk
    from mbdk.scene_file import checked
    sc = mbdk.scene("double_pendulum")
    assert checked(sc) is sc
    sc.joints[0].axis = (0.0, 1.0)          # unused by a revolute joint, still compared
    again = checked(sc)
    assert again is not sc and again.joints[0].axis == (1.0, 0.0)
    sc.bodies[0].mass = -1.0
    with pytest.raises(mbdk.SceneError, match="body 'bar1': field 'mass' = -1.0"):
        checked(sc)


def test_a_changed_scene_is_caught_however_it_changed():
    """A numpy array in a field, and an element moved from one list to another (the
    concatenation of the lists unchanged), both make simulate re-read the scene, which names
    the problem, instead of passing an unchecked scene on."""
    import numpy as np
    import mbdk
    sc = mbdk.scene("double_pendulum")
    sc.joints[0].point1 = np.array([0.5, 0.0])
    with pytest.raises(mbdk.SceneError, match="joint 'O': field 'point1'"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01)   # compared, not a numpy ValueError
    sc = mbdk.scene("spring_damper_bar")
    sc.forces.insert(0, sc.joints.pop())
    with pytest.raises(mbdk.SceneError):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01)
