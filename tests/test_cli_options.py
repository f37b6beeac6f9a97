"""The command line reaches every option of the Python API (issue 39, item 4): `mbdk run`'s
options are mbdk.simulate's keywords and `mbdk solve`'s mbdk.solve_ode's, made from their
signatures (mbdk.cli_options), so an option the API gains cannot be missing here; the values
given reach the function as the API takes them; `mbdk scenes`, `mbdk check` (with what the
assembly moved), `--workers` with `--scheduler`, plain English."""
import inspect
import subprocess
import sys

import numpy as np
import pytest

import mbdk
from mbdk import cli, cli_options
from mbdk.results_io import load_result


def mbdk_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "mbdk", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd)


@pytest.mark.parametrize("fn, helps, skip", [
    (mbdk.simulate, cli_options.RUN_HELP, cli_options.RUN_SKIP),
    (mbdk.solve_ode, cli_options.SOLVE_HELP, cli_options.SOLVE_SKIP)])
def test_every_keyword_of_the_api_has_its_option(fn, helps, skip):
    """Every keyword of the function is an option with a help line, and the tables name no
    keyword the function does not have (a renamed one would leave a stale line)."""
    names = {p.name for p in cli_options.keywords(fn, skip)}
    assert names == set(helps), (names ^ set(helps))
    usage = mbdk_cli("run" if fn is mbdk.simulate else "solve", "--help").stdout
    for name in names:
        assert "--" + name.replace("_", "-") in usage, name


def test_the_options_given_reach_simulate_as_the_api_takes_them(tmp_path):
    """A generalized-alpha run with step-size control, the watch off and two outputs: the file
    holds the run simulate gives with the same keywords, bit for bit."""
    out = tmp_path / "ga.npz"
    p = mbdk_cli("run", "double_pendulum", "--method", "generalized_alpha", "--rho-inf", "0.5",
                 "--h", "1e-3", "--t-end", "1", "--adaptive", "estimated", "--err-rtol", "1e-5",
                 "--dt-out", "0.5", "--no-watch", "--outputs", "energy", "residuals",
                 "--penalty", "1e7", "10", "1", "--out", out)
    assert p.returncode == 0, p.stderr
    assert "estimated step-size control, err_rtol = 1e-05" in p.stdout
    r = mbdk.simulate(mbdk.scene("double_pendulum"), "generalized_alpha", rho_inf=0.5, h=1e-3,
                      t_end=1, adaptive="estimated", err_rtol=1e-5, dt_out=0.5, watch=False,
                      outputs=("energy", "residuals"))
    back = load_result(out)
    assert np.array_equal(back.q, r.q) and back.a is None and back.energy is not None
    assert back.manifest["watch"] == r.manifest["watch"]


def test_watch_tolerances_and_solve_options():
    """--watch takes name=value tolerances (a tight energy tolerance stops explicit Euler by
    name); solve takes rtol, params and y0 (the decay problem's closed form y0 exp(-lambda t))."""
    p = mbdk_cli("run", "double_pendulum", "--method", "explicit_euler", "--h", "1e-3",
                 "--t-end", "1", "--watch", "energy=1e-6,every=1", "--out", "x.npz")
    assert p.returncode == 2 and "EnergyDriftError" in p.stderr, p.stderr
    p = mbdk_cli("solve", "decay", "dopri54", "--t-end", "2", "--rtol", "1e-10", "--atol",
                 "1e-12", "--params", "lambda=0.5", "--y0", "3")
    assert p.returncode == 0, p.stderr
    y = float(p.stdout.split("y = [")[1].split("]")[0])
    assert y == pytest.approx(3 * np.exp(-1.0), rel=1e-8)
    assert "CPU" in p.stdout and "steps" in p.stdout


def test_scenes_lists_every_built_in_scene_with_its_kind():
    p = mbdk_cli("scenes")
    assert p.returncode == 0
    names = [line.split()[0] for line in p.stdout.splitlines()]
    assert sorted(names) == sorted(mbdk.scenes("all"))
    assert any(line.split()[1] == "spatial" for line in p.stdout.splitlines())


def test_check_assembles_and_says_what_moved(tmp_path):
    """A slider 0.118 m off its guide: check moves it onto the joint and says by how much (it
    passed silently before); the usage of check is check's."""
    path = tmp_path / "off.toml"
    path.write_text("""
[scene]
name = "off"
[[body]]
name = "slider"
mass = 1.0
inertia = 0.1
x = 0.3
y = 0.118
given = ["x"]
[[joint]]
name = "guide"
type = "prismatic"
body1 = "slider"
body2 = "ground"
axis = [1.0, 0.0]
""")
    p = mbdk_cli("check", path)
    assert p.returncode == 0, p.stderr
    assert "assembly:" in p.stdout and "slider.y by -0.118" in p.stdout, p.stdout
    assert "1 body, 3 coordinates" in p.stdout and "1 degree of freedom" in p.stdout
    assert mbdk_cli("check", "--help").stdout.startswith("usage: mbdk check")


def test_workers_beside_a_scheduler_is_refused(tmp_path):
    p = mbdk_cli("sweep", "grid.toml", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1",
                 "--out", "t.csv", cwd=tmp_path)
    assert p.returncode == 2 and "the scheduler's cluster has its own workers" in p.stderr


@pytest.mark.parametrize("t, text", [(2.5e-4, "250 us"), (0.0123, "12.3 ms"), (4.89, "4.89 s"),
                                     (185.0, "3 min 5 s")])
def test_times_print_in_plain_units(t, text):
    assert cli.seconds(t) == text


def test_a_signature_keyword_without_help_is_an_error():
    def f(*, x: float = 1.0, y: int = 2):
        return x, y
    import argparse
    with pytest.raises(mbdk.InvalidInputError, match="'y' has no command-line help"):
        cli_options.add_options(argparse.ArgumentParser(), f, {"x": "x"}, set())
    assert inspect.signature(f)
