"""Sweeps on Dask (mbdk.sweep, issue 24): a grid of runs as independent tasks, on a local
cluster of processes or a scheduler's address, gathered into one table with each run's error
against its reference, identical bit for bit to the serial loop of the same tasks; bad grids
named before any task starts."""
import subprocess
import sys

import numpy as np
import pytest

from mbdk import InvalidInputError
from mbdk.sweep import same_rows, sweep, tasks_of

GRID = {"t_end": 2.0, "scenes": ["double_pendulum"], "problems": ["damped_oscillator"],
        "methods": ["rk4", "dopri54"], "steps": [1e-2, 1e-3], "tolerances": [1e-6, 1e-9]}


def same(a, b):
    return same_rows(a, b)


def test_a_local_cluster_gives_the_serial_bits():
    """8 runs on 2 worker processes and serially: the same table (errors, steps, counters);
    the errors fall with the step and the tolerance (rk4 by about 10^4 per decade of h, the
    damped oscillator against its closed form, the double pendulum against dopri54 at
    rtol 1e-12)."""
    serial = sweep(GRID, workers=0)
    local = sweep(GRID, workers=2)
    assert serial.engine == "serial" and local.engine == "local cluster of 2 processes"
    assert len(serial.rows) == 8 and same(serial, local)
    rows = {(r["case"], r["method"], r["control"]): r["error"] for r in serial.rows}
    for case in ("double_pendulum", "damped_oscillator"):
        assert rows[(case, "rk4", 1e-3)] < rows[(case, "rk4", 1e-2)] / 1e3
        assert rows[(case, "dopri54", 1e-9)] < rows[(case, "dopri54", 1e-6)] / 100
    assert all(r["status"] == "SUCCESS" and r["cpu_time"] > 0 for r in serial.rows)


def test_a_scheduler_address_is_used():
    """A cluster started elsewhere, reached by its address (the --scheduler option)."""
    from dask.distributed import LocalCluster
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        r = sweep({**GRID, "problems": [], "methods": ["rk4"]}, scheduler=cluster.scheduler_address)
    assert r.engine.startswith("scheduler at tcp://")
    assert same(r, sweep({**GRID, "problems": [], "methods": ["rk4"]}, workers=0))


@pytest.mark.parametrize("change, text", [
    (dict(methods=["rk5"]), "'methods' has 'rk5'"),
    (dict(scenes=["nowhere"]), "'scenes' has 'nowhere'"),
    (dict(problems=["nothing"]), "'problems' has 'nothing'"),
    (dict(steps=[]), "rk4 needs steps"),
    (dict(speed=3), "unknown field 'speed'"),
    (dict(t_end=0.0), "t_end = 0.0"),
])
def test_bad_grids_are_named(change, text):
    with pytest.raises(InvalidInputError, match=text):
        tasks_of({**GRID, **change})


def test_the_command_line_writes_the_table(tmp_path):
    grid = tmp_path / "grid.toml"
    grid.write_text('[sweep]\nt_end = 1.0\nproblems = ["pendulum"]\nmethods = ["rk4"]\n'
                    'steps = [0.01, 0.001]\n')
    out = tmp_path / "table.csv"
    r = subprocess.run([sys.executable, "-m", "mbdk", "sweep", grid, "--workers", "0", "--out",
                        out], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "2 runs on serial" in r.stdout
    lines = out.read_text().splitlines()
    assert lines[0].startswith("case,method,formulation,control,status,error")
    errors = [float(x.split(",")[5]) for x in lines[1:]]
    assert len(errors) == 2 and errors[1] < errors[0] / 1e3 and np.all(np.isfinite(errors))
    bad = subprocess.run([sys.executable, "-m", "mbdk", "sweep", grid, "--workers", "0",
                          "--out", tmp_path / "t.txt"], capture_output=True, text=True)
    assert bad.returncode == 2 and "CSV" in bad.stderr and not (tmp_path / "t.txt").exists()
