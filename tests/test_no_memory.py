"""Out of memory is a named error, not the end of the process (issue 36).

Each case runs in a child process whose address space is limited (RLIMIT_AS, LIMIT), so that
the allocation fails the same way on every machine and nothing outside the child feels it
(OpenBLAS starts one thread, which keeps what it reserves at import small). The child reports
what it caught as JSON and then runs a small solve: the test checks that it exited normally,
that the error was NoMemoryError with ERR_NO_MEMORY, and that the size it names is the size of
what the run had to hold, counted here from the run's dimensions (not from the kernel's
arithmetic): bdf's Newton matrix and its LU factors, 2 n^2 doubles over its n unknowns (13 per
free spatial body: 7 coordinates, 6 velocities; si2 adds none without joints); the penalty
formulation's M + alpha_p D^T D, nc^2 doubles over the nc = 3 nb coordinates. The C side
(mbdk_stepper_create_ode with 2^27 states, a scene stepper of 2^24 bodies, bdf's Newton matrix
through mbdk_solve_ode) is kernel/tests/c_no_memory.c."""
import json
import os
import resource
import subprocess
import sys
import textwrap

import pytest

from mbdk.errors import format_bytes

#: the child's address space: the interpreter, numpy and the kernel fit, the runs' arrays not
LIMIT = 3 << 30


def _limit():
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT, LIMIT))


def run_child(body: str) -> dict:
    """body runs under the limit and sets `err` to what it caught; returns the report."""
    code = textwrap.dedent('''
        import json
        import mbdk
        err = None
    ''') + textwrap.dedent(body) + textwrap.dedent('''
        after = mbdk.solve_ode("damped_oscillator", "rk4", h=0.01, t_end=1.0)
        print(json.dumps({
            "type": type(err).__name__, "no_memory": isinstance(err, mbdk.NoMemoryError),
            "status": int(getattr(err, "status", 0)), "message": str(err),
            "alloc_bytes": err.result.stats.alloc_bytes if getattr(err, "result", None)
            else None,
            "samples": len(err.result.t) if getattr(err, "result", None) else None,
            "after": after.success}))
    ''')
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "MBDK_PROGRESS": "0"}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                          preexec_fn=_limit)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_bdf_si2_on_many_free_spatial_bodies_names_its_dense_newton_matrix():
    nb = 2000
    n = 13 * nb                                   # the unknowns: (r, p; v, Omega) per body
    newton = 2 * 8.0 * n * n                      # the Newton matrix and its LU factors
    rep = run_child(f'''
        from mbdk.scene_file import scene_from_dict
        bodies = [{{"name": f"b{{i}}", "kind": "spatial", "mass": 1.0,
                    "inertia": [0.1, 0.2, 0.3], "position": [float(i), 0.0, 0.0]}}
                  for i in range({nb})]
        sc = scene_from_dict({{"scene": {{"name": "free"}}, "body": bodies}}, "free.toml")
        try:
            mbdk.simulate(sc, "bdf", formulation="si2", rtol=1e-6, atol=1e-8, t_end=0.01)
        except MemoryError as e:
            err = e
    ''')
    assert rep["no_memory"] and rep["type"] == "NoMemoryError"
    assert rep["status"] == -7                    # ERR_NO_MEMORY
    assert newton <= rep["alloc_bytes"] < 1.01 * newton
    msg = rep["message"]
    assert format_bytes(rep["alloc_bytes"]) in msg            # the size asked for ...
    assert "26 000 x 26 000" in msg and "Newton matrix of bdf" in msg   # ... and what it was
    assert "bdf/si2 on spatial scene 'free' (2000 bodies)" in msg
    assert rep["samples"] == 1                    # the initial state, written before the run
    assert rep["after"]                           # the process goes on


def test_penalty_matrix_of_a_large_planar_scene_is_named_from_the_model_build():
    """The model is built before the run (mbdk_model_init): its failed allocation reaches
    Python through scene_run's statistics all the same."""
    nb = 20000
    nc = 3 * nb
    rep = run_child(f'''
        from mbdk.scene_file import scene_from_dict
        bodies = [{{"name": f"b{{i}}", "mass": 1.0, "inertia": 0.1, "x": float(i)}}
                  for i in range({nb})]
        sc = scene_from_dict({{"scene": {{"name": "row"}}, "body": bodies}}, "row.toml")
        try:
            mbdk.simulate(sc, "rk4", formulation="penalty", h=1e-3, t_end=0.01)
        except MemoryError as e:
            err = e
    ''')
    assert rep["no_memory"] and rep["status"] == -7
    assert rep["alloc_bytes"] == 8.0 * nc * nc   # M + alpha_p D^T D, dense
    assert format_bytes(rep["alloc_bytes"]) in rep["message"]
    assert "60 000 x 60 000" in rep["message"] and "penalty formulation" in rep["message"]
    assert rep["after"]


def test_a_spatial_model_too_large_to_check_is_no_memory_not_degenerate_joints():
    """simulate checks a spatial scene's initial state by one evaluation of its model before the
    run; a model too large for memory there is named as such (it read as degenerate joints,
    SingularMatrixError, when the failed build left the rank at 0). A chain of 3000 bodies on
    spherical joints closed into a loop by a last joint to the ground: a loop's rows are
    checked for redundancy on the whole C (a tree's, joint by joint, in memory that grows as
    its rows do), 9003 x 18 000 doubles (1.3 GB), the rank test's matrices 3 x 9003^2 (1.9 GB)
    more."""
    rep = run_child('''
        from mbdk.scene_file import scene_from_dict
        nb = 3000
        bodies = [{"name": f"b{i}", "kind": "spatial", "mass": 1.0, "inertia": [0.1, 0.2, 0.3],
                   "position": [i + 0.5, 0.0, 0.0]} for i in range(nb)]
        joints = [{"name": "j0", "type": "spherical", "body1": "b0", "at": [0.0, 0.0, 0.0]}] + [
            {"name": f"j{i}", "type": "spherical", "body1": f"b{i}", "body2": f"b{i - 1}",
             "at": [float(i), 0.0, 0.0]} for i in range(1, nb)] + [
            {"name": "close", "type": "spherical", "body1": f"b{nb - 1}",
             "at": [float(nb), 0.0, 0.0]}]
        sc = scene_from_dict({"scene": {"name": "chain"}, "body": bodies,
                                      "joint": joints}, "chain.toml")
        try:
            mbdk.simulate(sc, "rk4", h=1e-3, t_end=1e-3)
        except Exception as e:
            err = e
    ''')
    assert rep["no_memory"] and rep["status"] == -7, rep["message"]
    assert "spatial scene 'chain' (3000 bodies, 9003 constraint rows)" in rep["message"]
    assert rep["after"]


def test_a_driven_spatial_tree_is_checked_in_memory_that_grows_as_its_rows_do():
    """A chain of 3000 bodies on revolute joints (about z), its root held by an angle driver
    (f = 0; 15 001 rows): a tree, whose rows are checked connection by connection (the driver's
    with the revolute it drives, one connection of 6 rows), so it starts and runs within the
    child's 3 GB, where a dense C alone would take 2.2 GB and the rank test's matrices 5.4 GB
    more."""
    rep = run_child('''
        from mbdk.scene_file import scene_from_dict
        nb = 3000
        bodies = [{"name": f"b{i}", "kind": "spatial", "mass": 1.0, "inertia": [0.1, 0.2, 0.3],
                   "position": [i + 0.5, 0.0, 0.0]} for i in range(nb)]
        joints = [{"name": "j0", "type": "revolute", "body1": "b0", "at": [0.0, 0.0, 0.0],
                   "axis": [0, 0, 1]},
                  {"name": "drive", "type": "angle_driver", "body1": "b0", "axis": [0, 0, 1],
                   "function": {"rate": 0.0, "amplitude": 0.0, "omega": 2.0}}] + [
            {"name": f"j{i}", "type": "revolute", "body1": f"b{i}", "body2": f"b{i - 1}",
             "at": [float(i), 0.0, 0.0], "axis": [0, 0, 1]} for i in range(1, nb)]
        sc = scene_from_dict({"scene": {"name": "driven"}, "body": bodies,
                              "joint": joints}, "driven.toml")
        r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=5e-3)
        assert r.success and "sparse" in r.manifest["linear_solve"]
        assert sc.rows == 5 * nb + 1
    ''')
    assert rep["type"] == "NoneType", rep["message"]
    assert rep["after"]


def test_a_long_spatial_chain_runs_the_index3_family_in_memory_that_grows_as_its_bodies_do():
    """trapezoidal_index3 (book form) on a chain of 10 000 spatial bars (30 000 rows) runs within
    the child's 3 GB: compact rows and the model's sparse Newton matrix (mbdk_spatial_i3), where
    the dense path's C alone would take 14.4 GB (30 000 x 60 000 doubles) and its Newton matrix
    by differences 2 x 90 000^2 doubles."""
    rep = run_child('''
        import warnings
        from mbdk.benchmarks import spatial_chain
        warnings.simplefilter("ignore", mbdk.AccuracyWarning)
        r = mbdk.simulate(spatial_chain(10_000), "trapezoidal_index3", h=1e-3, t_end=3e-3,
                          formulation="index3")
        assert r.success and "colored columns" in r.manifest["linear_solve"]
    ''')
    assert rep["type"] == "NoneType", rep["message"]
    assert rep["after"]


@pytest.mark.parametrize("method, form", [("bdf", "si2"), ("ida", "index1")])
def test_a_long_spatial_chain_runs_the_dae_methods_in_memory_that_grows_as_its_bodies_do(
        method, form):
    """bdf (si2) and ida (index1) on the DAE of a chain of 10 000 spatial bars (30 000 rows;
    160 000 or 190 000 unknowns) run within the child's 3 GB (measured about 0.6 GB for the
    process): compact rows and sparse Newton matrices (bdf's own, mbdk_mechanism_dae; ida's
    by KLU, mbdk_ida), where a dense one and its LU would take 2 x 190 000^2 doubles (578 GB)
    and its Jacobian 190 001 evaluations of a dense C of 14.4 GB."""
    rep = run_child(f'''
        import warnings
        from mbdk.benchmarks import spatial_chain
        from mbdk.codes import DAE_NEWTON_MATRIX
        warnings.simplefilter("ignore", mbdk.AccuracyWarning)
        r = mbdk.simulate(spatial_chain(10_000), "{method}", formulation="{form}", rtol=1e-6,
                          atol=1e-8, t_end=2e-3)
        assert r.success and r.stats.nlu_sparse == r.stats.nlu > 0
        assert r.manifest["newton_matrix"] == DAE_NEWTON_MATRIX["{method}_sparse"]
    ''')
    assert rep["type"] == "NoneType", rep["message"]
    assert rep["after"]
