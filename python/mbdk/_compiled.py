"""How Python calls a compiled solve: without the GIL, and interruptible.

The f2py layer marks the solves threadsafe, so f2py releases the GIL around them: solves in
two Python threads run at once. Each call gets an interrupt flag (a one-element int32 array)
whose address the kernel polls once per step; set non-zero, the solve ends with
ERR_INTERRUPTED and keeps the samples it wrote.

Ctrl-C reaches Python as KeyboardInterrupt in the main thread only, and only when the main
thread runs Python code. So a long solve started from the main thread runs in a worker thread
while the main thread waits on it; a KeyboardInterrupt during the wait sets the flag, the kernel
returns within a step, and the caller raises SolveInterrupted (a KeyboardInterrupt) carrying
the partial result. Short solves (under LONG_WORK state-steps) run in the calling thread: they
end within milliseconds. The worker is one thread, started at the first long solve and kept:
a fresh thread per solve would open a new malloc arena with its first allocations, each time.
Only the main thread hands it work, and waits while it runs, so it serves one solve at a time.
A forked child (multiprocessing's default on Linux) has no copy of the thread: it starts its
own. A second Ctrl-C while the kernel winds down gives up the wait: the worker finishes the
solve unseen (its arrays stay referenced) and the next long solve gets a fresh worker.
"""
from __future__ import annotations

import os
import queue
import threading

import numpy as np

#: steps x state size above which a solve from the main thread runs in a worker thread
LONG_WORK = 200_000


def new_flag() -> np.ndarray:
    return np.zeros(1, dtype=np.int32)


class _Worker:
    """The kept worker thread: runs one (fn, args) at a time for the main thread."""

    def __init__(self):
        self._jobs = queue.SimpleQueue()
        threading.Thread(target=self._loop, name="mbdk-solve", daemon=True).start()

    def _loop(self):
        while True:
            fn, args, box, done = self._jobs.get()
            try:
                box["out"] = fn(*args)
            except BaseException as exc:  # re-raised in the caller's thread
                box["exc"] = exc
            finally:
                done.set()

    def submit(self, fn, args, box, done):
        self._jobs.put((fn, args, box, done))


_worker = None


def _forget_worker():
    global _worker
    _worker = None


os.register_at_fork(after_in_child=_forget_worker)


def call(fn, args: tuple, flag: np.ndarray, work: float):
    """fn(*args) (a threadsafe kernel entry that polls flag). Returns (fn's results, whether a
    KeyboardInterrupt was turned into the flag)."""
    global _worker
    if work < LONG_WORK or threading.current_thread() is not threading.main_thread():
        return fn(*args), False
    if _worker is None:
        _worker = _Worker()
    box, done = {}, threading.Event()
    _worker.submit(fn, args, box, done)
    # waiting on an Event, not on Thread.join: a KeyboardInterrupt inside join can leave the
    # thread looking finished while it still runs (CPython 3.11)
    interrupted = False
    while True:
        try:
            if done.wait(0.1):
                break
        except KeyboardInterrupt:
            if interrupted:     # the second Ctrl-C: stop waiting
                _worker = None
                raise
            flag[0] = 1
            interrupted = True
    if "exc" in box:
        raise box["exc"]
    return box["out"], interrupted
