"""The command line's options of `mbdk run` and `mbdk solve`, made from the keyword arguments of
mbdk.simulate and mbdk.solve_ode themselves (their names, types and defaults, by
inspect.signature) and a help line per option here: an option the Python API gains appears on
the command line, and tests/test_cli_options.py fails while it has no help line, so the two
cannot drift apart.

Names: a keyword's underscores become dashes (t_end: --t-end). Types: numbers as numbers; a
flag (bool) as --name / --no-name; outputs as a list of names; penalty as three numbers;
adaptive as true, false, extrapolated or estimated; watch as on, off or name=value pairs
(position=1e-3,energy=0.05: mbdk.Watch's fields); params and y0 of solve as name=value pairs
and a list of numbers. Only the options given reach the function: every default stays the
API's own.
"""
from __future__ import annotations

import argparse
import inspect

from .errors import InvalidInputError

#: simulate's keywords the command line does not take: the scene and method are positional,
#: a command line run always raises on failure (and says so on one line), events are Python
#: functions
RUN_SKIP = {"scene", "method", "raise_on_failure", "unknown", "events"}
#: solve_ode's: the problem and method are positional; jac is a Python callable
SOLVE_SKIP = {"problem", "method", "raise_on_failure", "jac"}

RUN_HELP = {
    "h": "the step (fixed-step methods; the first step of error-controlled ones)",
    "t_end": "the end time (s)",
    "formulation": "reduced, baumgarte, penalty, projection (ODE methods); index3, "
                   "augmented_lagrangian (index-3 family); index1, ggl (ida); i3, si2 (bdf)",
    "t0": "the start time (s)",
    "every": "keep every k-th step as a sample (fixed step)",
    "outputs": "the outputs to compute: a, multipliers, reactions, energy, residuals",
    "alpha": "Baumgarte's alpha, or the augmented Lagrangian's penalty factor",
    "beta": "Baumgarte's beta",
    "penalty": "the penalty formulation's alpha_p omega_p mu_p",
    "projection_tol": "max |Phi| the projections reach",
    "solver": "the constrained solve: auto, schur, kkt, revolute_schur, sparse",
    "small_dense": "factorise tiny systems by block LDL^T (--no-small-dense: the general "
                   "dense LU and Cholesky)",
    "assemble_initial": "assemble the initial state onto the joints first",
    "startup": "the multistep methods' start-up: rk4 or bdf",
    "newton_rtol": "Newton's relative tolerance (implicit and index-3 methods)",
    "newton_atol": "Newton's absolute tolerance",
    "max_iter": "Newton's iteration limit (index-3 methods)",
    "adaptive": "the index-3 family's step-size control: true (extrapolated), estimated, false",
    "err_rtol": "step-size control's relative tolerance (index-3 family)",
    "err_atol": "step-size control's absolute tolerance (index-3 family)",
    "dt_out": "the samples' spacing (error-controlled methods)",
    "h_min": "the smallest step (error-controlled methods)",
    "h_max": "the largest step (error-controlled methods)",
    "rtol": "relative tolerance (error-controlled ODE methods, ida)",
    "atol": "absolute tolerance (error-controlled ODE methods, ida)",
    "max_steps": "the most steps an error-controlled method takes",
    "max_order": "the highest order of bdf, cvode_* and ida",
    "watch": "what the run must keep: on, off, or name=value tolerances "
             "(position, velocity, energy, momentum, quaternion, every)",
    "locate_events": "dopri54, bs32: end a step where a contact closes or opens",
    "switch_angles": "spatial scenes with angles: switch the angle set this near its lock",
    "coordinates": "spatial scenes: absolute (each body's pose) or joint (a spanning tree's "
                   "turns, slides and spherical turns, the other joints kept as rows)",
    "rho_inf": "generalized_alpha's spectral radius at infinity, in [0, 1]",
    "alpha_hht": "hht's alpha, in [-1/3, 0]",
    "newmark_beta": "the index-3 family's beta",
    "newmark_gamma": "the index-3 family's gamma",
    "alpha_m": "generalized_alpha's alpha_m (with alpha_f, beta, gamma)",
    "alpha_f": "generalized_alpha's alpha_f",
    "t_eval": "the sample times themselves (error-controlled ODE methods)",
}

SOLVE_HELP = {
    "h": "the step (fixed-step methods; the first step of error-controlled ones)",
    "t_end": "the end time",
    "t0": "the start time",
    "y0": "the initial state (numbers; default: the problem's)",
    "params": "the problem's parameters, name=value pairs",
    "every": "keep every k-th step as a sample (fixed step)",
    "nq": "second-order problems: the coordinates' count (Euler-Cromer)",
    "fd_jacobian": "implicit methods: the Jacobian by differences",
    "startup": "the multistep methods' start-up: rk4 or bdf",
    "rtol": "relative tolerance (error-controlled methods)",
    "atol": "absolute tolerance (error-controlled methods)",
    "dt_out": "the samples' spacing (error-controlled methods)",
    "h_min": "the smallest step (error-controlled methods)",
    "h_max": "the largest step (error-controlled methods)",
    "max_steps": "the most steps an error-controlled method takes",
    "max_order": "the highest order of bdf and cvode_*",
    "t_eval": "the sample times themselves (error-controlled methods)",
}


def _pairs(text: str) -> dict:
    """name=value[,name=value...] with numbers where they read as numbers."""
    out = {}
    for item in filter(None, (p.strip() for p in text.split(","))):
        name, eq, value = item.partition("=")
        if not eq or not name:
            raise argparse.ArgumentTypeError(f"{item!r} is not name=value")
        for kind in (int, float, str):
            try:
                out[name.strip()] = kind(value.strip())
                break
            except ValueError:
                continue
    return out


def _watch(text: str):
    if text in ("on", "true"):
        return True
    if text in ("off", "false"):
        return False
    return _pairs(text)


def _adaptive(text: str):
    return {"true": True, "false": False}.get(text.lower(), text)


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None


#: options whose values are not one number, word or flag
SPECIAL = {"outputs": dict(nargs="*", metavar="NAME"),
           "penalty": dict(nargs=3, type=_number, metavar=("ALPHA_P", "OMEGA_P", "MU_P")),
           "watch": dict(type=_watch, metavar="on|off|NAME=VALUE,..."),
           "adaptive": dict(type=_adaptive, metavar="true|false|extrapolated|estimated"),
           "params": dict(type=_pairs, metavar="NAME=VALUE,..."),
           "y0": dict(nargs="+", type=_number, metavar="Y"),
           "t_eval": dict(nargs="+", type=_number, metavar="T")}


def keywords(fn, skip) -> list[inspect.Parameter]:
    """fn's keyword arguments the command line takes."""
    return [p for p in inspect.signature(fn).parameters.values()
            if p.name not in skip and p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)]


def add_options(parser, fn, helps: dict, skip: set) -> None:
    """An option for every keyword of fn (module docstring); a keyword without a help line is
    an error here, not a silent gap."""
    for p in keywords(fn, skip):
        if p.name not in helps:
            raise InvalidInputError(f"{fn.__name__}'s keyword {p.name!r} has no command-line "
                                    "help line (mbdk.cli_options)")
        flag = "--" + p.name.replace("_", "-")
        required = p.default is inspect.Parameter.empty
        kw = dict(dest=p.name, help=helps[p.name])
        if not required:
            kw["default"] = argparse.SUPPRESS
        annotation = str(p.annotation)
        if p.name in SPECIAL:
            kw.update(SPECIAL[p.name])
        elif annotation == "bool":
            kw["action"] = argparse.BooleanOptionalAction
        elif annotation.startswith("float") or annotation == "tuple":
            kw["type"] = _number
        elif annotation.startswith("int"):
            kw["type"] = _integer
        elif p.annotation is inspect.Parameter.empty and (
                p.default is None or isinstance(p.default, (int, float))):
            kw["type"] = _number      # an untyped number (solve_ode's atol)
        parser.add_argument(flag, required=required, **kw)


def given(args, fn, skip: set) -> dict:
    """The keyword arguments the command line gave (the others keep fn's defaults)."""
    return {p.name: getattr(args, p.name) for p in keywords(fn, skip) if hasattr(args, p.name)}
