"""The command line of issue 24's first item: `mbdk run SCENE ... --out FILE` saves a run's
samples with its manifest (.npz, .csv, .h5), `mbdk plot FILE` draws them, `mbdk check` prints a
scene's report; bad input gets a one-line named error, exit status 2, and no file."""
import subprocess
import sys

import numpy as np
import pytest

import mbdk
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
    assert np.array_equal(d["t"], ref.t) and np.array_equal(d["q"], ref.q)
    assert np.array_equal(d["velocities"], ref.v)
    assert np.array_equal(d["energy_balance"], ref.energy_balance())
    assert d["manifest"]["method"] == "rk4" and d["manifest"]["h"] == 1e-3
    assert d["status"] == "SUCCESS" and d["q_names"][:3] == ["bar1.x", "bar1.y", "bar1.angle"]
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
        a = load_result(save_result(r, tmp_path / "a.npz"))
        b = load_result(save_result(r, tmp_path / f"b{suffix}"))
        for k in ("t", "q", "velocities", "energy", "energy_balance", "residuals",
                  "multipliers"):
            assert np.array_equal(a[k], b[k]), (sc.name, k)
        assert a["q_names"] == b["q_names"] and a["manifest"] == b["manifest"]


def test_check_prints_the_scene_report():
    r = mbdk_cli("check", "four_bar")
    assert r.returncode == 0 and "1 degrees of freedom" in r.stdout


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
])
def test_bad_input_is_named_and_writes_nothing(tmp_path, args, text):
    r = mbdk_cli(*args, cwd=tmp_path)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert text in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) <= 3
    assert not any(tmp_path.iterdir())
