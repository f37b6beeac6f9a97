"""Sweeps on Dask (mbdk.sweep, issue 24): a grid of runs as independent tasks, on a local
cluster of processes or a scheduler's address, gathered into one table with each run's error
against its reference, identical bit for bit to the serial loop of the same tasks; bad grids
named before any task starts; a case that fails when loaded or run is its rows, with its
error's class and message (issue 36)."""
import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mbdk import InvalidInputError
from mbdk.sweep import COLUMNS, load_grid, same_rows, sweep, tasks_of

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


STUDY_GRIDS = Path(__file__).resolve().parents[1] / "studies" / "grids"


def test_the_work_precision_grid_runs_on_a_local_cluster_with_the_serial_bits():
    """The work-precision study's grid file (every fixed-step method on seven problems, seven
    steps each, the error over 100 samples) on 2 local worker processes and serially: the
    same 525 rows, bit for bit, in the same order (the runs go out in round-robin batches)."""
    from mbdk import methods
    grids = [{**g, "min_cpu": 0.0} for g in load_grid(STUDY_GRIDS / "work_precision.toml")]
    # the file keeps up with the registry: every fixed-step ODE method but bdf1 (implicit
    # Euler's formula), euler_cromer only on the second-order problems
    fixed = set(methods("ode", step="fixed")) - {"bdf1"}
    for g in grids:
        assert set(g["methods"]) | {"euler_cromer"} == fixed | {"euler_cromer"}, g["problems"]
    serial = sweep(grids, workers=0)
    local = sweep(grids, workers=2)
    assert len(serial.rows) == 525 and same_rows(serial, local)
    assert all(r["status"] == "SUCCESS" for r in serial.rows)
    # fourth order where it should be: rk4's error falls 16-fold per halving on the riccati
    # problem (closed form) and on the double pendulum (against rk4 at 16x the finest step)
    for case in ("riccati", "double_pendulum"):
        e = [r["error"] for r in serial.rows if r["case"] == case and r["method"] == "rk4"]
        ratios = np.array(e[1:4]) / np.array(e[:3])
        assert np.all((ratios > 1 / 20) & (ratios < 1 / 12)), (case, ratios)


def test_samples_params_and_labels_against_direct_runs():
    """The error over samples equals the same comparison done by hand: rk4 on the double
    pendulum against rk4 at 8x the step, over 20 samples; and bdf on the stiff decay
    (params) against its closed form exp(-lambda t) over 40 samples, under its label."""
    import mbdk
    grids = [{"t_end": 2.0, "problems": ["double_pendulum"], "methods": ["rk4"],
              "step_counts": [200], "samples": 20,
              "reference": {"method": "rk4", "step_count": 1600}},
             {"t_end": 1.0, "problems": ["decay"], "params": {"lambda": 1.0e4},
              "label": "stiff decay", "methods": ["bdf"], "tolerances": [1e-8],
              "samples": 40}]
    rows = sweep(grids, workers=0).rows
    run = mbdk.solve_ode("double_pendulum", "rk4", h=0.01, t_end=2.0, every=10)
    ref = mbdk.solve_ode("double_pendulum", "rk4", h=2.0 / 1600, t_end=2.0, every=80)
    assert run.y.shape == (21, 4)
    assert rows[0]["error"] == np.max(np.abs(run.y - ref.y)) > 0
    d = mbdk.solve_ode("decay", "bdf", rtol=1e-8, atol=1e-10, t_end=1.0, dt_out=1.0 / 40,
                       params={"lambda": 1.0e4})
    assert rows[1]["case"] == "stiff decay" and rows[1]["steps"] == d.stats.steps
    assert rows[1]["error"] == np.max(np.abs(d.y[:, 0] - np.exp(-1.0e4 * d.t)))
    assert rows[1]["orders"] and rows[1]["nlu"] == d.stats.nlu


@pytest.mark.parametrize("change, text", [
    (dict(steps=None, step_counts=[150], samples=100), "150, which does not land on the 100"),
    (dict(steps=[0.025], samples=30), "do not land on the 30 samples"),
    (dict(params={"lam": 2.0}), "'params' is for problems"),
    (dict(scenes=[], problems=["decay"], params={"lam": 2.0}), "'lam', not a parameter of decay"),
    (dict(label="x"), "names the grid's one case"),
    (dict(reference={"method": "rk4", "n": 3}), "'reference' has 'n'"),
    (dict(min_cpu=-1.0), "'min_cpu' has -1.0"),
    (dict(samples=0), "'samples' has 0"),
    (dict(min_cpu="fast"), "'min_cpu' has 'fast', not a finite number"),
    (dict(t_end="ten"), "'t_end' has 'ten', not a finite number"),
    (dict(step_counts=[100]), "'steps' or 'step_counts', not both"),
    (dict(problems=[], steps=[0.26], samples=2, methods=["rk4"]),
     "0.26, which does not divide the interval"),
    (dict(reference={"method": "rk4"}), "give its h or step_count"),
])
def test_bad_grid_fields_are_named(change, text):
    grid = {k: v for k, v in {**GRID, **change}.items() if v is not None}
    with pytest.raises(InvalidInputError, match=text):
        tasks_of(grid)


def test_a_list_of_grids_names_the_bad_one():
    with pytest.raises(InvalidInputError, match="sweep grid 2 of 2: field 'methods' has 'rk5'"):
        tasks_of([GRID, {**GRID, "methods": ["rk5"]}])


def test_a_failed_reference_is_named_in_every_row_it_leaves_without_an_error():
    """The reference run overflows (explicit Euler at 50 s steps on the double pendulum): its
    cases' rows say so, with no error, rather than a success with NaN."""
    rows = sweep({"t_end": 1000.0, "problems": ["double_pendulum"], "methods": ["rk4"],
                  "step_counts": [100000],
                  "reference": {"method": "explicit_euler", "step_count": 20}}, workers=0).rows
    assert rows[0]["status"] == "reference NonFiniteSolutionError"
    assert np.isnan(rows[0]["error"]) and rows[0]["steps"] == 100000


def _failing_solve_ode(failing):
    """mbdk.ode.solve_ode, raising ZeroDivisionError (not an mbdk error) for the (problem, method)
    pairs in failing: a stand-in for a bug inside a run. Built here and pickled by value, so
    that a Dask worker can install it too."""
    def install():
        import mbdk.ode
        real = getattr(mbdk.ode.solve_ode, "real", mbdk.ode.solve_ode)

        def solve_ode(problem, method, **kw):
            if (problem, method) in failing:
                raise ZeroDivisionError(f"boom in {problem}/{method}\nsecond line")
            return real(problem, method, **kw)
        solve_ode.real = real
        mbdk.ode.solve_ode = solve_ode
        return True
    return install


def _failing_grid(tmp_path):
    broken = tmp_path / "broken.toml"
    broken.write_text('[[body]]\nname = "a"\nmass = -1\n')
    return [{"t_end": 1.0, "scenes": ["double_pendulum", str(tmp_path / "missing.toml"),
                                      str(broken)], "methods": ["rk4"], "steps": [1e-2]},
            {"t_end": 1.0, "problems": ["double_pendulum", "trolley_crane"],
             "methods": ["rk4"], "steps": [1e-2]}]


FAILING = {("double_pendulum", "rk4"), ("trolley_crane", "dopri54")}


def _check_failing_rows(rows, tmp_path):
    by_case = {r["case"]: r for r in rows}
    assert len(rows) == 5      # double_pendulum twice: the scene and the problem
    scene, problem = [r for r in rows if r["case"] == "double_pendulum"]
    assert scene["status"] == "SUCCESS" and scene["error"] > 0 and not scene["error_message"]
    missing = by_case[str(tmp_path / "missing.toml")]
    assert missing["status"] == "SceneError" and np.isnan(missing["error"])
    assert "missing.toml: cannot read the scene file" in missing["error_message"]
    broken = by_case[str(tmp_path / "broken.toml")]
    assert broken["status"] == "SceneError" and "'mass' = -1" in broken["error_message"]
    # a non-mbdk exception in the run: its class and its message, on one line
    assert problem["status"] == "ZeroDivisionError" and problem["steps"] == 0
    assert problem["error_message"] == "boom in double_pendulum/rk4 second line"
    # the reference run raised: the run itself gave its counts, but no error
    crane = by_case["trolley_crane"]
    assert crane["status"] == "reference ZeroDivisionError" and crane["steps"] == 100
    assert np.isnan(crane["error"])
    assert crane["error_message"] == ("the reference run: boom in trolley_crane/dopri54 "
                                      "second line")


def test_a_case_that_fails_is_its_rows_serially_and_on_dask(tmp_path, monkeypatch):
    """A missing scene file, a scene that does not build (SceneError), a run and a reference
    run that raise a non-mbdk exception: each case gives its rows, with the exception's class
    in the status and its message in error_message; the other cases run as usual; a cluster
    reached by its address gives the same rows (its worker raising the same exception)."""
    import mbdk
    from dask.distributed import Client, LocalCluster
    grid = _failing_grid(tmp_path)
    monkeypatch.setattr(mbdk.ode, "solve_ode", mbdk.ode.solve_ode)     # restored after the test
    _failing_solve_ode(FAILING)()
    serial = sweep(grid, workers=0)
    _check_failing_rows(serial.rows, tmp_path)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        with Client(cluster) as client:
            assert all(client.run(_failing_solve_ode(FAILING)).values())
        on_dask = sweep(grid, scheduler=cluster.scheduler_address)
    _check_failing_rows(on_dask.rows, tmp_path)
    assert same_rows(serial, on_dask)
    # the table keeps its columns, the message last
    out = tmp_path / "table.csv"
    serial.to_csv(out)
    with open(out, newline="") as fh:
        table = list(csv.DictReader(fh))
    assert list(table[0]) == COLUMNS
    assert list(table[0])[-1] == "error_message"
    assert [r["error_message"] for r in table] == [r["error_message"] for r in serial.rows]
    assert [r["status"] for r in table] == [r["status"] for r in serial.rows]


def test_a_bad_scheduler_address_is_named():
    with pytest.raises(InvalidInputError, match="scheduler = 'not an address': cannot connect"):
        sweep({**GRID, "problems": [], "methods": ["rk4"]}, scheduler="not an address")


def test_a_grid_file_that_is_not_text_is_named(tmp_path):
    grid = tmp_path / "grid.toml"
    grid.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(InvalidInputError, match=r"grid.toml: not a TOML text file: byte 0x80 "
                                                r"at offset 128"):
        load_grid(grid)
