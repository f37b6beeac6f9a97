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
While it waits, the main thread shows a progress bar (tqdm, on standard error) once a solve has
run for PROGRESS_AFTER seconds, when standard error is a terminal (or MBDK_PROGRESS=1 asks for
it): the kernel stores the time it has reached in the flag's second half, once per step (the
options' progress field), and the bar reads it ten times a second. Nothing is shown otherwise,
and a short solve never starts a bar.
A forked child (multiprocessing's default on Linux) has no copy of the thread: it starts its
own. A second Ctrl-C while the kernel winds down gives up the wait: the worker finishes the
solve unseen (its arrays stay referenced) and the next long solve gets a fresh worker.
"""
from __future__ import annotations

import os
import queue
import sys
import threading
import time

import numpy as np

#: steps x state size above which a solve from the main thread runs in a worker thread
LONG_WORK = 200_000
#: seconds a solve runs before its progress bar appears
PROGRESS_AFTER = 1.0


def new_flag() -> np.ndarray:
    """The interrupt flag (element 0) and, in elements 2-3 (8-byte aligned: numpy aligns its
    arrays to 16 bytes), the double the kernel stores the time reached in."""
    return np.zeros(4, dtype=np.int32)


def progress_of(flag: np.ndarray) -> float:
    """The time a solve has reached, as the kernel stored it in flag."""
    return float(flag[2:4].view(np.float64)[0])


def _show_progress() -> bool:
    setting = os.environ.get("MBDK_PROGRESS")
    if setting is not None:
        return setting not in ("", "0")
    return sys.stderr.isatty()


def progress_bar(total: int, desc: str, unit: str):
    """A bar for work longer than PROGRESS_AFTER seconds made of many pieces (the studies of
    the report, the runs of a sweep), shown where a solve's bar would be; None when it would
    not be (see _show_progress), or without tqdm. print_line writes beside it."""
    if not _show_progress():
        return None
    try:
        from tqdm import tqdm
    except ImportError:     # pragma: no cover - tqdm is in the requirements
        return None
    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, delay=PROGRESS_AFTER,
                leave=False)


def print_line(text: str, file=None) -> None:
    """print, above any bar on the terminal rather than through it."""
    file = file or sys.stdout
    try:
        from tqdm import tqdm
    except ImportError:     # pragma: no cover
        print(text, file=file, flush=True)
        return
    tqdm.write(text, file=file)
    file.flush()


class _Bar:
    """A tqdm bar over [t0, t_end], started PROGRESS_AFTER seconds into a solve."""

    def __init__(self, span):
        self.span, self.bar, self.start = span, None, time.monotonic()

    def update(self, flag):
        if self.span is None:
            return
        t0, t_end = self.span
        if self.bar is None:
            if time.monotonic() - self.start < PROGRESS_AFTER or not _show_progress():
                return
            try:
                from tqdm import tqdm
            except ImportError:     # pragma: no cover - tqdm is in the requirements
                self.span = None
                return
            self.bar = tqdm(total=t_end - t0, unit="s", unit_scale=False, leave=False,
                            desc="mbdk", file=sys.stderr,
                            bar_format="{desc}: {percentage:3.0f}%|{bar}| t = {n:.4g} of "
                                       "{total:.4g} s [{elapsed}<{remaining}]")
        now = min(max(progress_of(flag) - t0, 0.0), t_end - t0)
        self.bar.update(now - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()


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


def call(fn, args: tuple, flag: np.ndarray, work: float, span=None):
    """fn(*args) (a threadsafe kernel entry that polls flag). Returns (fn's results, whether a
    KeyboardInterrupt was turned into the flag). span = (t0, t_end): the interval of the
    solve, for its progress bar."""
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
    bar = _Bar(span)
    try:
        while True:
            try:
                if done.wait(0.1):
                    break
                bar.update(flag)
            except KeyboardInterrupt:
                if interrupted:     # the second Ctrl-C: stop waiting
                    _worker = None
                    raise
                flag[0] = 1
                interrupted = True
    finally:
        bar.close()
    if "exc" in box:
        raise box["exc"]
    return box["out"], interrupted
