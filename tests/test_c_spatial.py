"""The C API's spatial steppers against Python's simulate: kernel/examples/c_spatial.c steps
mbdk's heavy_top through mbdk_stepper_create_spatial (rk4) and
mbdk_stepper_create_spatial_index3 (trapezoidal_index3) and prints its tables and final
states; they are the scene Python builds, and the states are simulate's bit for bit (one
stepping routine over the mechanism interface, the same grid). The example checks its own
physics (energy, angular momentum, the pivot, second order) when meson runs it."""
import subprocess
import sys

import numpy as np
import pytest

import mbdk
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
        if head in ("tables", "y0", "rk4", "trapezoidal_index3"):
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
