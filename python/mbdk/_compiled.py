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

Solves in threads of one's own: Python runs signal handlers in the main thread only, which may
be anywhere (blocked in Thread.join, say) while other threads' solves run; the default handler
would raise KeyboardInterrupt there and leave those solves running to their end. So every flag
new_flag makes is kept in a registry of live flags (weak references: a flag leaves it when its
solve's arrays are freed), and at import, from the main thread, if SIGINT's handler is still
Python's default_int_handler, this module installs sigint_handler in its place: it sets every
live flag, then raises KeyboardInterrupt as the default does. Ctrl-C then ends every running
solve within a step, each with SolveInterrupted in its own thread, and the main thread gets its
KeyboardInterrupt as before (held back while a progress bar draws, until it is drawn: see
_Drawing). Setting the flag of a solve that has ended does nothing; a solve whose flag is made
after the Ctrl-C runs normally. A handler that was not the default (one's own, or SIG_IGN) is
left alone, and so is a process that imports mbdk first from another thread: such code can
call interrupt_all() itself (or install_sigint_handler() later, from the main thread).
asyncio.run installs its own Ctrl-C handling only over the default handler, so under it Ctrl-C
raises KeyboardInterrupt in the running code, as before Python 3.11.
"""
from __future__ import annotations

import os
import queue
import signal
import sys
import threading
import time
import weakref

import numpy as np

#: steps x state size above which a solve from the main thread runs in a worker thread
LONG_WORK = 200_000
#: seconds a solve runs before its progress bar appears
PROGRESS_AFTER = 1.0


#: weak references to the flags of solves that may still run (module docstring), by their own
#: id: a reference lives in the dict until its flag is freed, then its callback removes it
_live: dict = {}


def _forget(ref, pop=_live.pop):
    pop(id(ref), None)


def new_flag() -> np.ndarray:
    """The interrupt flag (element 0) and, in elements 2-3 (8-byte aligned: numpy aligns its
    arrays to 16 bytes), the double the kernel stores the time reached in; kept in the registry
    of live flags until it is freed."""
    flag = np.zeros(4, dtype=np.int32)
    ref = weakref.ref(flag, _forget)
    _live[id(ref)] = ref
    return flag


def live_flags() -> list:
    """The flags of the registry that still exist (their solves may run)."""
    while True:
        try:
            refs = list(_live.values())
        except RuntimeError:    # a flag freed (its reference removed) while the list was taken
            continue
        return [f for f in (r() for r in refs) if f is not None]


def interrupt_all() -> int:
    """Sets every live flag: each running solve ends within a step with ERR_INTERRUPTED
    (SolveInterrupted in its thread). Returns how many flags were set."""
    flags = live_flags()
    for f in flags:
        f[0] = 1
    return len(flags)


def sigint_handler(signum, frame):
    """SIGINT: stop the solves of every thread, then raise KeyboardInterrupt in the main thread
    as Python's default handler does (once a bar has finished drawing, see _drawing)."""
    interrupt_all()
    if _drawing.depth:
        _drawing.pending = True
        return
    signal.default_int_handler(signum, frame)


class _Drawing:
    """with _drawing: a bar's drawing, during which sigint_handler holds its KeyboardInterrupt
    back and raises it at the end. Raised inside tqdm, it would leave a bar half drawn that
    tqdm then believes it never showed, and does not clear (handlers run in the main thread
    only, where bars are drawn: no lock needed)."""

    depth, pending = 0, False

    def __enter__(self):
        self.depth += 1

    def __exit__(self, *exc):
        self.depth -= 1
        if not self.depth and self.pending:
            self.pending = False
            raise KeyboardInterrupt
        return False


_drawing = _Drawing()


def install_sigint_handler() -> bool:
    """Installs sigint_handler if SIGINT's handler is Python's default and this is the main
    thread (signal.signal works there only). Returns whether sigint_handler is the handler."""
    if threading.current_thread() is not threading.main_thread():
        return False
    current = signal.getsignal(signal.SIGINT)
    if current is sigint_handler:
        return True
    if current is not signal.default_int_handler:
        return False
    signal.signal(signal.SIGINT, sigint_handler)
    return True


install_sigint_handler()


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
        # tqdm is slow to import, and only a bar that is drawn needs it
        from tqdm import tqdm
    except ImportError:     # pragma: no cover - tqdm is in the requirements
        return None
    with _drawing:
        return _CountBar(tqdm(total=total, desc=desc, unit=unit, file=sys.stderr,
                              delay=PROGRESS_AFTER, leave=False))


class _CountBar:
    """progress_bar's tqdm bar, drawn under _drawing."""

    def __init__(self, bar):
        self._bar = bar

    def update(self, n=1):
        with _drawing:
            self._bar.update(n)

    def set_postfix_str(self, text):
        with _drawing:
            self._bar.set_postfix_str(text)

    def close(self):
        with _drawing:
            self._bar.close()


def print_line(text: str, file=None) -> None:
    """print, above any bar on the terminal rather than through it."""
    file = file or sys.stdout
    try:
        # tqdm is slow to import, and only a bar that is drawn needs it
        from tqdm import tqdm
    except ImportError:     # pragma: no cover
        print(text, file=file, flush=True)
        return
    with _drawing:
        tqdm.write(text, file=file)
        file.flush()


class _Bar:
    """A tqdm bar over [t0, t_end], shown PROGRESS_AFTER seconds into a solve, drawn under
    _drawing."""

    def __init__(self, span):
        self.span, self.bar = span, None
        if span is None or not _show_progress():
            return
        try:
            # tqdm is slow to import, and only a bar that is drawn needs it
            from tqdm import tqdm
        except ImportError:     # pragma: no cover - tqdm is in the requirements
            return
        t0, t_end = span
        with _drawing:
            self.bar = tqdm(total=t_end - t0, unit="s", unit_scale=False, leave=False,
                            desc="mbdk", file=sys.stderr, delay=PROGRESS_AFTER,
                            bar_format="{desc}: {percentage:3.0f}%|{bar}| t = {n:.4g} of "
                                       "{total:.4g} s [{elapsed}<{remaining}]")

    def update(self, flag):
        if self.bar is None:
            return
        t0, t_end = self.span
        now = min(max(progress_of(flag) - t0, 0.0), t_end - t0)
        with _drawing:
            self.bar.update(now - self.bar.n)

    def close(self):
        if self.bar is None:
            return
        with _drawing:
            shown = self.bar.last_print_t >= self.bar.start_t + self.bar.delay
            self.bar.close()
            if shown:
                # a bar below another one (a solve inside a sweep's bar) is cleared and the
                # cursor moved back up, but left where the bar ended, not at the line's start
                sys.stderr.write("\r")
                sys.stderr.flush()


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
