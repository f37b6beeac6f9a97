"""Progress of long solves (issue 24): the kernel stores the time it has reached, once per
step, where the options' progress field points (the second half of Python's interrupt flag),
and a solve that runs for more than a second from the main thread shows a tqdm bar on standard
error when that is a terminal or MBDK_PROGRESS=1 asks for it."""
import os
import subprocess
import sys

import numpy as np
import pytest

import mbdk
from mbdk import _compiled


@pytest.fixture
def flags(monkeypatch):
    made = []
    new_flag = _compiled.new_flag

    def keep():
        made.append(new_flag())
        return made[-1]
    monkeypatch.setattr(_compiled, "new_flag", keep)
    return made


@pytest.mark.parametrize("method, kw", [
    ("rk4", dict(h=1e-3, every=100)), ("dopri54", dict(rtol=1e-8, atol=1e-10)),
    ("bdf", dict(rtol=1e-7, atol=1e-9)), ("cvode_bdf", dict(rtol=1e-7, atol=1e-9)),
    ("ida", dict(rtol=1e-7, atol=1e-9)), ("trapezoidal_index3", dict(h=1e-3, every=100)),
])
def test_every_driver_reports_the_time_it_reached(flags, method, kw):
    """After a run of 0.7 s, the progress the kernel stored is where its last step began
    (error-controlled methods store it before a step, the fixed-step loops the step's end):
    within a step of 0.7, and exactly 0.7 for the fixed steps."""
    r = mbdk.simulate(mbdk.scene("double_pendulum"), method, t_end=0.7, **kw)
    p = _compiled.progress_of(flags[-1])
    if "h" in kw:
        assert p == pytest.approx(0.7, abs=1e-12)
    else:
        assert 0.7 - 0.7 / max(r.stats.steps, 1) * 50 < p <= 0.7


def test_a_compiled_problem_and_a_spatial_scene_report_it_too(flags):
    mbdk.solve_ode("pendulum", "rk4", h=1e-3, t_end=0.3)
    assert _compiled.progress_of(flags[-1]) == pytest.approx(0.3)
    mbdk.simulate(mbdk.scene("heavy_top"), "rk4", h=1e-3, t_end=0.2)
    assert _compiled.progress_of(flags[-1]) == pytest.approx(0.2)


SCRIPT = """
import mbdk
from mbdk import _compiled
_compiled.PROGRESS_AFTER = 0.0
r = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-5, t_end=10.0, every=10000)
print(r.status.name)
"""


@pytest.mark.parametrize("setting, shown", [("1", True), ("0", False)])
def test_a_long_run_shows_a_bar_when_asked(setting, shown):
    """A run of a million steps (about half a second here) from the main thread, its bar asked
    for with MBDK_PROGRESS=1 (standard error is a pipe here, so off by default), and not with
    0; the run's result is the same either way."""
    env = {**os.environ, "MBDK_PROGRESS": setting, "OPENBLAS_NUM_THREADS": "1"}
    r = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, env=env)
    assert r.returncode == 0 and r.stdout.strip() == "SUCCESS", r.stderr
    assert ("mbdk:" in r.stderr and "of 10 s" in r.stderr) == shown, r.stderr


def test_the_flag_keeps_the_interrupt_in_its_first_element():
    f = _compiled.new_flag()
    assert f.dtype == np.int32 and f.size == 4 and f.ctypes.data % 8 == 0


SWEEP = """
from mbdk import _compiled
from mbdk.sweep import sweep
_compiled.PROGRESS_AFTER = 0.0
t = sweep({"t_end": 1.0, "problems": ["pendulum"], "methods": ["rk4"],
           "step_counts": [10, 20, 40, 80]}, workers=WORKERS)
print(len(t.rows))
"""


@pytest.mark.parametrize("workers", [0, 2])
@pytest.mark.parametrize("setting, shown", [("1", True), ("0", False)])
def test_a_sweep_counts_its_runs_when_asked(setting, shown, workers):
    """A sweep's bar counts the runs done, serially and as a cluster's batches come back, when
    MBDK_PROGRESS=1 asks for it (shown at once here: PROGRESS_AFTER = 0), and is absent with 0."""
    env = {**os.environ, "MBDK_PROGRESS": setting, "OPENBLAS_NUM_THREADS": "1"}
    r = subprocess.run([sys.executable, "-c", SWEEP.replace("WORKERS", str(workers))],
                       capture_output=True, text=True, env=env)
    assert r.returncode == 0 and r.stdout.strip() == "4", r.stderr
    assert ("sweep:" in r.stderr and "/4 [" in r.stderr) == shown, r.stderr


def test_the_report_counts_its_studies_when_asked(tmp_path, root):
    """The report's bar over its studies, beside the lines it prints per study."""
    env = {**os.environ, "MBDK_PROGRESS": "1", "OPENBLAS_NUM_THREADS": "1"}
    script = ("from mbdk import _compiled; _compiled.PROGRESS_AFTER = 0.0\n"
              "from pathlib import Path\nfrom mbdk.report import build_report\n"
              f"build_report(Path({str(tmp_path)!r}), quick=True, "
              f"studies=Path({str(root / 'studies')!r}), "
              "only=['ch5_formulas'])\n")
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert "report:" in r.stderr and "/1 [" in r.stderr and "[1/1] ch5_formulas" in r.stdout
