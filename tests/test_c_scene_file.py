"""A scene from its file in C (issue 39, item 5): `mbdk tables` writes a scene's kernel tables and
its assembled initial state (mbdk.tables_file), and kernel/examples/c_scene_file.c reads them
with mbdk_scene_tables_read and steps them. The C program's final state is simulate's, bit for
bit (the same tables, the same assembled start, one stepping routine), on planar and spatial
scenes, ODE methods and the index-3 family; a bad tables file is refused with the file, line,
key and value named."""
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

import mbdk
from mbdk.codes import FORMULATIONS, INDEX3_FORMULATIONS
from mbdk.tables_file import read_tables, scene_tables, write_tables


@pytest.fixture(scope="module")
def exe(root):
    path = root / "build" / f"cp{sys.version_info[0]}{sys.version_info[1]}" / "c_scene_file"
    if not path.exists():
        pytest.skip("no c_scene_file in the meson build folder: mbdk is not an editable "
                    "install from this tree with its examples")
    return path


def c_final(exe, path, method, h, t_end, formulation=0):
    run = subprocess.run([str(exe), str(path), method, repr(h), repr(t_end), str(formulation)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    head, t, *y = run.stdout.split()
    assert head == "final"
    return float(t), np.array([float(x) for x in y])


#: (scene, method, formulation, h, t_end): steps within each scene's stability limit (the
#: gears' mesh stiffness, the governor's fast mode)
CASES = [
    ("double_pendulum", "rk4", "projection", 1e-3, 0.2),
    ("four_bar", "rk4", "reduced", 1e-3, 0.2),
    ("pla_gears", "rk4", "reduced", 1e-5, 0.01),      # gear meshes, friction, wear states
    ("trolley_crane", "trapezoidal_index3", "augmented_lagrangian", 1e-3, 0.2),
    ("double_pendulum", "trapezoidal_index3", "index3", 1e-3, 0.2),
    ("heavy_top", "rk4", "projection", 1e-3, 0.2),
    ("flyball_governor", "rk4", "reduced", 1e-4, 0.05),
    ("spatial_double_pendulum", "trapezoidal_index3", "augmented_lagrangian", 1e-3, 0.2),
    ("double_pendulum", "rk4", "baumgarte", 1e-3, 0.2),       # gains 1/h, sqrt(2)/h as simulate's
    ("heavy_top", "rk4", "baumgarte", 1e-3, 0.2),
    ("four_bar", "rk4", "penalty", 1e-3, 0.2),
    ("spatial_double_pendulum", "rk4", "penalty", 1e-3, 0.2),
    ("parallelogram_redundant", "trapezoidal_index3", "augmented_lagrangian", 1e-3, 0.2),
]


@pytest.mark.parametrize("name, method, formulation, h, t_end", CASES)
def test_the_c_program_steps_simulates_bits(exe, tmp_path, name, method, formulation, h,
                                            t_end):
    sc = mbdk.scene(name)
    path = write_tables(sc, tmp_path / f"{name}.toml")
    codes = INDEX3_FORMULATIONS if method == "trapezoidal_index3" else FORMULATIONS
    t, y = c_final(exe, path, method, h, t_end, codes[formulation])
    r = mbdk.simulate(sc, method, h=h, t_end=t_end, formulation=formulation)
    want = np.concatenate([r.q[-1], r.v[-1], [r.wear[w.name][-1] for w in sc.wear]])
    assert t == r.t[-1]
    assert y.shape == want.shape
    assert np.array_equal(y, want), np.abs(y - want).max()


def test_the_file_holds_the_assembled_start_and_the_runs_tables(exe, tmp_path):
    """The four-bar with its coupler moved 1 cm off its joints: the file's y0 is the assembled
    state (|Phi| at roundoff; the coupler moved back by about 1 cm), not the pose written, so the
    C program starts where simulate does and ends on its bits; read back, every table equals the
    one the run builds."""
    sc = mbdk.scene("four_bar")
    bodies = list(sc.bodies)
    bodies[1] = replace(bodies[1], x=bodies[1].x + 0.01)
    sc = replace(sc, bodies=bodies)
    path = write_tables(sc, tmp_path / "fb.toml")
    keys = read_tables(path)
    for k, v in scene_tables(sc).items():
        assert np.array_equal(np.asarray(keys[k]).ravel(), np.asarray(v).ravel()), k
    nc = 3 * keys["nb"]
    q0, q_file = keys["y0"][:nc], np.array(sc.q0())
    assert np.abs(q0 - q_file).max() > 1e-3                       # the assembly moved it
    assert np.abs(mbdk.evaluate(sc, q0, keys["y0"][nc:2 * nc])["phi"]).max() < 1e-12
    t, y = c_final(exe, path, "rk4", 1e-3, 0.1, FORMULATIONS["reduced"])
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.1, formulation="reduced")
    assert np.array_equal(y, np.concatenate([r.q[-1], r.v[-1]]))


def test_the_example_file_is_what_mbdk_tables_writes_now(root, tmp_path):
    """kernel/examples/double_pendulum.tables.toml (meson's check of the C reader) is the file
    `mbdk tables double_pendulum` writes with this tree: it cannot fall behind the tables."""
    committed = read_tables(root / "kernel" / "examples" / "double_pendulum.tables.toml")
    now = read_tables(write_tables(mbdk.scene("double_pendulum"), tmp_path / "dp.toml"))
    assert committed.keys() == now.keys()
    for k in now:
        assert np.array_equal(np.asarray(committed[k]), np.asarray(now[k])), k


@pytest.mark.parametrize("edit, words", [
    (("mass", "mass = [1.0, nan]"), ["line 14", "'mass'", "nan", "finite"]),
    (("jint", "jint = [1, 1, 0, 0, 1, 2, 1]"), ["'jint'", "7 values", "8 expected"]),
    (("jint", "jint = [1, 1, 0, 0, 1, 2, 1, 0.5]"), ["'jint'", "0.5", "integer"]),
    (("nb", "nb = 0"), ["'nb'", "out of range"]),
    (("kind", 'kind = "planer"'), ["'kind'", "planer", "planar"]),
    (("version", "version = 2"), ["'version'", "reads version 1"]),
    (("y0", None), ["'y0' missing"]),
    (("fint", "fint = [1, 1, 0, 0]\nfint = [1, 1, 0, 0]"), ["'fint' given twice"]),
    (("scene", "scene = double_pendulum"), ["'scene'", "string"]),
])
def test_a_bad_tables_file_is_refused_by_name(exe, tmp_path, edit, words):
    key, line = edit
    good = (write_tables(mbdk.scene("double_pendulum"), tmp_path / "dp.toml")
            .read_text().splitlines())
    lines = [ln for ln in good if not ln.startswith(f"{key} =")] if line is None else \
        [line if ln.startswith(f"{key} =") else ln for ln in good]
    bad = tmp_path / "bad.toml"
    bad.write_text("\n".join(lines) + "\n")
    run = subprocess.run([str(exe), str(bad), "rk4", "1e-3", "0.01"], capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 2 and not run.stdout
    message = run.stderr.strip()
    assert message.startswith(str(bad)), message
    for w in words:
        assert w in message, (w, message)


def test_mbdk_tables_writes_the_file_or_nothing(tmp_path, capsys):
    from mbdk.cli import main
    out = tmp_path / "top.toml"
    assert main(["tables", "heavy_top", "--out", str(out)]) == 0
    assert read_tables(out)["kind"] == "spatial" and read_tables(out)["rotation"] == 1
    assert main(["tables", "heavy_top", "--out", str(tmp_path / "top.txt")]) != 0
    assert "ending in .toml" in capsys.readouterr().err
    assert not (tmp_path / "top.txt").exists()


@pytest.mark.parametrize("norm", ["stabilise", "none"])
def test_a_spatial_scenes_quaternion_norm_travels_with_its_tables(exe, tmp_path, norm):
    """quaternion_norm and norm_gain are the scene's (they change the run): the file carries
    them and the C stepper keeps simulate's bits with them."""
    sc = replace(mbdk.scene("heavy_top"), quaternion_norm=norm, norm_gain=25.0)
    path = write_tables(sc, tmp_path / "top.toml")
    assert read_tables(path)["norm"] == {"stabilise": 2, "none": 3}[norm]
    assert read_tables(path)["norm_gain"] == 25.0
    t, y = c_final(exe, path, "rk4", 1e-3, 0.2, FORMULATIONS["projection"])
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.2, formulation="projection")
    assert np.array_equal(y, np.concatenate([r.q[-1], r.v[-1]]))


def test_the_start_at_any_t0_and_on_redundant_joints(tmp_path):
    """y0 at a t0 where t0 + h rounds (12345.678) and on the redundant parallelogram (which the
    ODE formulations refuse): the assembled state either way, at the file's t0."""
    keys = read_tables(write_tables(mbdk.scene("double_pendulum"), tmp_path / "a.toml",
                                    t0=12345.678))
    assert keys["t0"] == 12345.678
    sc = mbdk.scene("parallelogram_redundant")
    keys = read_tables(write_tables(sc, tmp_path / "b.toml"))
    r = mbdk.simulate(sc, "trapezoidal_index3", h=1e-3, t_end=1e-3)
    assert np.array_equal(keys["y0"], np.concatenate([r.q[0], r.v[0]]))


def test_comments_and_what_mbdk_tables_does_not_write(exe, tmp_path):
    """Trailing comments are read past (TOML's); a list over several lines, a scene file given
    by mistake and a state length that its bodies do not have are refused with what to do."""
    good = write_tables(mbdk.scene("double_pendulum"), tmp_path / "dp.toml").read_text()

    def run(text):
        bad = tmp_path / "x.toml"
        bad.write_text(text)
        return subprocess.run([str(exe), str(bad), "rk4", "1e-3", "0.01"], capture_output=True,
                              text=True, timeout=60)
    commented = good.replace("nb = 2", "nb = 2   # bodies").replace(
        'kind = "planar"', 'kind = "planar"  # "spatial" is the other')
    assert run(commented).returncode == 0
    lines = good.replace("mass = [1.0, 2.0]", "mass = [1.0,\n  2.0]")
    assert "several lines" in run(lines).stderr
    scene_file = (mbdk.scene("double_pendulum").source)
    assert "scene file?" in run(open(scene_file).read()).stderr
    short = good.replace("n = 12", "n = 11").replace(
        "y0 = [", "y0 = [").rsplit(",", 1)[0] + "]\n"
    out = run(short).stderr
    assert "'n' = 11" in out and "has 12 values" in out, out
    empty = good.replace("mass = [1.0, 2.0]", "mass = [1.0,, 2.0]")
    assert "value 2 is empty" in run(empty).stderr
    hexa = good.replace("mass = [1.0, 2.0]", "mass = [1.0, 0x1p1]")
    assert "'0x1p1' is not a finite decimal number" in run(hexa).stderr
