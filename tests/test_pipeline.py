"""The one scene pipeline: every method through simulate, outputs only on request, solves that
release the GIL, and Ctrl-C that stops a long solve with its partial result."""
import _thread
import multiprocessing
import signal
import threading

import numpy as np
import pytest

import mbdk
from mbdk.benchmarks import bar_chain


def test_trapezoidal_index3_is_a_method_of_the_registry():
    info = mbdk.methods()["trapezoidal_index3"]
    assert info.solves == "dae" and info.order == 2 and info.implicit
    assert "trapezoidal_index3" not in mbdk.methods("ode")
    assert set(mbdk.methods("ode")) | set(mbdk.methods("dae")) == set(mbdk.methods())
    with pytest.raises(mbdk.NotApplicableError, match="index-3 DAE"):
        mbdk.solve_ode("pendulum", "trapezoidal_index3", h=1e-3, t_end=1.0)
    r = mbdk.simulate(mbdk.scene("double_pendulum"), "trapezoidal_index3", h=1e-3, t_end=0.1)
    assert r.manifest["formulation"] == "augmented_lagrangian"
    assert r.iterations is not None and r.iterations.shape == r.t.shape


@pytest.mark.parametrize("method,formulation", [("rk4", "reduced"), ("bdf2", "baumgarte"),
                                                ("rk4", "projection"),
                                                ("trapezoidal_index3", "augmented_lagrangian"),
                                                ("trapezoidal_index3", "index3")])
def test_outputs_are_computed_only_when_asked_and_change_nothing_else(method, formulation):
    sc = mbdk.scene("four_bar")
    kw = dict(formulation=formulation, h=1e-3, t_end=0.2, every=10)
    full = mbdk.simulate(sc, method, **kw)
    bare = mbdk.simulate(sc, method, outputs=(), **kw)
    assert np.array_equal(full.t, bare.t) and np.array_equal(full.q, bare.q)
    assert np.array_equal(full.v, bare.v)
    assert bare.a is None and bare.multipliers is None and bare.reactions is None
    assert bare.energy is None and bare.residuals is None and bare.manifest["outputs"] == []
    # the output pass visits the joints at every sample; a run without it does not
    assert bare.visits["revolute"] < full.visits["revolute"]
    one = mbdk.simulate(sc, method, outputs=("energy",), **kw)
    assert np.array_equal(one.energy, full.energy) and one.residuals is None
    some = mbdk.simulate(sc, method, outputs=("reactions", "residuals"), **kw)
    assert np.array_equal(some.reactions, full.reactions)
    assert np.array_equal(some.residuals, full.residuals)
    with pytest.raises(mbdk.NotApplicableError, match="reactions"):
        bare.reaction("A")
    with pytest.raises(mbdk.NotApplicableError, match="energy"):
        bare.energy_balance()


def test_unknown_outputs_and_options_are_named():
    sc = mbdk.scene("double_pendulum")
    with pytest.raises(mbdk.InvalidInputError, match="'power'.*unknown"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.1, outputs=("energy", "power"))
    with pytest.raises(mbdk.InvalidInputError, match="adaptive: options of the index-3 methods"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.1, adaptive=True)


def _long_rk4(sc, t_end=4.0):
    return mbdk.simulate(sc, "rk4", h=1e-5, t_end=t_end, every=50000, outputs=())


def test_two_solves_in_two_threads_agree_bit_for_bit_with_serial_runs():
    """f2py releases the GIL around the solve: two threads give the same bits as serial runs,
    and each reports its own thread's CPU time (a process clock would count both threads and
    exceed the run's wall time when they overlap)."""
    sc1, sc2 = mbdk.scene("double_pendulum"), mbdk.scene("four_bar")
    serial = [_long_rk4(sc1, 2.0), _long_rk4(sc2, 2.0)]
    out = [None, None]

    def run(i, sc):
        out[i] = _long_rk4(sc, 2.0)
    threads = [threading.Thread(target=run, args=(i, sc)) for i, sc in enumerate((sc1, sc2))]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    for s, p in zip(serial, out):
        assert np.array_equal(s.q, p.q) and np.array_equal(s.v, p.v)
        assert p.stats.cpu_time <= 1.1 * p.stats.wall_time + 2e-3


def test_the_gil_is_free_while_a_solve_runs():
    """While another thread's solve runs, this thread keeps executing Python: with the GIL held
    by the solve it could not take a single turn until the solve ended."""
    sc = mbdk.scene("double_pendulum")
    worker = threading.Thread(target=_long_rk4, args=(sc, 2.0))
    turns = 0
    worker.start()
    while worker.is_alive():
        turns += 1
    worker.join()
    assert turns > 10_000


#: a process started as a background job of a non-interactive shell ignores SIGINT (POSIX): no
#: Ctrl-C reaches it, nor _thread.interrupt_main's, and mbdk leaves the ignoring in place
SIGINT_IGNORED = pytest.mark.skipif(signal.getsignal(signal.SIGINT) is signal.SIG_IGN,
                                    reason="SIGINT is ignored in this process (a background job)")


@SIGINT_IGNORED
@pytest.mark.parametrize("method,formulation", [("rk4", "reduced"),
                                                ("trapezoidal_index3", "augmented_lagrangian")])
def test_ctrl_c_stops_a_long_solve_and_keeps_its_partial_result(method, formulation):
    """A KeyboardInterrupt in the main thread (what Ctrl-C raises) while a long solve runs sets
    its interrupt flag: the kernel stops within a step and the partial result comes back with
    SolveInterrupted, itself a KeyboardInterrupt. The run would take half a minute or more
    uninterrupted (bounded, so that a lost interrupt fails the test instead of hanging CI); the
    interrupt comes after 1 s, well after the set-up on a loaded machine."""
    sc = mbdk.scene("double_pendulum")
    timer = threading.Timer(1.0, _thread.interrupt_main)
    timer.start()
    try:
        with pytest.raises(mbdk.SolveInterrupted) as err:
            mbdk.simulate(sc, method, formulation=formulation, h=1e-5, t_end=300.0, every=1000)
    finally:
        timer.cancel()
    assert isinstance(err.value, KeyboardInterrupt)
    r = err.value.result
    assert r.status == mbdk.Status.ERR_INTERRUPTED and not r.success
    assert 0 < r.t[-1] < 300.0 and len(r.t) > 1, (r.t[-1], len(r.t))
    assert np.all(np.isfinite(r.q)) and r.residuals[:, 0].max() < 1e-8, r.residuals[:, 0].max()
    assert r.stats.steps >= (len(r.t) - 2) * 1000, (r.stats.steps, len(r.t))   # index3 adds the state it stopped at


def _long_rk4_steps():
    return _long_rk4(mbdk.scene("double_pendulum"), 0.5).stats.steps


def test_a_forked_child_runs_long_solves_with_a_worker_of_its_own():
    """A long solve in the parent starts the kept worker thread; a child forked afterwards
    (multiprocessing's default on Linux) has no copy of that thread and must start its own
    rather than queue work nobody runs (it would wait forever). Bounded by the timeout."""
    assert _long_rk4_steps() == 50_000      # long enough for the worker (LONG_WORK)
    with multiprocessing.get_context("fork").Pool(1) as pool:
        assert pool.apply_async(_long_rk4_steps).get(timeout=60) == 50_000


@SIGINT_IGNORED
def test_ctrl_c_stops_a_long_ode_solve():
    timer = threading.Timer(0.3, _thread.interrupt_main)
    timer.start()
    try:
        with pytest.raises(mbdk.SolveInterrupted) as err:
            mbdk.solve_ode("pendulum", "rk4", h=1e-6, t_end=1e3, every=100000)
    finally:
        timer.cancel()
    r = err.value.result
    assert r.status == mbdk.Status.ERR_INTERRUPTED and 0 < r.t[-1] < 1e3


def test_a_callback_solve_inside_a_callback_is_refused_not_deadlocked():
    def inner(t, y):
        return [-y[0]]

    def outer(t, y):
        mbdk.solve_ode(inner, "rk4", h=0.1, t_end=0.2, y0=[1.0])
        return [-y[0]]
    with pytest.raises(mbdk.CallbackError) as err:
        mbdk.solve_ode(outer, "rk4", h=0.1, t_end=0.2, y0=[1.0])
    assert isinstance(err.value.__cause__, mbdk.NotApplicableError)
    assert "nested callback solves are refused" in str(err.value)

    # a compiled solve inside a callback is fine, and a callback solve after the refusal too
    def with_compiled(t, y):
        k = mbdk.solve_ode("decay", "rk4", h=0.1, t_end=0.2).y[-1, 0]
        return [-k * 0 - y[0]]
    r = mbdk.solve_ode(with_compiled, "rk4", h=0.1, t_end=0.2, y0=[1.0])
    assert r.success and abs(r.y[-1, 0] - np.exp(-0.2)) < 1e-5


def test_the_kernel_assembles_and_takes_pose_values_at_the_assembled_pose():
    """The four-bar's coupler drawn 0.1 rad off its assembled angle, with a spring (no rest
    length given) from the coupler to the ground: the kernel moves the coordinates not given
    until every joint holds, keeps the given crank angle, and takes the spring's rest length at
    the assembled pose (so the spring starts relaxed: zero potential energy), all in the one run."""
    import tomllib
    from pathlib import Path
    from mbdk.scene_file import scene_from_dict
    d = tomllib.loads((Path(mbdk.__file__).parent / "scenes" / "four_bar.toml").read_text())
    coupler = d["body"][1]
    d["force"].append({"name": "k", "type": "spring", "body1": coupler["name"],
                       "point1": [0.4, 0.0], "body2": "ground", "point2": [0.3, -1.0],
                       "stiffness": 50.0})
    coupler["angle_deg"] += 5.7
    coupler["x"] += 0.05
    sc = scene_from_dict(d, "four_bar + spring")
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01)
    assert r.assembly["iterations"] >= 1 and r.assembly["moved_q"] > 0.05
    assert r.residuals[0, 0] < 1e-12 and r.residuals[0, 1] < 1e-12
    for i, b in enumerate(sc.bodies):
        if "angle" in b.given:
            assert r.q[0, 3 * i + 2] == sc.q0()[3 * i + 2]
    assert abs(r.energy_parts["potential_springs"][0]) < 1e-20
    # the same tables resolved at the scene's own (unassembled) pose would stretch the spring
    tab = mbdk.model.build_tables(sc)
    assert abs(tab.freal[5, len(sc.forces) - 1] - mbdk.model.build_tables(sc, r.q[0]).freal[
        5, len(sc.forces) - 1]) > 1e-3


@pytest.mark.parametrize("formulation", ["index3", "augmented_lagrangian"])
def test_visits_count_newton_iterations_and_tangents(formulation):
    """trapezoidal_index3 evaluates the forces once per Newton iteration (nfev, the consistent
    start included) and their tangent once per Newton matrix (nlu): the spring's visits are
    exactly their sum, gravity (no tangent) is visited nfev times, and the hinge once per
    matrix on top of its constraint evaluations."""
    sc = mbdk.scene("spring_bar")
    r = mbdk.simulate(sc, "trapezoidal_index3", formulation=formulation, h=1e-3, t_end=0.2,
                      outputs=())
    assert r.stats.nlu >= 1 and r.stats.nfev > r.stats.steps
    assert r.visits["spring"] == r.stats.nfev + r.stats.nlu
    assert r.visits["gravity"] == r.stats.nfev
    assert r.visits["revolute"] >= r.stats.nfev + r.stats.nlu


def test_public_evaluate_gives_a_state_that_solves_the_equations_of_motion():
    """mbdk.evaluate at a state off the initial one: the returned a and lambda satisfy
    M a + D^T lambda = f and D a = gamma with the returned M (from the scene's masses), D, f and
    gamma, checked here in numpy; bad states are named errors."""
    sc = mbdk.scene("four_bar")
    e0 = mbdk.evaluate(sc)
    q = np.array(sc.q0(), float)
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.3)
    e = mbdk.evaluate(sc, r.q[-1], r.v[-1], t=0.3)
    mass = np.repeat([[b.mass, b.mass, b.inertia] for b in sc.bodies], 1, axis=0).ravel()
    assert np.abs(mass * e["a"] + e["D"].T @ e["lam"] - e["f"]).max() < 1e-10
    assert np.abs(e["D"] @ e["a"] - e["gamma"]).max() < 1e-10
    assert np.allclose(e["a"], r.a[-1], rtol=1e-12, atol=1e-12)
    assert e0["phi"].size == 8 and np.abs(e0["phi"]).max() < 1e-12
    with pytest.raises(mbdk.InvalidInputError, match="entries"):
        mbdk.evaluate(sc, q[:3], r.v[-1])
    with pytest.raises(mbdk.InvalidInputError, match="finite"):
        mbdk.evaluate(sc, q * np.nan, r.v[-1])


def test_bodies_and_coordinates_outside_q_are_refused_not_written():
    """Element references the kernel would turn into writes outside q: a torque on a body with
    an empty name (read as the ground once), the same tables handed to the kernel directly
    (torque on body 0, a driver of coordinate 0), and masses changed after loading."""
    from mbdk.scene_file import scene_from_dict
    d = {"body": [{"name": "bar", "mass": 1.0, "inertia": 0.1}],
         "force": [{"type": "torque", "body": "", "torque": 1.0}]}
    with pytest.raises(mbdk.SceneError, match="field 'body' = '' is empty"):
        scene_from_dict(d)
    sc = mbdk.scene("physical_pendulum")
    tab = mbdk.model.build_tables(sc)
    y = np.concatenate([sc.q0(), sc.v0()])
    fint, freal = np.zeros((4, 1), np.int32, order="F"), np.zeros((12, 1), order="F")
    fint[:, 0] = [mbdk.codes.FORCE_CODES["torque"], 0, 0, 0]
    *_, status = mbdk._kernel.model_eval(tab.mass, tab.inertia, tab.kind, tab.nj, tab.jint, tab.jreal, 1,
                                         fint, freal, mbdk.ModelOptions().pack(), tab.m, 0.0, y)
    assert status == mbdk.Status.ERR_INVALID_INPUT
    jint = np.asfortranarray(np.hstack([tab.jint[:, :tab.nj], [[4], [1], [0], [0]]]), np.int32)
    jreal = np.asfortranarray(np.hstack([tab.jreal[:, :tab.nj], np.zeros((12, 1))]))
    *_, status = mbdk._kernel.model_eval(tab.mass, tab.inertia, tab.kind, tab.nj + 1, jint, jreal, tab.nf,
                                         tab.fint, tab.freal, mbdk.ModelOptions().pack(),
                                         tab.m + 1, 0.0, y)
    assert status == mbdk.Status.ERR_INVALID_INPUT
    sc.bodies[0].mass = -1.0
    with pytest.raises(mbdk.InvalidInputError, match="body 'bar': field 'mass' = -1.0"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01)


def test_a_callback_of_the_wrong_length_or_nan_is_a_named_failure():
    with pytest.raises(mbdk.CallbackError, match=r"shape \(1,\) for a state of 2 entries"):
        mbdk.solve_ode(lambda t, y: [y[1]], "rk4", h=0.1, t_end=1.0, y0=[1.0, 0.0])
    with pytest.raises(mbdk.CallbackError, match="non-finite"):
        mbdk.solve_ode(lambda t, y: [y[1], float("nan")], "rk4", h=0.1, t_end=1.0, y0=[1.0, 0.0])


def test_stability_analysis_names_the_index3_method_as_not_applicable():
    for f in (lambda: mbdk.stability_region("trapezoidal_index3"),
              lambda: mbdk.stability.amplification_factor("trapezoidal_index3", [-1.0])):
        with pytest.raises(mbdk.NotApplicableError, match="no step on y' = A y"):
            f()


def test_a_long_run_holds_its_results_once():
    """2 x 10^4 samples of a 64-bar chain with every output but reactions: the peak of Python's
    allocations during simulate (tracemalloc, which numpy reports to) stays within 1.1 times
    the result arrays it returns: the kernel writes them once and the result keeps them, with
    no copy (the arrays themselves are all but a few percent of the peak; a copy of the
    multipliers alone would add 0.18, one of q and v 0.6)."""
    import tracemalloc
    sc = bar_chain(64, -30.0)
    tracemalloc.start()
    try:
        r = mbdk.simulate(sc, "rk4", h=1e-5, t_end=0.2, every=1,
                          outputs=("a", "multipliers", "residuals"))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    held = sum(x.base.nbytes if x.base is not None else x.nbytes
               for x in {id(a.base if a.base is not None else a): a
                         for a in (r.t, r.q, r.v, r.a, r.multipliers, r.residuals)}.values())
    assert r.q.shape == (20_001, 192)
    assert peak < 1.1 * held
