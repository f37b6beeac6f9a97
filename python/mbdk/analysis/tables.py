"""Writing a study's tables as CSV and Markdown (and reading them back into the report).

The CSV keeps every value at full precision (it is the data); the Markdown and the report show
each column in one number format, chosen from all of the column's values, so that a reader can
compare the rows of a column digit by digit."""
from __future__ import annotations

import csv
import math
import numbers
import re
from pathlib import Path

#: significant digits shown of every real number in the report's tables
DIGITS = 5

# A number printed with a decimal comma, as the book's tables print them ("-7,27", "3,41e-4"):
# the report shows decimal points throughout. Only whole cells that are such a number are
# converted, so that a list such as "1,2,3" in a note stays as written.
_COMMA_NUMBER = re.compile(r"[-+]?\d+,\d+([eE][-+]?\d+)?")


def _is_real(v) -> bool:
    return (isinstance(v, numbers.Real) and not isinstance(v, (bool, numbers.Integral)))


def _text(v) -> str:
    s = str(v)
    return s.replace(",", ".") if _COMMA_NUMBER.fullmatch(s.strip()) else s


def column_format(values, digits: int = DIGITS) -> str:
    """The one format for a column's real numbers: "f<decimals>" (fixed point) when the finite
    non-zero magnitudes lie within [1e-3, 1e5) and within four decades of each other, so that the
    smallest still shows `digits` significant digits; otherwise "e<digits - 1>" (scientific with
    `digits` significant digits). Integers, text and missing values do not take part."""
    mags = [abs(float(v)) for v in values
            if _is_real(v) and math.isfinite(float(v)) and float(v) != 0.0]
    if not mags:
        return f"f{digits - 1}" if any(_is_real(v) for v in values) else ""
    lo, hi = min(mags), max(mags)
    if lo >= 1e-3 and hi < 1e5 and hi / lo < 1e4:
        return f"f{max(0, digits - 1 - math.floor(math.log10(lo)))}"
    return f"e{digits - 1}"


def fmt(v, spec: str = "") -> str:
    """One cell: a real number in the column's format `spec` (see column_format; by itself when
    none is given), an integer as it is, text with a decimal comma turned into a point."""
    if v is None:
        return ""
    if _is_real(v):
        x = float(v)
        if math.isnan(x):
            return "nan"
        if math.isinf(x):
            return "inf" if x > 0 else "-inf"
        spec = spec or column_format([x])
        if x == 0.0 and spec.startswith("e"):
            return "0"
        return f"{x:.{int(spec[1:])}{spec[0]}}"
    if isinstance(v, numbers.Integral) and not isinstance(v, bool):
        return str(int(v))
    return _text(v)


def format_column(values, digits: int = DIGITS) -> list[str]:
    """Every cell of one column in the column's one format."""
    spec = column_format(values, digits)
    return [fmt(v, spec) for v in values]


def format_rows(rows: list[dict], columns: list[str]) -> list[list[str]]:
    """The table's cells as text, row by row, each column in its own one format."""
    cols = [format_column([r.get(c) for r in rows]) for c in columns]
    return [list(cells) for cells in zip(*cols)] if cols else [[] for _ in rows]


def write_table(rows: list[dict], columns: list[str], out: Path, name: str, title: str,
                notes: str = "") -> dict:
    """Writes out/name.csv and out/name.md; returns a description for the report."""
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / f"{name}.csv"
    with open(csv_path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=columns, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({c: ("" if r.get(c) is None else r.get(c)) for c in columns})
    md = [f"### {title}", ""]
    md.append("| " + " | ".join(columns) + " |")
    md.append("|" + "---|" * len(columns))
    for cells in format_rows(rows, columns):
        md.append("| " + " | ".join(cells) + " |")
    if notes:
        md += ["", notes]
    md_path = out / f"{name}.md"
    md_path.write_text("\n".join(md) + "\n")
    return {"name": name, "title": title, "csv": csv_path, "md": md_path, "columns": columns,
            "rows": rows, "notes": notes}


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))
