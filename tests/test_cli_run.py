"""The command line of issue 24's first item: `mbdk run SCENE ... --out FILE` saves a run's
samples with its manifest (.npz, .csv, .h5), `mbdk plot FILE` draws them, `mbdk check` prints a
scene's report; bad input gets a one-line named error, exit status 2, and no file. Issue 36:
every failure, Ctrl-C (status 130) and a full disk included, is one named line and no file."""
import errno
import os
import re
import signal
import subprocess
import sys
import zipfile

import numpy as np
import pytest

import mbdk
from mbdk import cli, results_io
from mbdk import sweep as sweep_module
from mbdk.results_io import load_result, save_result

SCENE = str(mbdk.scene("double_pendulum").source)


def mbdk_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "mbdk", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd)


def test_run_saves_what_simulate_returns_and_plot_draws_it(tmp_path):
    """A scene file run from the command line: the file holds the samples of the same run in
    Python, bit for bit, with the manifest and the status; the summary names the status, the
    steps and the CPU time; the plot is a PNG."""
    out = tmp_path / "dp.npz"
    r = mbdk_cli("run", SCENE, "--method", "rk4", "--h", "1e-3", "--t-end", "2", "--every", "10",
                 "--out", out)
    assert r.returncode == 0, r.stderr
    assert "status SUCCESS; 2000 steps; CPU" in r.stdout and f"wrote {out}" in r.stdout
    d = load_result(out)
    ref = mbdk.simulate(mbdk.load_scene(SCENE), "rk4", h=1e-3, t_end=2, every=10)
    assert isinstance(d, mbdk.SceneResult)
    assert np.array_equal(d.t, ref.t) and np.array_equal(d.q, ref.q)
    assert np.array_equal(d.v, ref.v)
    assert np.array_equal(d.energy_balance(), ref.energy_balance())
    assert np.array_equal(d.energy_parts["work"], ref.energy_parts["work"])
    assert "W, the work of dampers, loads and drivers integrated at every step" in r.stdout
    assert d.manifest["method"] == "rk4" and d.manifest["h"] == 1e-3
    assert d.status.name == "SUCCESS" and d.q_names[:3] == ["bar1.x", "bar1.y", "bar1.angle"]
    p = mbdk_cli("plot", out)
    assert p.returncode == 0, p.stderr
    png = out.with_suffix(".png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


@pytest.mark.parametrize("suffix", [".csv", ".h5"])
def test_every_format_holds_the_same_run(tmp_path, suffix):
    """.csv (17 significant digits) and .h5 give back the arrays of .npz exactly; a spatial run
    too (its velocities are (v, Omega), its residuals' third column the quaternion norm)."""
    for sc, kw in ((mbdk.scene("trolley_crane"), dict(h=1e-3, t_end=1.0, every=20)),
                   (mbdk.scene("heavy_top"), dict(h=1e-3, t_end=0.2, every=20))):
        r = mbdk.simulate(sc, "rk4", **kw)
        if sc.name == "trolley_crane":   # W: the damper's work, as the run integrated it
            assert r.energy_parts["work"][-1] < 0
        a = load_result(save_result(r, tmp_path / "a.npz"))
        b = load_result(save_result(r, tmp_path / f"b{suffix}"))
        for x in (a, b):
            for k in ("t", "q", "v", "a", "multipliers", "reactions", "energy", "residuals",
                      "iterations"):
                mine, theirs = getattr(r, k), getattr(x, k)
                assert (mine is None and theirs is None) or np.array_equal(mine, theirs), \
                    (sc.name, k)
            assert x.energy_parts.keys() == r.energy_parts.keys()
            for k, v in r.energy_parts.items():
                assert np.array_equal(x.energy_parts[k], v), (sc.name, k)
            assert np.array_equal(x.energy_balance(), r.energy_balance())
            assert (x.q_names, x.v_names, x.manifest, x.stats, x.status, x.kind, x.bodies,
                    x.joints, x.rotation) == (r.q_names, r.v_names, r.manifest, r.stats,
                                              r.status, r.kind, r.bodies, r.joints, r.rotation)


def test_check_prints_the_scene_report():
    r = mbdk_cli("check", "four_bar")
    assert r.returncode == 0 and "1 degree of freedom" in r.stdout


@pytest.mark.parametrize("args, text", [
    (["run", "nowhere.toml", "--method", "rk4", "--h", "1e-3", "--t-end", "1", "--out",
      "x.npz"], "nowhere.toml"),
    (["run", SCENE, "--method", "rk5", "--h", "1e-3", "--t-end", "1", "--out", "x.npz"],
     "rk5"),
    (["run", SCENE, "--method", "rk4", "--h", "1e-3", "--t-end", "1", "--out",
      "missing/x.npz"], "does not exist"),
    (["run", SCENE, "--method", "rk4", "--h", "1e-3", "--t-end", "1", "--out", "x.txt"],
     "unknown result format"),
    # the watch stops explicit Euler's drift: a failed run writes no file
    (["run", SCENE, "--method", "explicit_euler", "--h", "0.05", "--t-end", "20", "--out",
      "x.npz"], "ConstraintDriftError"),
    (["run", SCENE, "--method", "rk4", "--step", "1e-3", "--t-end", "1", "--out", "x.npz"],
     "--step"),
    (["plot", "none.npz"], "no such result file"),
    # as root the folder's mode does not stop a write; /proc refuses the file itself
    (["run", SCENE, "--method", "rk4", "--h", "1e-3", "--t-end", "1", "--out",
      "/proc/mbdk-test.npz"], "/proc/mbdk-test.npz: No such file or directory; no file written"),
    (["sweep", "grid.toml", "--workers", "0", "--out", "t.csv"], "grid.toml: cannot read"),
    (["sweep", SCENE, "--workers", "0", "--out", "t.csv"], "no [sweep] table"),
    (["check", "nowhere.toml"], "SceneError: nowhere.toml: cannot read the scene file"),
    (["report", "--only", "nothing"], "--only nothing: no such study"),
    (["solve", "nothing", "rk4", "--h", "0.1", "--t-end", "1"], "unknown problem 'nothing'"),
])
def test_bad_input_is_named_and_writes_nothing(tmp_path, args, text):
    r = mbdk_cli(*args, cwd=tmp_path)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert text in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.startswith(f"mbdk {args[0]}: ") and r.stderr.count("\n") == 1, r.stderr
    assert not any(tmp_path.iterdir())


def _interrupt_once_running(args, cwd):
    """`mbdk ARGS` in a child process, sent SIGINT (what Ctrl-C sends) as soon as its solve's
    progress bar appears, i.e. while the kernel runs and the bar is being drawn; (status, the
    lines of standard error as a terminal would show them)."""
    env = {**os.environ, "MBDK_PROGRESS": "1", "OPENBLAS_NUM_THREADS": "1"}
    # SIGINT as a shell gives it, even where the tests run with it ignored
    p = subprocess.Popen([sys.executable, "-m", "mbdk", *map(str, args)], cwd=cwd, env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    seen = b""
    while b"mbdk:" not in seen:
        chunk = os.read(p.stderr.fileno(), 4096)
        assert chunk, (p.wait(), seen.decode())
        seen += chunk
    p.send_signal(signal.SIGINT)
    out, err = p.communicate()
    err = (seen + err).decode()
    assert "Traceback" not in err, err
    return p.returncode, _screen(err)


def _screen(text):
    """The lines a terminal shows after text, as tqdm draws on it (carriage returns, a newline
    to a bar's row and the cursor up, \\x1b[A, back), blank ones left out."""
    rows, row, col = [[]], 0, 0
    for token in re.findall(r"\x1b\[A|\r|\n|[^\r\n\x1b]", text):
        if token == "\n":
            row, col = row + 1, 0
            rows += [[] for _ in range(row + 1 - len(rows))]
        elif token == "\r":
            col = 0
        elif token == "\x1b[A":
            row = max(row - 1, 0)
        else:
            line = rows[row]
            line += [" "] * (col + 1 - len(line))
            line[col] = token
            col += 1
    return [s for s in ("".join(r).rstrip() for r in rows) if s]


@pytest.mark.parametrize("cmd, line", [
    (["run", "double_pendulum", "--method", "rk4", "--h", "1e-5", "--t-end", "1000",
      "--every", "10000", "--out", "long.npz"],
     r"mbdk run: interrupted after t = (\S+) s \(Ctrl-C\); no file written"),
    (["sweep", "long.toml", "--workers", "0", "--out", "long.csv"],
     r"mbdk sweep: interrupted \(Ctrl-C\); no file written"),
])
def test_ctrl_c_is_one_line_status_130_and_no_file(tmp_path, cmd, line):
    """Ctrl-C while the kernel runs (a run of 10^8 steps, a sweep of one of 10^9): the
    command stops at once with one line and status 130 (128 + SIGINT), and writes nothing."""
    (tmp_path / "long.toml").write_text('[sweep]\nt_end = 1000.0\nproblems = ["pendulum"]\n'
                                        'methods = ["rk4"]\nstep_counts = [1000000000]\n')
    status, shown = _interrupt_once_running(cmd, tmp_path)
    m = re.fullmatch(line, shown[0]) if len(shown) == 1 else None
    assert status == 130 and m, shown
    if m.groups():
        assert 0 <= float(m.group(1)) < 1000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["long.toml"]


def _full_disk_open(real_open=open):
    """open() for the writers: the file is created, but its writes go to /dev/full, which
    fails them with ENOSPC as a full disk does."""
    def fake(path, mode="r", *a, **kw):
        if "w" not in mode:
            return real_open(path, mode, *a, **kw)
        real_open(path, mode, *a, **kw).close()
        return real_open("/dev/full", mode, *a, **kw)
    return fake


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full (Linux)")
@pytest.mark.parametrize("module, args", [
    (results_io, ["run", "double_pendulum", "--method", "rk4", "--h", "1e-2", "--t-end", "1",
                  "--out", "run.npz"]),
    (results_io, ["run", "double_pendulum", "--method", "rk4", "--h", "1e-2", "--t-end", "1",
                  "--out", "run.csv"]),
    (sweep_module, ["sweep", "grid.toml", "--workers", "0", "--out", "table.csv"]),
])
def test_a_full_disk_is_one_line_and_leaves_no_file(tmp_path, monkeypatch, capsys, module,
                                                    args):
    """The write of the result fails with ENOSPC: one named line naming the file, status 2,
    and neither the file nor its temporary copy is left."""
    (tmp_path / "grid.toml").write_text('[sweep]\nt_end = 1.0\nproblems = ["pendulum"]\n'
                                        'methods = ["rk4"]\nsteps = [0.01]\n')
    with pytest.raises(OSError) as err:                 # the stand-in fails as a full disk does
        _full_disk_open()(tmp_path / "probe", "w").write("x" * 10_000_000)
    assert err.value.errno == errno.ENOSPC
    (tmp_path / "probe").unlink()
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(module, "open", _full_disk_open(), raising=False)
    assert cli.main(args) == 2
    err = capsys.readouterr().err
    assert err == (f"mbdk {args[0]}: OSError: {args[-1]}: No space left on device; "
                   "no file written\n"), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["grid.toml"]


def _result_files(folder):
    """Files that are not mbdk results, as a user could hand them to mbdk plot: empty, a
    truncated result, a damaged one, a zip of something else, an npz without the result's
    arrays, and results whose arrays disagree or whose CSV is mangled."""
    good = save_result(mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-2, t_end=1),
                       folder / "good.npz")
    data = good.read_bytes()
    files = {"empty.npz": b"", "truncated.npz": data[:len(data) // 2]}
    damaged = bytearray(data)
    damaged[len(data) // 3:len(data) // 3 + 64] = bytes(64)
    files["damaged.npz"] = bytes(damaged)
    for name, v in files.items():
        (folder / name).write_bytes(v)
    with zipfile.ZipFile(folder / "other.npz", "w") as z:
        z.writestr("notes.txt", "not a result")
    np.savez(folder / "keys.npz", a=np.arange(3))
    d = dict(np.load(good))
    np.savez(folder / "shapes.npz", **{**d, "q": d["q"][:, :2]})
    np.savez(folder / "scalar_names.npz", **{**d, "q_names": np.array("x")})
    csv_text = save_result(mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-2, t_end=1),
                           folder / "good.csv").read_text().splitlines()
    (folder / "mangled.csv").write_text("\n".join(csv_text[:5] + ["1.0,2.0"]) + "\n")
    good.unlink()
    (folder / "good.csv").unlink()
    return sorted(p.name for p in folder.iterdir())


def test_plot_names_a_file_that_is_not_a_result(tmp_path, capsys):
    """mbdk plot on each: one line (status 2) saying which file is not an mbdk result and
    why, and no PNG; with --traceback, the traceback instead."""
    names = _result_files(tmp_path)
    assert len(names) == 8
    why = {"empty.npz": "an empty file", "truncated.npz": "truncated",
           "damaged.npz": "damaged zip", "other.npz": "no 't' array; it holds notes.txt",
           "keys.npz": "no 't' array; it holds a", "shapes.npz": "'q' has shape",
           "scalar_names.npz": "TypeError", "mangled.csv": "ValueError"}
    for name in names:
        assert cli.main(["plot", str(tmp_path / name)]) == 2, name
        err = capsys.readouterr().err
        assert err.startswith(f"mbdk plot: InvalidInputError: {tmp_path / name}: not an mbdk "
                              "result file (") and why[name] in err, err
        assert err.endswith("; no file written\n") and err.count("\n") == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == names
    with pytest.raises(mbdk.InvalidInputError):
        cli.main(["plot", str(tmp_path / "empty.npz"), "--traceback"])


def test_a_sweep_grid_that_is_not_text_or_a_bad_scheduler_is_one_line(tmp_path, capsys):
    grid = tmp_path / "grid.toml"
    grid.write_bytes(bytes(range(256)))
    assert cli.main(["sweep", str(grid), "--workers", "0", "--out", str(tmp_path / "t.csv")]) == 2
    err = capsys.readouterr().err
    assert err == (f"mbdk sweep: InvalidInputError: {grid}: not a TOML text file: byte 0x80 at "
                   "offset 128 is not UTF-8 text; no file written\n"), err
    grid.write_text('[sweep]\nt_end = 1.0\nproblems = ["pendulum"]\nmethods = ["rk4"]\n'
                    'steps = [0.01]\n')
    assert cli.main(["sweep", str(grid), "--scheduler", "not an address", "--out",
                     str(tmp_path / "t.csv")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mbdk sweep: InvalidInputError: scheduler = 'not an address': cannot "
                          "connect") and err.count("\n") == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["grid.toml"]


def test_an_unexpected_exception_is_one_line_naming_its_class(monkeypatch, capsys):
    """A failure that is no mbdk error (a bug) is still one line, with its class, its message
    and the way to see where it came from."""
    def broken(*a, **kw):
        raise ZeroDivisionError("float division by zero\nin the kernel's wrapper")
    monkeypatch.setattr(mbdk.ode, "solve_ode", broken)
    assert cli.main(["solve", "pendulum", "rk4", "--h", "0.1", "--t-end", "1"]) == 2
    assert capsys.readouterr().err == (
        "mbdk solve: ZeroDivisionError: float division by zero in the kernel's wrapper "
        "(an unexpected error: --traceback shows where)\n")
    with pytest.raises(ZeroDivisionError):
        cli.main(["solve", "pendulum", "rk4", "--h", "0.1", "--t-end", "1", "--traceback"])


def test_a_closed_standard_output_ends_quietly():
    """`mbdk problems | head -0`: the reader is gone before the command writes; it ends with
    status 141 (128 + SIGPIPE) and nothing on standard error, not a BrokenPipeError."""
    p = subprocess.Popen([sys.executable, "-m", "mbdk", "problems"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    p.stdout.close()
    err = p.stderr.read()
    assert p.wait() == 141 and err == "", err


INCLINE = """
[scene]
name = "worn_block"

[[body]]
name = "block"
mass = 1.0
inertia = 0.1
x = 0.0
y = 1.0e-5
vx = 1.0

[[force]]
type = "gravity"
g = [0.0, -9.81]

[[force]]
type = "contact"
name = "floor"
body1 = "block"
shape1 = { type = "point" }
shape2 = { type = "line", point = [0.0, 0.0], normal = [0.0, 1.0] }
stiffness = 1.0e6
damping = 200.0
friction = { static = 0.5, dynamic = 0.5, stiction_speed = 1.0e-3, transition_speed = 2.0e-3 }

[[wear]]
name = "pad"
law = "archard"
load = "floor.normal_force"
coefficient = 1.0e-9
"""


def test_wear_reaches_the_file_the_summary_the_plot_and_the_sweep(tmp_path):
    """A block sliding to rest on a floor, its pad worn by Archard's law: the volume is in the
    result file (every format, the same bits as the run's), in `mbdk run`'s summary, in
    `mbdk plot`'s figure (a fourth panel) and in the sweep's wear column; and the file gives
    back the run's other outputs (multipliers, reactions, accelerations, energy parts)."""
    scene = tmp_path / "worn.toml"
    scene.write_text(INCLINE)
    sc = mbdk.load_scene(scene)
    r = mbdk.simulate(sc, "rk4", h=1e-4, t_end=0.3, every=100)
    assert r.wear["pad"][-1] > 0
    for suffix in (".npz", ".csv"):
        back = load_result(save_result(r, tmp_path / f"w{suffix}"))
        assert list(back.wear) == ["pad"] and np.array_equal(back.wear["pad"], r.wear["pad"])
        assert np.array_equal(back.contacts["floor"]["normal_force"],
                              r.contacts["floor"]["normal_force"])
        assert np.array_equal(back.a, r.a) and np.array_equal(back.energy, r.energy)
    out = tmp_path / "run.npz"
    p = mbdk_cli("run", scene, "--method", "rk4", "--h", "1e-4", "--t-end", "0.3", "--every",
                 "100", "--out", out)
    assert p.returncode == 0, p.stderr
    assert f"wear 'pad': {r.wear['pad'][-1]:.6g} m^3 worn by t = 0.3 s" in p.stdout
    assert "contact 'floor': largest penetration" in p.stdout
    floor = load_result(out).contacts["floor"]
    for field, values in r.contacts["floor"].items():
        assert np.array_equal(floor[field], values), field
    assert floor["friction_force"].max() > 0          # the pad slides: Coulomb friction
    assert np.array_equal(load_result(out).wear["pad"], r.wear["pad"])
    assert mbdk_cli("plot", out).returncode == 0
    assert out.with_suffix(".png").read_bytes()[:4] == b"\x89PNG"
    grid = tmp_path / "grid.toml"
    grid.write_text(f'[sweep]\nscenes = ["{scene}"]\nmethods = ["rk4"]\nsteps = [1e-4]\n'
                    't_end = 0.3\n')
    table = sweep_module.sweep(sweep_module.load_grid(grid), workers=0)
    wear = [row["wear"] for row in table.rows if row["method"] == "rk4"]
    assert wear and all(w.startswith("pad ") for w in wear)
    assert float(wear[0].split()[1]) == pytest.approx(r.wear["pad"][-1], rel=1e-12)


def test_a_result_file_from_before_its_metadata_still_loads(tmp_path):
    """A file of the former layout (t, q, velocities, names, status, manifest, the outputs; no
    metadata) loads as a SceneResult with what it holds."""
    r = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-2, t_end=0.5)
    old = tmp_path / "old.npz"
    np.savez(old, t=r.t, q=r.q, velocities=r.v, energy=r.energy,
             work=r.energy_parts["work"], residuals=r.residuals, multipliers=r.multipliers,
             q_names=np.array(r.q_names), velocity_names=np.array(r.v_names),
             status=np.array("SUCCESS"), manifest=np.array('{"method": "rk4"}'))
    back = load_result(old)
    assert back.bodies == ["bar1", "bar2"] and back.kind == "planar"
    assert np.array_equal(back.energy_balance(), r.energy_balance())
    assert back.success and back.manifest == {"method": "rk4"} and back.a is None


def test_a_wrong_joint_name_is_named():
    r = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-2, t_end=0.1)
    with pytest.raises(mbdk.InvalidInputError, match="'hinge'.*its joints are"):
        r.reaction("hinge")
