"""The C API's spatial steppers against Python's simulate: kernel/examples/c_spatial.c steps
mbdk's heavy_top through mbdk_stepper_create_spatial (rk4) and
mbdk_stepper_create_spatial_index3 (trapezoidal_index3), and a ball sliding with wear (its
worn volume a state after the body's) by rk4, and prints its tables and final states; they are
the scenes Python builds, and the states are simulate's bit for bit (one stepping routine over
the mechanism interface, the same grid). The example checks its own physics (energy, angular
momentum, the pivot, second order; the ball's rolling speed and Archard volume) when meson runs
it."""
import subprocess
import sys

import numpy as np
import pytest

import mbdk
from mbdk.scene_file import scene_from_dict
from mbdk.spatial_model import spatial_tables


@pytest.fixture(scope="module")
def printed(root):
    exe = root / "build" / f"cp{sys.version_info[0]}{sys.version_info[1]}" / "c_spatial"
    if not exe.exists():
        pytest.skip("no c_spatial in the meson build folder: mbdk is not an editable install "
                    "from this tree with its examples")
    run = subprocess.run([str(exe), "print"], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    lines = {}
    for line in run.stdout.splitlines():
        head, *rest = line.split()
        if head in ("tables", "y0", "rk4", "trapezoidal_index3", "wear_tables", "wear_y0",
                    "wear_rk4"):
            lines[head] = rest
    return lines


def test_the_example_steps_the_built_in_heavy_top(printed):
    sc = mbdk.scene("heavy_top")
    nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = spatial_tables(sc)
    assert (nb, nj, nf) == (1, 1, 1)
    reals = np.array([float(x) for x in printed["tables"][:-6]])
    ints = [int(x) for x in printed["tables"][-6:]]
    want = np.concatenate([mass, inertia[:, :, 0].ravel(), jreal[:, 0], freal[:, 0]])
    assert np.array_equal(reals, want)
    assert ints == [jtype[0], jbody[0, 0], jbody[1, 0], ftype[0], fbody[0, 0], fbody[1, 0]]
    assert np.array_equal(np.array([float(x) for x in printed["y0"]]), sc.state0())


@pytest.mark.parametrize("method", ["rk4", "trapezoidal_index3"])
def test_the_c_stepper_gives_simulates_bits(printed, method):
    """500 steps of 1 ms from the same (unassembled) state: the C stepper's final state is
    simulate's, every bit of it."""
    kw = {"formulation": "augmented_lagrangian"} if method == "trapezoidal_index3" else {}
    r = mbdk.simulate(mbdk.scene("heavy_top"), method, h=1e-3, t_end=0.5,
                      assemble_initial=False, **kw)
    final = np.concatenate([r.q[-1], r.v[-1]])
    assert np.array_equal(np.array([float(x) for x in printed[method]]), final)


#: the ball of the example's part 5, as a scene file writes it (its numbers are the C tables')
BALL = {"scene": {"name": "sliding_ball"},
        "body": [{"name": "ball", "kind": "spatial", "mass": 1.0,
                  "inertia": [1e-3, 1e-3, 1e-3], "position": [0.0, 0.0, 0.049990190000000004],
                  "velocity": [1.0, 0.0, 0.0]}],
        "force": [{"type": "gravity", "g": [0.0, 0.0, -9.81]},
                  {"type": "contact", "name": "floor", "body1": "ball",
                   "shape1": {"type": "sphere", "radius": 0.05},
                   "shape2": {"type": "plane", "normal": [0.0, 0.0, 1.0]}, "stiffness": 1e6,
                   "damping": 100.0,
                   "friction": {"static": 0.3, "dynamic": 0.3, "stiction_speed": 1e-3,
                                "transition_speed": 2e-3}}],
        "wear": [{"name": "ball", "law": "archard", "load": "floor.normal_force",
                  "coefficient": 5e-13}]}


def test_the_example_wears_the_ball_python_builds(printed):
    """The example's wear tables are spatial_tables' of the same scene (the wear entry after
    the forces, naming its contact's column), its y0 the bodies' state and the volume 0."""
    sc = scene_from_dict(BALL, "ball.toml")
    nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = spatial_tables(sc)
    assert (nb, nj, nf) == (1, 0, 3)
    words = printed["wear_tables"]
    reals = np.array([float(x) for x in words[:-3 * nf]])
    ints = [int(x) for x in words[-3 * nf:]]
    assert np.array_equal(reals, np.concatenate([mass, inertia[:, :, 0].ravel(),
                                                 freal.T.ravel()]))
    assert ints == [int(x) for k in range(nf) for x in (ftype[k], fbody[0, k], fbody[1, k])]
    assert np.array_equal(np.array([float(x) for x in printed["wear_y0"]]),
                          np.concatenate([sc.state0(), [0.0]]))


def test_the_c_stepper_with_wear_gives_simulates_bits(printed):
    """2000 rk4 steps of 0.1 ms: the C stepper's final state, the worn volume included, is
    simulate's, every bit of it."""
    r = mbdk.simulate(scene_from_dict(BALL, "ball.toml"), "rk4", h=1e-4, t_end=0.2,
                      assemble_initial=False)
    final = np.concatenate([r.q[-1], r.v[-1], [r.wear["ball"][-1]]])
    assert np.array_equal(np.array([float(x) for x in printed["wear_rk4"]]), final)
