"""The report's tables (issue 39): one number format per column, chosen from all the column's
values; decimal points throughout (the book's decimal commas converted where a cell is a
number); long tables shown as their head and flagged rows with a link to the CSV; the front
page's findings from the rows a study flags."""
import math
import re

import numpy as np

from mbdk.analysis.tables import column_format, fmt, format_column, format_rows, write_table
from mbdk.report import _table_html, findings, flagged_rows, is_flagged, INLINE_ROWS, HEAD_ROWS


def _decimals(cell: str) -> int:
    mant = cell.split("e")[0]
    return len(mant.split(".")[1]) if "." in mant else 0


def test_a_moderate_column_is_fixed_point_with_one_number_of_decimals():
    vals = [0.5, 0.25, 0.125, 0.0625, 0.03125, 12.0]
    cells = format_column(vals)
    assert all("e" not in c for c in cells)
    assert len({_decimals(c) for c in cells}) == 1
    # the smallest magnitude keeps five significant digits, and every cell reads back its value
    assert cells[4] == "0.031250"
    assert all(abs(float(c) - v) <= 0.5e-6 for c, v in zip(cells, vals))


def test_a_column_over_many_decades_is_scientific_throughout():
    # the report used to show "0.001" beside "1.0000e-04" in one column
    cells = format_column([0.001, 1e-4, 0.5, 2.0e-9])
    assert cells == ["1.0000e-03", "1.0000e-04", "5.0000e-01", "2.0000e-09"]
    assert column_format([1e5, 2.0]) == "e4" and column_format([1e-4, 2e-4]) == "e4"
    assert column_format([1.0, 1e4 * 1.01]) == "e4"       # beyond four decades: scientific


def test_integers_text_missing_and_non_finite_keep_their_own_form():
    cells = format_column([3, None, "FLAG", math.nan, -math.inf, 1.5, np.float64(2.25)])
    assert cells[:5] == ["3", "", "FLAG", "nan", "-inf"]
    assert cells[5:] == ["1.5000", "2.2500"]
    assert fmt(np.int64(7)) == "7" and fmt(True) == "True"


def test_decimal_commas_of_numbers_become_points_and_other_commas_stay():
    assert format_column(["-7,27", "3,41", "1,5e-3", "0.5"]) == ["-7.27", "3.41", "1.5e-3", "0.5"]
    assert fmt("1,2,3") == "1,2,3"
    assert fmt("the book's 7,27 is a misprint, see (4.9)") == "the book's 7,27 is a misprint, see (4.9)"


def test_every_column_of_a_table_has_one_format(tmp_path):
    rng = np.random.default_rng(3)
    rows = [{"h": 0.1 / 2 ** k, "error": float(rng.uniform(0.5, 2)) * 10.0 ** (-2 * k),
             "n": 10 * 2 ** k, "book": f"{k},{k + 1}"} for k in range(6)]
    cols = ["h", "error", "n", "book"]
    cells = format_rows(rows, cols)
    for j, c in enumerate(cols[:2]):
        column = [r[j] for r in cells]
        assert len({("e" in x, _decimals(x)) for x in column}) == 1, (c, column)
    assert [r[3] for r in cells] == [f"{k}.{k + 1}" for k in range(6)]
    t = write_table(rows, cols, tmp_path, "t", "a table")
    md_rows = [line.split("|")[1:-1] for line in t["md"].read_text().splitlines()[4:]]
    assert [[x.strip() for x in r] for r in md_rows] == cells
    assert "," not in "".join(x for r in cells for x in r)
    # the CSV keeps full precision: it is the data, not the display
    assert repr(rows[1]["error"]) in t["csv"].read_text()


def test_flagged_rows_are_found_once_and_head_the_findings():
    bad = {"quantity": "y(1)", "verdict": "FLAG"}
    ok = {"quantity": "y(2)", "verdict": "agrees"}
    tables = [{"rows": [bad, ok, {"eq": "(2.93)", "verdict": "book wrong: a sign"}]},
              {"rows": [dict(bad), {"eq": "(2.93)", "term": 2, "verdict": "WRONG"}]}]
    assert [is_flagged(r) for r in tables[0]["rows"]] == [True, False, True]
    assert len(flagged_rows(tables)) == 3                 # a table of flags repeats them
    got = findings({"tables": tables, "findings": ["x is y"], "verdict": "all fine"})
    assert got == ["3 printed values of the book flagged: y(1); (2.93) (x2)", "x is y",
                   "all fine"]
    assert findings({"tables": [{"rows": [ok]}]}) == []


def test_a_long_table_shows_its_head_and_its_flags_and_links_the_csv(tmp_path):
    n = INLINE_ROWS + 30
    rows = [{"i": i, "verdict": "FLAG" if i == n - 3 else "agrees"} for i in range(n)]
    t = write_table(rows, ["i", "verdict"], tmp_path, "long", "long table")
    page = _table_html(t, tmp_path)
    shown = re.findall(r"<tr[^>]*><td class='n'>(\d+)</td>", page)
    assert shown == [str(i) for i in range(HEAD_ROWS)] + [str(n - 3)]
    assert "href='long.csv'" in page and f"of {n} rows" in page
    short = write_table(rows[:INLINE_ROWS], ["i", "verdict"], tmp_path, "short", "short")
    assert len(re.findall(r"<tr[^>]*><td", _table_html(short, tmp_path))) == INLINE_ROWS
