"""Ctrl-C and solves in threads (issue 36): every solve's interrupt flag is kept in a registry
of live flags (mbdk._compiled), and the SIGINT handler mbdk installs over Python's default sets
them all before raising KeyboardInterrupt in the main thread, so that solves running in threads
of one's own stop within a step too, each with SolveInterrupted."""
import json
import os
import signal
import subprocess
import sys
import weakref

import pytest

from mbdk import _compiled


def python(script):
    """script in a fresh interpreter, with SIGINT as a shell gives it (the default), even where
    the tests run with it ignored; its standard output as JSON."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "MBDK_PROGRESS": "0"}
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env,
                       preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


THREADS = """
import json, os, signal, threading
import mbdk
from mbdk import _compiled

made = []
new_flag = _compiled.new_flag
def keep():
    made.append(new_flag())
    return made[-1]
_compiled.new_flag = keep
T_END = 20.0
ended = {}
def ode():      # 2e7 steps of a compiled problem
    try:
        r = mbdk.solve_ode("pendulum", "rk4", h=1e-6, t_end=T_END, every=10**6)
        ended["ode"] = ["finished", r.status.name, float(r.t[-1])]
    except mbdk.SolveInterrupted as e:
        ended["ode"] = ["SolveInterrupted", e.result.status.name, float(e.result.t[-1])]
def scene():    # 2e6 steps of a scene
    try:
        r = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-5, t_end=T_END,
                          every=10**5, outputs=())
        ended["scene"] = ["finished", r.status.name, float(r.t[-1])]
    except mbdk.SolveInterrupted as e:
        ended["scene"] = ["SolveInterrupted", e.result.status.name, float(e.result.t[-1])]
threads = [threading.Thread(target=f) for f in (ode, scene)]
for th in threads:
    th.start()
# both solves have taken a step (the kernel stores the time reached in their flags)
while (len(made) < 2 or min(_compiled.progress_of(f) for f in made) <= 0) \\
        and all(th.is_alive() for th in threads):
    threading.Event().wait(0.001)
started = [_compiled.progress_of(f) for f in made]
try:
    os.kill(os.getpid(), signal.SIGINT)      # what Ctrl-C sends
    for th in threads:                       # the main thread, waiting in user code
        th.join()
    main = "no KeyboardInterrupt"
except KeyboardInterrupt:
    main = "KeyboardInterrupt"
for th in threads:
    th.join()
print(json.dumps({"main": main, "ended": ended, "started": started,
                  "reached": [_compiled.progress_of(f) for f in made],
                  "flags": [int(f[0]) for f in made]}))
"""


def test_ctrl_c_stops_the_solves_of_every_thread():
    """Two long solves (a compiled problem and a scene) in threads of one's own, SIGINT sent to
    the process once both have taken a step: the main thread gets its KeyboardInterrupt, and
    each solve ends with SolveInterrupted (status ERR_INTERRUPTED) before t_end, the time its
    kernel reached short of it, rather than running on to the end as the default handler
    would leave them."""
    d = python(THREADS)
    assert d["main"] == "KeyboardInterrupt", d
    assert len(d["started"]) == 2 and min(d["started"]) > 0, d
    for name in ("ode", "scene"):
        how, status, t_last = d["ended"][name]
        assert (how, status) == ("SolveInterrupted", "ERR_INTERRUPTED"), d
        assert t_last < 20.0, d
    assert max(d["reached"]) < 20.0 and d["flags"] == [1, 1], d


HANDLER = """
import json, signal, threading
def mine(signum, frame):
    pass
if CUSTOM:
    signal.signal(signal.SIGINT, mine)
import mbdk
from mbdk import _compiled
h = signal.getsignal(signal.SIGINT)
other = []
th = threading.Thread(target=lambda: other.append(_compiled.install_sigint_handler()))
th.start(); th.join()
print(json.dumps({"ours": h is _compiled.sigint_handler, "mine": h is mine, "other": other}))
"""


def test_the_handler_is_installed_over_the_default_only():
    """At import, from the main thread, over Python's default handler; a handler of one's own
    is left alone; another thread cannot install it (signal.signal works in the main thread
    only) and says so."""
    assert python(HANDLER.replace("CUSTOM", "False")) == {"ours": True, "mine": False,
                                                         "other": [False]}
    assert python(HANDLER.replace("CUSTOM", "True")) == {"ours": False, "mine": True,
                                                        "other": [False]}


def test_the_registry_holds_live_flags_only():
    """A flag is in the registry while it exists; once freed (its solve's arrays with it), its
    entry is gone too."""
    flags = [_compiled.new_flag() for _ in range(3)]
    assert all(any(f is g for g in _compiled.live_flags()) for f in flags)
    refs = [weakref.ref(f) for f in flags]
    del flags
    assert all(r() is None for r in refs)
    assert all(r() is not None for r in list(_compiled._live.values()))


def test_ctrl_c_while_a_bar_draws_is_raised_when_it_is_drawn():
    """A KeyboardInterrupt raised inside tqdm would leave a half-drawn bar that is never
    cleared: while a bar draws, the handler sets the flags at once but raises when the
    drawing is done."""
    flag = _compiled.new_flag()
    done = []
    with pytest.raises(KeyboardInterrupt):
        with _compiled._drawing:
            _compiled.sigint_handler(signal.SIGINT, None)
            done.append(int(flag[0]))
    assert done == [1] and not _compiled._drawing.pending
    with pytest.raises(KeyboardInterrupt):      # outside a drawing: at once, as the default
        _compiled.sigint_handler(signal.SIGINT, None)
