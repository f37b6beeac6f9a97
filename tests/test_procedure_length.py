"""No kernel procedure is longer than MAX_LINES.

What it checks: every subroutine, function and module procedure body in kernel/src/**/*.f90,
counted in physical lines from its first statement to its end statement (both included, comments
and blank lines inside it too, and the internal procedures it contains), is at most MAX_LINES
long, except the ones listed in STILL_LONG with their current length. The test fails when a
procedure not in the list is longer than MAX_LINES, when a listed one is no longer there or has
become MAX_LINES long or shorter (take it off the list, so that the list cannot go stale), and
when a listed one has grown (its length is pinned: split it rather than let it grow). It also
fails when a file cannot be parsed into balanced procedure and interface blocks, so that a
parsing slip cannot hide a long procedure. Interface bodies (an abstract interface's, a C
binding's) declare a procedure and are not counted.

Why 150: a procedure that long mixes set-up, stepping, error control and output; the issue
"one mechanism model" asks that each does one thing, named for it.
"""
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ROOT / "kernel" / "src"
MAX_LINES = 150

#: Procedures still longer than MAX_LINES, outside the directories that have been split
#: (drivers/, sundials/, explicit/, implicit/, model/, spatial/): (file under kernel/src, name)
#: -> length in lines.
STILL_LONG = {}

_PREFIX = (r"(?:(?:pure|impure|elemental|recursive|non_recursive|module)\s+"
           r"|(?:integer|real|logical|complex|character|double\s+precision|type|class)"
           r"\s*(?:\([^()]*(?:\([^()]*\)[^()]*)*\))?\s+)*")
_START = re.compile(r"^\s*" + _PREFIX + r"(subroutine|function)\s+(\w+)", re.I)
_MODULE_PROCEDURE = re.compile(r"^\s*module\s+procedure\s+(\w+)\s*$", re.I)
_END = re.compile(r"^\s*end\s*(subroutine|function|procedure)\b\s*(\w*)", re.I)
_INTERFACE = re.compile(r"^\s*(?:abstract\s+)?interface\b", re.I)
_END_INTERFACE = re.compile(r"^\s*end\s*interface\b", re.I)


def _code(line: str) -> str:
    """line without its comment (a '!' outside a character literal)."""
    quote = None
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = None
        elif ch in "'\"":
            quote = ch
        elif ch == "!":
            return line[:i]
    return line


def procedure_lengths(path: Path) -> dict:
    """{name: length in lines} of the procedure bodies of one free-form Fortran file (see the
    module docstring; an internal procedure is named host.name); ValueError where its blocks do
    not balance."""
    lengths = {}
    stack = []          # (name, kind, first line) of the open procedures, innermost last
    interfaces = 0      # depth of interface blocks: their procedures are declarations
    continued = False   # the previous line ended with '&': this one is not a statement's start
    for number, raw in enumerate(path.read_text().splitlines(), start=1):
        line = _code(raw)
        if not line.strip():      # blank or a comment: a continued statement goes on after it
            continue
        starts_statement = not continued
        continued = line.rstrip().endswith("&")
        if not starts_statement:
            continue
        if _END_INTERFACE.match(line):
            interfaces -= 1
            if interfaces < 0:
                raise ValueError(f"{path}:{number}: 'end interface' without an interface")
            continue
        if _INTERFACE.match(line):
            interfaces += 1
            continue
        end = _END.match(line)
        if end:
            if interfaces:
                continue
            if not stack:
                raise ValueError(f"{path}:{number}: '{raw.strip()}' closes no procedure")
            name, kind, first = stack.pop()
            if end.group(1).lower() != kind or (end.group(2) and end.group(2).lower() != name):
                raise ValueError(f"{path}:{number}: '{raw.strip()}' closes {kind} {name}")
            key = ".".join([host for host, _, _ in stack] + [name])
            if key in lengths:
                raise ValueError(f"{path}:{number}: {key} defined twice")
            lengths[key] = number - first + 1
            continue
        if interfaces:
            continue
        start = _START.match(line)
        if start:
            stack.append((start.group(2).lower(), start.group(1).lower(), number))
        elif _MODULE_PROCEDURE.match(line):
            stack.append((_MODULE_PROCEDURE.match(line).group(1).lower(), "procedure", number))
    if stack or interfaces:
        what = f"procedure {stack[-1][0]}" if stack else "interface"
        raise ValueError(f"{path}: unclosed {what}")
    return lengths


def all_lengths() -> dict:
    """{(file under kernel/src, procedure name): length} over kernel/src/**/*.f90."""
    found = {}
    for path in sorted(SOURCES.rglob("*.f90")):
        rel = path.relative_to(SOURCES).as_posix()
        for name, n in procedure_lengths(path).items():
            found[(rel, name)] = n
    return found


def test_the_parser_measures_what_it_is_given(tmp_path):
    """A made-up file: a 2-line subroutine; a function with a kind and a prefix, its header
    continued across a comment line, with a comment saying 'end subroutine' (7 lines, its
    internal subroutine included, which is named host.name); an interface body, which is not
    counted; and files whose blocks do not balance."""
    src = tmp_path / "x.f90"
    src.write_text("module x\n"
                   "  abstract interface\n"
                   "    subroutine cb(a)\n"
                   "      real :: a\n"
                   "    end subroutine cb\n"
                   "  end interface\n"
                   "contains\n"
                   "  subroutine s(a)\n"
                   "  end subroutine s\n"
                   "  pure real(kind(1.0d0)) function f(a, &\n"
                   "      ! a comment inside the header\n"
                   "      b) result(c)   ! end subroutine s\n"
                   "  contains\n"
                   "    subroutine inner()\n"
                   "    end subroutine inner\n"
                   "  end function f\n"
                   "end module x\n")
    assert procedure_lengths(src) == {"s": 2, "f.inner": 2, "f": 7}
    src.write_text("module y\ncontains\n  subroutine s()\nend module y\n")
    with pytest.raises(ValueError, match="unclosed procedure s"):
        procedure_lengths(src)
    src.write_text("module y\ncontains\n  subroutine s()\n  end function s\nend module y\n")
    with pytest.raises(ValueError, match="closes subroutine s"):
        procedure_lengths(src)


def _end_statements(path: Path) -> int:
    """How many procedure end statements path has outside interface blocks, counted line by
    line without the parser (a check of it: a procedure whose start it missed would change
    its count or unbalance the file)."""
    count, inside = 0, False
    for line in path.read_text().splitlines():
        if re.match(r"^\s*end\s*interface\b", line, re.I):
            inside = False
        elif re.match(r"^\s*(abstract\s+)?interface\b", line, re.I):
            inside = True
        elif not inside and re.match(r"^\s*end\s*(subroutine|function|procedure)\b", line, re.I):
            count += 1
    return count


def test_every_kernel_file_parses_into_its_procedures():
    found = all_lengths()
    for path in SOURCES.rglob("*.f90"):
        rel = path.relative_to(SOURCES).as_posix()
        assert sum(f == rel for f, _ in found) == _end_statements(path), rel
    assert len(found) > 400
    # the SUNDIALS drivers' and the models' entries are there (a parser that missed them would
    # pass)
    assert ("sundials/mbdk_cvode.f90", "mbdk_cvode_solve") in found
    assert ("sundials/mbdk_ida.f90", "mbdk_ida_solve") in found
    assert ("model/mbdk_model.f90", "mbdk_model_init") in found
    assert ("spatial/mbdk_spatial_model.f90", "mbdk_spatial_init") in found


def test_no_procedure_is_longer_than_150_lines_but_the_listed_ones():
    found = all_lengths()
    too_long = {key: n for key, n in found.items() if n > MAX_LINES and key not in STILL_LONG}
    assert not too_long, f"longer than {MAX_LINES} lines (split them): {too_long}"
    stale = {key: (n, found.get(key)) for key, n in STILL_LONG.items()
             if found.get(key) is None or found[key] <= MAX_LINES}
    assert not stale, f"listed as too long but gone or short now (take them off): {stale}"
    grown = {key: (n, found[key]) for key, n in STILL_LONG.items() if found[key] > n}
    assert not grown, f"listed ones that have grown (listed, now): {grown}"
