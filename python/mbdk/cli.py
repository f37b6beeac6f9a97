"""The `mbdk` command: `mbdk --version`, `mbdk report`, `mbdk methods`, `mbdk problems`,
`mbdk solve`, `mbdk scenes`, `mbdk check|scene NAME|FILE [--symbolic]`,
`mbdk run SCENE ... --out FILE`, `mbdk plot FILE`, `mbdk animate SCENE ... --out PAGE.html`,
`mbdk sweep GRID --out TABLE.csv`::

    mbdk run my_scene.toml --method rk4 --h 1e-3 --t-end 10 --out run.npz
    mbdk plot run.npz                     # run.png: coordinates, energy balance, residuals
    mbdk animate four_bar --method dopri54 --t-end 5 --out four_bar.html   # the motion

Every failure ends the command with one line on standard error that names the command, the
kind of failure and what it concerns, and a non-zero status; no traceback (--traceback shows
it):

status 2
    bad arguments (argparse's usage error, on one line), mbdk's named errors
    (`mbdk run: SceneError: my.toml: ...`), a file that cannot be read or written, a full
    disk (`mbdk run: OSError: run.npz: No space left on device; no file written`), and any
    other exception, by its class name and message;
status 130 (128 + SIGINT, the shell's convention)
    Ctrl-C, `mbdk run: interrupted after t = 1.23 s (Ctrl-C); no file written` (the run's
    last sample);
status 141 (128 + SIGPIPE)
    standard output closed early (`mbdk methods | head -3`), quietly.

The commands that write a file (run, sweep, plot, animate, tables, fmu) write it under a temporary name and
rename it when complete, so a failure leaves no file, not even a partial one, and the line says "no
file written". Ctrl-C during a solve stops the solves of every thread (mbdk._compiled).
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

from . import ode
from .cli_options import (RUN_HELP, RUN_SKIP, SOLVE_HELP, SOLVE_SKIP, add_options, given)
from .errors import InvalidInputError, MbdkError as MbdkErrorBase
from .methods import methods
from .problems import problems
from .report import STUDIES, build_report
from .animation import MAX_FRAMES, write_animation
from .results_io import check_writable, plot_result, save_result
from .model import assemble, build_tables
from .scene_file import scene_or_file, scenes
from .scene_report import scene_report
from .simulate import simulate
from .sweep import load_grid, one_line, sweep
from .symbolic import cross_check
from .tables_file import write_tables
from .fmu import export_fmu

#: the commands that write their output file only when they succeed
WRITERS = ("run", "sweep", "plot", "animate", "tables", "fmu")
#: simulate's keywords an FMU does not take: its master chooses the communication points
FMU_SKIP = RUN_SKIP | {"t_end", "every", "outputs", "dt_out", "t_eval", "locate_events",
                       "switch_angles", "max_steps", "coordinates"}
#: the API whose keywords are `mbdk solve`'s options (taken at import: the call itself goes
#: through ode.solve_ode, which a test may stand in for)
_SOLVE_API = ode.solve_ode


class _Parser(argparse.ArgumentParser):
    """argparse whose usage errors are one line (the usage is behind --help)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: {message} (see {self.prog} --help)\n")


class _Version(argparse.Action):
    """--version: mbdk's version from the package metadata, read only when asked for (reading
    it costs the import of importlib.metadata, which no other command needs)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"mbdk {ode.package_version()}")
        parser.exit(0)


def _describe(exc: BaseException) -> str:
    """An exception as 'ClassName: message' on one line; an OSError names its file."""
    if isinstance(exc, OSError) and exc.strerror:
        where = f"{exc.filename}: " if exc.filename else ""
        return f"{type(exc).__name__}: {where}{exc.strerror}"
    return f"{type(exc).__name__}: {one_line(exc) or '(no message)'}"


def parser() -> argparse.ArgumentParser:
    """The command line's parser: every command and option (the documentation prints its
    help)."""
    ap = _Parser(prog="mbdk", description="mbdk: compiled multibody-dynamics kernel and its "
                 "integrator studies")
    ap.add_argument("--version", action=_Version, help="print mbdk's version and exit")
    sub = ap.add_subparsers(dest="cmd", required=True)
    rp = sub.add_parser("report", help="run every study and write the HTML report: a front "
                        "page of findings and one page per study")
    rp.add_argument("--out", type=Path, default=Path("report"))
    rp.add_argument("--quick", action="store_true", help="coarser, faster runs")
    rp.add_argument("--studies", type=Path, default=None, help="the studies/ folder")
    rp.add_argument("--only", nargs="*", default=None, help="run only these studies")
    sub.add_parser("methods", help="list the methods")
    sub.add_parser("problems", help="list the compiled problems")
    sp = sub.add_parser("solve", help="solve a compiled problem and print the last sample")
    sp.add_argument("problem", help="a compiled problem of mbdk problems")
    sp.add_argument("method", help="a method of mbdk methods")
    add_options(sp, _SOLVE_API, SOLVE_HELP, SOLVE_SKIP)
    sub.add_parser("scenes", help="list the built-in scenes")
    sc = sub.add_parser("check", aliases=["scene"],
                        help="check a scene and print its report: coordinates, constraint rows, "
                        "degrees of freedom, redundant joints, each joint's class, the index, "
                        "and what the assembly of its initial state moves")
    sc.add_argument("scene", help="a built-in scene's name or a scene file (TOML)")
    sc.add_argument("--symbolic", action="store_true",
                    help="also derive its equations with SymPy and compare with the kernel")
    run = sub.add_parser("run", help="run a scene and save its samples with the manifest")
    run.add_argument("scene", help="a built-in scene's name or a scene file (TOML)")
    run.add_argument("--method", required=True, help="a method of mbdk methods")
    run.add_argument("--out", type=Path, required=True,
                     help="the result file: .npz, .csv or .h5 (h5py)")
    add_options(run, simulate, RUN_HELP, RUN_SKIP)
    run.add_argument("--no-watch", dest="watch", action="store_const", const=False,
                     default=argparse.SUPPRESS, help="turn the watch's checks off (--watch off)")
    sw = sub.add_parser("sweep", help="run a grid of runs on Dask and write its table (CSV)")
    sw.add_argument("grid", type=Path,
                    help="a TOML file with a [sweep] table or [[sweep]] tables (mbdk.sweep)")
    sw.add_argument("--workers", type=int, default=None,
                    help="local worker processes (default 2; 0: serially in this process); "
                    "not with --scheduler, whose cluster has its own")
    sw.add_argument("--scheduler", default=None,
                    help="the address of an existing Dask scheduler, tcp://host:port")
    sw.add_argument("--out", type=Path, required=True, help="the table (CSV)")
    pl = sub.add_parser("plot", help="plot a saved result (PNG)")
    pl.add_argument("result", type=Path)
    pl.add_argument("--out", type=Path, default=None, help="the PNG (default: beside the result)")
    an = sub.add_parser("animate", help="run a scene and write an animation of its motion "
                        "from the run's samples: an HTML page that plays in a browser, offline "
                        "(planar in the plane, spatial in a view turned by dragging)")
    an.add_argument("scene", help="a built-in scene's name or a scene file (TOML)")
    an.add_argument("--method", required=True, help="a method of mbdk methods")
    an.add_argument("--out", type=Path, required=True, help="the page (.html)")
    an.add_argument("--frames", type=int, default=MAX_FRAMES,
                    help=f"at most this many of the run's samples are shown (default "
                    f"{MAX_FRAMES}; the first and last always)")
    add_options(an, simulate, RUN_HELP, RUN_SKIP)
    an.add_argument("--no-watch", dest="watch", action="store_const", const=False,
                    default=argparse.SUPPRESS, help="turn the watch's checks off (--watch off)")
    tb = sub.add_parser("tables", help="write a scene's kernel tables and initial state "
                        "(assembled) as a file a C program reads with mbdk_scene_tables_read "
                        "(mbdk.h) to step the scene without Python")
    tb.add_argument("scene", help="a built-in scene's name or a scene file (TOML)")
    tb.add_argument("--out", type=Path, required=True, help="the tables file (.toml)")
    tb.add_argument("--t0", type=float, default=0.0, help="the initial time (default 0)")
    fm = sub.add_parser("fmu", help="write a scene as an FMI 3.0 co-simulation FMU (the "
                        "kernel's C stepper inside, no Python) for FMPy, Modelica tools, "
                        "Simulink and other co-simulation masters (mbdk.export_fmu)")
    fm.add_argument("scene", help="a built-in scene's name or a scene file (TOML)")
    fm.add_argument("--out", type=Path, required=True, help="the FMU (.fmu)")
    fm.add_argument("--method", required=True,
                    help="a fixed-step ODE method (rk4, heun, ...) or the index-3 family "
                         "(trapezoidal_index3, newmark, hht, generalized_alpha)")
    fm.add_argument("--input", dest="inputs", action="append", default=[], metavar="NAME",
                    help="a point force or torque that becomes an input (its name, or "
                         "NAME.FIELD such as motor.torque); repeat for several")
    fm.add_argument("--stop-time", type=float, default=1.0,
                    help="the default experiment's duration (s, default 1)")
    fm.add_argument("--step-size", type=float, default=argparse.SUPPRESS,
                    help="the default experiment's communication step (a multiple of h; "
                         "default 0.01 s)")
    fm.add_argument("--no-bundle", dest="bundle", action="store_false",
                    help="do not copy the binary's shared libraries (gfortran, LAPACK, "
                         "SUNDIALS, SuiteSparse) into the FMU")
    add_options(fm, simulate, RUN_HELP, FMU_SKIP)
    for p in (rp, sp, sc, run, pl, sw, an, tb, fm):
        p.add_argument("--traceback", action="store_true", help="show the traceback of errors")
    ap.commands = sub.choices      # name -> the command's parser, aliases included
    return ap


def main(argv=None) -> int:
    """Runs the command line with these arguments (default sys.argv[1:]); returns the exit
    status (module docstring)."""
    ap = parser()
    args, extra = ap.parse_known_args(argv)
    if extra:       # named by the command they were given to
        ap.commands[args.cmd].error(f"unrecognized arguments: {' '.join(extra)}")

    try:
        status = _main(args)
        sys.stdout.flush()      # here, not at exit: a closed pipe is then caught below
        return status
    except BrokenPipeError:
        # the reader of standard output has gone (`mbdk methods | head`): end quietly, and keep
        # Python's final flush from failing again
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except BaseException as exc:
        if isinstance(exc, SystemExit) or getattr(args, "traceback", False):
            raise
        if not isinstance(exc, (Exception, KeyboardInterrupt)):
            raise
        _fail(args, exc)
        return 130 if isinstance(exc, KeyboardInterrupt) else 2


def _fail(args, exc: BaseException) -> None:
    """The one line on standard error for a failed command."""
    cmd = f"mbdk {args.cmd}"
    if isinstance(exc, KeyboardInterrupt):
        result = getattr(exc, "result", None)
        t = getattr(result, "t", None)
        # a sweep's runs each have their own t; a run's partial result ends at its last
        # sample, which the solve had passed
        text = (f"interrupted after t = {float(t[-1]):.6g} s (Ctrl-C)"
                if t is not None and len(t) and args.cmd != "sweep" else "interrupted (Ctrl-C)")
    else:
        text = _describe(exc)
        if not isinstance(exc, (MbdkErrorBase, OSError)):
            text += " (an unexpected error: --traceback shows where)"
    if args.cmd in WRITERS and getattr(args, "written", None) is None:
        text += "; no file written"
    try:
        print(f"{cmd}: {text}", file=sys.stderr, flush=True)
    except OSError:     # standard error itself is gone: the status still tells
        pass


def _main(args) -> int:
    if args.cmd == "report":
        if args.studies is not None and not args.studies.is_dir():
            raise InvalidInputError(f"--studies {args.studies}: not a folder")
        unknown = [n for n in (args.only or []) if n not in STUDIES]
        if unknown:
            raise InvalidInputError(f"--only {unknown[0]}: no such study; the studies: "
                                    f"{', '.join(STUDIES)}")
        build_report(args.out, quick=args.quick, studies=args.studies, only=args.only)
    elif args.cmd == "methods":
        for m in methods().values():
            print(f"{m.name:16s} order {m.order}  {'implicit' if m.implicit else 'explicit'}"
                  f"  {m.stability}  [{m.reference}]")
    elif args.cmd == "problems":
        for p in problems().values():
            print(f"{p.name:18s} n={p.n or 'len(y0)'}  {p.equation}  params {p.params}  "
                  f"[{p.reference}]")
    elif args.cmd == "scenes":
        for kind in ("planar", "spatial"):
            for name in scenes(kind):
                sc = scene_or_file(name)
                print(f"{name:26s} {kind:8s} {sc.description}")
    elif args.cmd in ("scene", "check"):
        sc = scene_or_file(args.scene)
        print(scene_report(sc))
        print(_assembly_line(sc))
        if args.symbolic:
            r = cross_check(sc)
            print("symbolic cross-check (SymPy, max relative difference at 5 random "
                  "states): " + ", ".join(f"{k} {r[k]:.1e}" for k in
                                          ("phi", "D", "gamma", "phit", "f", "a", "lam")
                                          if r[k] is not None)
                  + (" (f from the kernel: contacts)" if r["f_from_kernel"] else "")
                  + f"; derivation {r['derive_s']:.2f} s CPU")
    elif args.cmd == "run":
        _run(args)
    elif args.cmd == "sweep":
        if args.out.suffix.lower() != ".csv":
            raise InvalidInputError(f"{args.out}: a sweep's table is a CSV file; give a name "
                                    "ending in .csv")
        check_writable(args.out)
        if args.workers is not None and args.scheduler is not None:
            raise InvalidInputError(f"--workers {args.workers} with --scheduler "
                                    f"{args.scheduler}: the scheduler's cluster has its own "
                                    "workers; give one of the two")
        table = sweep(load_grid(args.grid), workers=2 if args.workers is None else args.workers,
                      scheduler=args.scheduler)
        table.to_csv(args.out)
        args.written = args.out
        failed = [r for r in table.rows if r["error_message"]]
        kinds = sorted({r["status"] for r in failed})
        print(f"{plural(len(table.rows), 'run')} on {table.engine} in "
              f"{seconds(table.wall_time)} ({len(failed)} failed"
              f"{': ' + ', '.join(kinds) if kinds else ''}); wrote {args.out}")
    elif args.cmd == "plot":
        args.written = plot_result(args.result, args.out)
        print(f"wrote {args.written}")
    elif args.cmd == "animate":
        _animate(args)
    elif args.cmd == "tables":
        sc = scene_or_file(args.scene)
        args.written = write_tables(sc, args.out, args.t0)
        print(f"wrote {args.written}: the tables of {sc.kind} scene {sc.name!r} for "
              "mbdk_scene_tables_read (mbdk.h)")
    elif args.cmd == "fmu":
        sc = scene_or_file(args.scene)
        kw = given(args, simulate, FMU_SKIP)
        if hasattr(args, "step_size"):
            kw["step_size"] = args.step_size
        args.written = export_fmu(sc, args.out, args.method, inputs=args.inputs,
                                  stop_time=args.stop_time, bundle=args.bundle, **kw)
        print(f"wrote {args.written}: scene {sc.name!r} ({sc.kind}) by {args.method} as an FMI "
              f"3.0 co-simulation FMU{'' if args.bundle else ' (libraries not bundled)'}")
    elif args.cmd == "solve":
        r = ode.solve_ode(args.problem, args.method, **given(args, _SOLVE_API, SOLVE_SKIP))
        print(f"t = {r.t[-1]:.10g}  y = {r.y[-1].tolist()}  {plural(r.stats.steps, 'step')}  "
              f"CPU {seconds(r.cpu_time)}  status {r.status.name}")
    return 0


def plural(n: int, word: str) -> str:
    """'1 step', '2 steps'."""
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def seconds(t: float) -> str:
    """A time in plain units: 0.25 ms, 12.3 ms, 4.89 s, 2 min 3 s."""
    if t < 1e-3:
        return f"{1e6 * t:.3g} us"
    if t < 1.0:
        return f"{1e3 * t:.3g} ms"
    if t < 120.0:
        return f"{t:.3g} s"
    return f"{int(t // 60)} min {t % 60:.0f} s"


def _assembly_line(sc) -> str:
    """What assembling the initial state onto the joints moves (a planar scene; a spatial
    scene's own check, mbdk.spatial_model.check_initial, refuses a start off its joints)."""
    if sc.kind == "spatial":
        return "assembly: a spatial scene's start is checked against its joints when it runs"
    _q, _v, rep = assemble(sc, build_tables(sc))
    if not rep["changes"]:
        return "assembly: the initial state meets every joint as given (nothing moved)"
    moved = ", ".join(f"{k} by {v:+.3g}" for k, v in rep["changes"].items())
    return (f"assembly: {plural(rep['iterations'], 'iteration')} moved {moved} onto the "
            "joints (the coordinates not marked given)")


def _run(args) -> None:
    """mbdk run: the scene run, a summary on one screen, the result file (written only when
    the run succeeded)."""
    out = check_writable(args.out)
    sc = scene_or_file(args.scene)
    kw = given(args, simulate, RUN_SKIP)
    r = simulate(sc, args.method, **kw)
    m = r.manifest
    sc_ = m.get("step_control")
    control = (f"{sc_['mode']} step-size control, err_rtol = {sc_['err_rtol']:g}, err_atol = "
               f"{sc_['err_atol']:g}" if sc_ else
               f"rtol = {m['rtol']:g}, atol = {m.get('atol')}" if "rtol" in m else
               f"h = {m.get('h', kw.get('h'))}")
    print(f"scene {sc.name!r}: {args.method}/{m.get('formulation', '')}, {control}, "
          f"t = {r.t[0]:g} .. {r.t[-1]:g}")
    print(f"status {r.status.name}; {plural(r.stats.steps, 'step')}; CPU "
          f"{seconds(r.cpu_time)} (the solving thread), wall {seconds(r.stats.wall_time)}")
    if r.residuals is not None and len(r.residuals):
        res = np.max(np.abs(r.residuals), axis=0)
        print(f"residuals (max over the samples): |Phi| {res[0]:.2e}, |Phi'| {res[1]:.2e}")
    if r.energy is not None:
        try:
            bal = float(np.max(np.abs(r.energy_balance())))
            work = float(r.energy_parts["work"][-1])
            print(f"energy balance: max |E - E0 - W| {bal:.2e} J (E0 = {r.energy[0]:.6g} J; "
                  f"W, the work of dampers, loads and drivers integrated at every step, "
                  f"{work:.6g} J at the end)")
        except MbdkErrorBase:
            pass
    for name, c in r.contacts.items():
        print(f"contact {name!r}: largest penetration {np.nanmax(c['penetration']):.3g} m, "
              f"normal force {np.nanmax(c['normal_force']):.6g} N, friction force "
              f"{np.nanmax(c['friction_force']):.6g} N (over the samples)")
    for name, w in r.wear.items():
        print(f"wear {name!r}: {w[-1]:.6g} m^3 worn by t = {r.t[-1]:g} s")
    save_result(r, out)
    args.written = out
    print(f"wrote {out} ({len(r.t)} samples of every output the run has, with the "
          "manifest)")


def _animate(args) -> None:
    """mbdk animate: the scene run, then its motion as a page (written only when the run
    succeeded)."""
    if args.frames < 2:
        raise InvalidInputError(f"--frames {args.frames}: give at least 2 (the first and the "
                                "last sample)")
    out = check_writable(args.out, (".html", ".htm"))
    sc = scene_or_file(args.scene)
    kw = given(args, simulate, RUN_SKIP)
    info = methods().get(args.method)
    if info is not None and info.adaptive and "dt_out" not in kw and "t_eval" not in kw:
        # an error-controlled run samples only its ends unless told: spread the frames'
        # samples over the run (simulate's own default otherwise)
        # (frames - 1 intervals: the first and the last sample are frames)
        kw["dt_out"] = (kw.get("t_end", 1.0) - kw.get("t0", 0.0)) / (args.frames - 1)
    # the frames need the coordinates only, unless other outputs are asked for
    kw.setdefault("outputs", ())
    r = simulate(sc, args.method, **kw)
    args.written = write_animation(r, sc, out, max_frames=args.frames)
    print(f"scene {sc.name!r}: {args.method}, t = {r.t[0]:g} .. {r.t[-1]:g} s, "
          f"{plural(len(r.t), 'sample')}, {plural(min(len(r.t), args.frames), 'frame')} at "
          f"most; wrote {out} (open it in a browser)")
