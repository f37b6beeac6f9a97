"""Writing a study's tables as CSV and Markdown (and reading them back into the report)."""
from __future__ import annotations

import csv
import math
from pathlib import Path


def fmt(v, digits: int = 6) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if v == 0:
            return "0"
        if abs(v) >= 1e5 or abs(v) < 1e-3:
            return f"{v:.{max(digits - 2, 2)}e}"
        return f"{v:.{digits}g}"
    return str(v)


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
    for r in rows:
        md.append("| " + " | ".join(fmt(r.get(c)) for c in columns) + " |")
    if notes:
        md += ["", notes]
    md_path = out / f"{name}.md"
    md_path.write_text("\n".join(md) + "\n")
    return {"name": name, "title": title, "csv": csv_path, "md": md_path, "columns": columns,
            "rows": rows, "notes": notes}


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))
