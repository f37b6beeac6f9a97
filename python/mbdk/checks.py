"""Checks shared by the scene readers and the run entries: numbers in the range mbdk computes
with, name-like arguments, error-control tolerances, the step count an h_max implies, and the
memory a run's samples need. Each raises a named error (mbdk.errors) that names the argument or
field, its value, and what to change.
"""
from __future__ import annotations

import math
import os
from numbers import Integral, Real

import numpy as np

from .errors import InvalidInputError, NoMemoryError, NotApplicableError

#: the magnitudes a number of a scene may have, 0 aside. mbdk forms squares and products of two
#: of them (r^2 in a distance row, m r^2 in an inertia, omega^2 r, k x) and reciprocals (1/m,
#: the inverse inertia); with both factors within 1e-150..1e150 these stay normal doubles
#: (1e-300..1e300, inside 2.2e-308..1.8e308). Physical values in SI units lie far inside it.
NUMBER_MIN, NUMBER_MAX = 1e-150, 1e150
#: a positive length (a distance joint's, a radius, a body's size) must be at least this much of
#: the scene's length scale (its largest coordinate or offset): positions carry a roundoff of
#: about 1e-16 of that scale, and the constraint tests of assembly, Newton and the watch work
#: to about 1e-10 of it, so a shorter length is lost in the roundoff of the positions
LENGTH_RESOLUTION = 1e-9
#: the most a scene file may hold: a scene of 10^5 bodies takes a few MiB
MAX_SCENE_BYTES = 64 * 2**20


def show(v) -> str:
    """A value for a message: a huge integer by its first digits and its length (its full text
    may be thousands of digits, and Python refuses to print more than 4300)."""
    if isinstance(v, Integral) and not isinstance(v, bool) and abs(int(v)) >= 10**20:
        n = abs(int(v))
        d = int(n.bit_length() * math.log10(2))      # the digits, or one fewer
        digits = d + 1 if n >= 10**d else d
        return f"{'-' if v < 0 else ''}an integer of {digits} digits"
    if isinstance(v, (list, tuple)) and len(v) <= 20 and any(
            isinstance(x, Integral) and not isinstance(x, bool) and abs(int(x)) >= 10**20
            for x in v):
        inner = ", ".join(show(x) for x in v)
        return f"[{inner}]" if isinstance(v, list) else f"({inner})"
    try:
        text = repr(v)
    except ValueError:     # a container holding an integer beyond Python's text limit
        return f"a {type(v).__name__} holding an integer too long to print"
    return text if len(text) <= 200 else text[:200] + "..."


def number_problem(v, *, in_range: bool = True) -> str | None:
    """Why v is not a finite real number (in the range of NUMBER_MIN..NUMBER_MAX, or 0, when
    in_range), as the end of a message (`= value ...`), or None."""
    if isinstance(v, bool) or not isinstance(v, Real):
        return f"= {show(v)} is not a number"
    try:
        f = float(v)
    except (OverflowError, ValueError, TypeError):
        return (f"= {show(v)} is out of range: larger than any floating-point number; "
                "give a value in SI units (magnitude below 1e150)")
    if not math.isfinite(f):
        return f"= {f} is not finite"
    if in_range and f != 0 and not NUMBER_MIN <= abs(f) <= NUMBER_MAX:
        return (f"= {show(v)} is out of range: a nonzero magnitude must lie between "
                "1e-150 and 1e150 (squares, products and reciprocals of such "
                "values stay finite and normal); give it in SI units, or 0")
    return None


def real(name: str, value, *, positive: bool = False, nonneg: bool = False) -> float:
    """A real-number argument as float: not a bool, a string or None, finite (a huge integer is
    out of range, not an OverflowError)."""
    if type(value) is float and math.isfinite(value) and \
            (not positive or value > 0) and (not nonneg or value >= 0):
        return value
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, bool) or not isinstance(value, Real):
        raise InvalidInputError(f"{name} = {show(value)} is not a real number; give a finite "
                                "number")
    try:
        v = float(value)
    except (OverflowError, ValueError):
        raise InvalidInputError(f"{name} = {show(value)} is out of range (larger than any "
                                "floating-point number); give a finite number") from None
    if not math.isfinite(v):
        raise InvalidInputError(f"{name} = {v} is not finite; give a finite number")
    if positive and not v > 0:
        raise InvalidInputError(f"{name} = {v} must be positive")
    if nonneg and v < 0:
        raise InvalidInputError(f"{name} = {v} is negative; give a value >= 0")
    return v


def choice(name: str, value, known, *, error=InvalidInputError, what: str = "") -> str:
    """A name-like argument (a method, formulation, solver, ...): a string among known; a list,
    a dict or any other value is refused by name, not with Python's 'unhashable type'."""
    if isinstance(value, str):
        try:
            if value in known:
                return value
        except TypeError:
            pass
    names = ", ".join(map(str, known))
    kind = "" if isinstance(value, str) else f" (a {type(value).__name__}, not a name)"
    raise error(f"{name} = {show(value)}{kind} is not {what or 'known'}; known: {names}")


def tolerances(rtol, atol, *, where: str, rtol_floor: float) -> tuple[float, float]:
    """(rtol, atol) of an error-controlled scene run, planar or spatial: each one number,
    finite, rtol in [floor, 1) or 0, atol > 0; a per-state atol is solve_ode's."""
    if atol is not None and not isinstance(atol, (str, bytes)) and np.ndim(atol) != 0:
        raise NotApplicableError(f"atol = {show(atol)}: {where} takes one absolute tolerance (a "
                                 "number); per-state tolerances are solve_ode's")
    r = real("rtol", 1e-6 if rtol is None else rtol, nonneg=True)
    if r >= 1:
        raise InvalidInputError(f"rtol = {r} must be below 1 (1e-6 keeps about 6 digits)")
    if 0 < r < rtol_floor:
        raise InvalidInputError(f"rtol = {r:g} asks for more digits than double precision "
                                f"holds; give rtol >= {rtol_floor:.1e} (or 0 with atol > 0)")
    a = real("atol", 1e-8 if atol is None else atol)
    if not a > 0:
        raise InvalidInputError(f"atol = {a} must be > 0 (a state passing through 0 would get "
                                "an infinite weight; 1e-8 is the default)")
    return r, a


def step_bounds(t0: float, t_end: float, h_max: float, max_steps: int, *, default_steps: int,
                has_max_steps: bool = True) -> None:
    """Refuses, before the run, an h_max under which the interval needs more steps than the run
    may take (it would count steps up to max_steps, for minutes, and stop short of t_end)."""
    if not h_max:
        return
    limit = max_steps or default_steps
    need = (t_end - t0) / h_max
    if need > limit:
        what = (f"max_steps = {limit:.3g}{'' if max_steps else ' (the default)'}"
                if has_max_steps else f"{limit:.3g}, the most steps an error-controlled run "
                "takes")
        raise InvalidInputError(
            f"h_max = {h_max:g} over t_end - t0 = {t_end - t0:g} needs at least {need:.3g} "
            f"steps, more than {what}: give h_max >= {(t_end - t0) / limit:.3g} (or 0: no "
            f"bound), a shorter interval{', or a larger max_steps' if has_max_steps else ''}")


#: the share of the available memory a run's samples may take: the rest is for the process
#: itself, the kernel's work arrays, the result's derived arrays and the rest of the system
#: (a run that takes it all is ended by the system's out-of-memory killer, not by an error)
MEMORY_SHARE = 0.75


def available_memory() -> int | None:
    """Bytes of memory the system can give without swapping: /proc/meminfo's MemAvailable
    (else the physical memory), less where a control group's limit leaves less; None where
    none of these can be read."""
    avail = None
    try:
        with open("/proc/meminfo", "rb") as f:
            for line in f:
                if line.startswith(b"MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    if avail is None:
        try:
            avail = int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
        except (OSError, ValueError, AttributeError):
            pass
    for limit_file, usage_file in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                                   ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                                    "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        try:
            with open(limit_file) as f:
                limit = f.read().strip()
            with open(usage_file) as f:
                usage = int(f.read().strip())
        except (OSError, ValueError):
            continue
        if limit.isdigit() and int(limit) < 2**60:
            left = max(int(limit) - usage, 0)
            avail = left if avail is None else min(avail, left)
    return avail


def _gib(nbytes: float) -> str:
    return f"{nbytes / 2**30:.3g} GiB" if nbytes >= 2**30 else f"{nbytes / 2**20:.3g} MiB"


def check_memory(nbytes: float, *, what: str, change: str) -> None:
    """Refuses a run whose sample arrays need more bytes than the machine has available, naming
    the size and the arguments that set it."""
    avail = available_memory()
    if avail is not None and nbytes > MEMORY_SHARE * avail:
        raise NoMemoryError(f"{what} needs {_gib(nbytes)} for its samples, more than "
                            f"{MEMORY_SHARE:.0%} of the {_gib(avail)} of memory available "
                            f"(the rest is the process's and the system's): {change}")


def memory_error(exc: MemoryError, nbytes: float, *, what: str, change: str) -> NoMemoryError:
    """The named error for a MemoryError raised while a run's samples were allocated."""
    why = str(exc) or "out of memory"
    return NoMemoryError(f"{what}: allocating its samples ({_gib(nbytes)}) failed ({why}): "
                         f"{change}")



def length_scale(sizes, source: str, error) -> float:
    """Checks a scene's geometric sizes against its length scale, the largest of them.

    sizes: (label, field, magnitude, kind[, note]) with kind "coordinate" (a position in space:
    sets the scale only), "offset" (a point on a body: 0 is meaningful, otherwise it must be
    resolvable) or "length" (a distance, a radius: must be resolvable; note: what the message
    says to do). A nonzero offset or a length below LENGTH_RESOLUTION of the scale is refused,
    naming it and the value that sets the scale (one of the two is usually in the wrong units).
    Returns the scale."""
    sizes = [s if len(s) == 5 else (*s, "") for s in sizes if math.isfinite(s[2])]
    if not sizes:
        return 0.0
    top = max(sizes, key=lambda s: abs(s[2]))
    scale = abs(top[2])
    for label, fld, size, kind, note in sizes:
        if kind == "coordinate" or (kind == "offset" and size == 0):
            continue
        if abs(size) < LENGTH_RESOLUTION * scale or (kind == "length" and size == 0):
            what = note or ("next to that scale it is lost in the roundoff of the positions; "
                            "one of the two is likely wrong (in other units, or mistyped): "
                            "give lengths in metres throughout"
                            + ("; a point meant to be the body's origin is written 0"
                               if kind == "offset" else ""))
            raise error(f"{source}: {label}: field {fld!r} has size {abs(size):.3g}, below "
                        f"{LENGTH_RESOLUTION:g} of the scene's length scale {scale:.3g} (set by "
                        f"{top[0]}, field {top[1]!r}): {what}")
    return scale
