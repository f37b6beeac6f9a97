"""Tables the documentation reads from the running package, so that they cannot drift from it:

    .. mbdk-table:: status      the kernel's status table: code, name, message, exception
    .. mbdk-table:: methods     the method registry: name, family, order, stability, reference
    .. mbdk-table:: problems    the compiled problems: name, size, equation, parameters
    .. mbdk-table:: scenes      the built-in scenes: name, kind, description
    .. mbdk-cli-help::          the help of the command line and of each of its commands

and the docstrings' bars escaped for reST (escape_bars).
"""
import os
import re

from docutils import nodes
from docutils.parsers.rst import Directive
from docutils.statemachine import StringList

import mbdk
from mbdk import cli
from mbdk.errors import exception_for, status_message


def _cell(text) -> str:
    return str(text).replace("\n", " ").replace("|", "\\|")


def _status_rows():
    for s in mbdk.Status:
        exc = exception_for(s).__name__ if s.failed else "(success)"
        yield [f"``{int(s)}``", f"``{s.name}``", status_message(s), f"``{exc}``"]


def _method_rows():
    for m in mbdk.methods().values():
        yield [f"``{m.name}``", m.family, str(m.order), m.stability, m.reference]


def _problem_rows():
    for p in mbdk.problems().values():
        params = ", ".join(f"{k} = {v:g}" if isinstance(v, float) else f"{k} = {v}"
                           for k, v in p.params.items())
        yield [f"``{p.name}``", str(p.n or "len(y0)"), p.equation, params or "-", p.reference]


def _scene_rows():
    for kind in ("planar", "spatial"):
        for name in mbdk.scenes(kind):
            sc = mbdk.scene(name)
            yield [f"``{name}``", kind, getattr(sc, "description", "") or "-"]


TABLES = {
    "status": (["code", "name", "the kernel's message", "raised as"], _status_rows, "8 22 50 20"),
    "methods": (["name", "family", "order", "stability", "reference"], _method_rows,
                "16 12 6 36 30"),
    "problems": (["name", "n", "equation", "parameters (defaults)", "reference"], _problem_rows,
                 "16 6 36 22 20"),
    "scenes": (["name", "bodies", "what it is"], _scene_rows, "22 10 68"),
}


class MbdkTable(Directive):
    required_arguments = 1

    def run(self):
        which = self.arguments[0]
        if which not in TABLES:
            raise self.error(f"mbdk-table: {which!r} is not one of {', '.join(TABLES)}")
        header, rows, widths = TABLES[which]
        lines = [".. list-table::", "   :header-rows: 1", f"   :widths: {widths}", ""]
        for row in [header, *rows()]:
            lines.append(f"   * - {_cell(row[0])}")
            lines.extend(f"     - {_cell(c)}" for c in row[1:])
        node = nodes.container()
        self.state.nested_parse(StringList(lines, source=f"mbdk-table {which}"),
                                self.content_offset, node)
        return node.children


class MbdkCliHelp(Directive):
    """``.. mbdk-cli-help::`` the help of ``mbdk`` and of each of its commands, as argparse
    prints it, from the command line's own parser."""

    def run(self):
        os.environ["COLUMNS"] = "92"     # argparse wraps to the terminal's width
        ap = cli.parser()
        out = []
        seen = set()
        for name, p in [("mbdk", ap), *ap.commands.items()]:
            if id(p) in seen:            # an alias (check is scene)
                continue
            seen.add(id(p))
            title = "mbdk" if p is ap else f"mbdk {name}"
            section = nodes.rubric(text=title)
            block = nodes.literal_block(text=p.format_help().rstrip())
            block["language"] = "text"
            out += [section, block]
        return out


_INLINE_LITERAL = re.compile(r"(``.+?``|`[^`]+`)")


def _escape(text: str) -> str:
    """text with | escaped outside inline literals and roles."""
    parts = _INLINE_LITERAL.split(text)
    return "".join(p if k % 2 else p.replace("|", "\\|") for k, p in enumerate(parts))


def escape_bars(app, what, name, obj, options, lines):
    """The docstrings are plain text first (help() shows them as written) and write a norm or
    an absolute value as |x|, which reST reads as a substitution reference. Escape those bars,
    but not in literal blocks, doctests or tables, where they are text already."""
    literal = None          # the indentation of the line that opened a literal block
    doctest = False
    for i, line in enumerate(lines):
        stripped = line.lstrip()
        indent = len(line) - len(stripped)
        if literal is not None:
            if not stripped or indent > literal:
                continue
            literal = None
        if doctest:
            if stripped:
                continue
            doctest = False
        if stripped.startswith(">>>"):
            doctest = True
            continue
        if stripped.startswith(("+-", "+=", "| ")) or "|" not in line:
            if stripped.endswith("::"):
                literal = indent
            continue
        lines[i] = _escape(line)
        if stripped.endswith("::"):
            literal = indent


def setup(app):
    app.add_directive("mbdk-table", MbdkTable)
    app.connect("autodoc-process-docstring", escape_bars)
    app.add_directive("mbdk-cli-help", MbdkCliHelp)
    return {"parallel_read_safe": True, "version": mbdk.__version__}
