"""The study report: runs every script in studies/ and writes one page per study (its findings,
figures with captions, a study's own HTML (animations), short tables inline and long ones as a
head with a link to the CSV) under a front page that fits one screen: per study its title, what
it found and a link, the hard cases the studies met, and the build manifest."""
from __future__ import annotations

import html
import importlib.util
import json
import numbers
import sys
import time
from collections import Counter
from pathlib import Path

from ._compiled import print_line, progress_bar
from .analysis.tables import format_rows
from .ode import build_info

#: the studies in report order (file names in studies/)
STUDIES = ["scene_motion", "ch4_tables", "pendulum", "phase_portraits", "work_precision",
           "error_control", "benchmark_rk4", "stability", "scene_drift", "scene_checks",
           "ch3_pendulum", "index3", "pipeline_cost", "step_control", "ch5_formulas",
           "ch6_numbers", "gear_wear", "knee_wear", "rigid_body", "spatial_scenes",
           "symbolic_check", "sweep_scaling", "fuzz"]

#: tables longer than this are shown as their head (and flagged rows) with a link to the CSV:
#: a reader scans a few dozen rows, the rest is data for a script
INLINE_ROWS = 40
#: rows of a long table shown on the study's page
HEAD_ROWS = 12

_STYLE = """body{font-family:sans-serif;max-width:1300px;margin:auto;padding:0.5em 1em}
h1{font-size:20px;margin:0.3em 0}h2{font-size:17px}h3{font-size:14px;margin:1em 0 0.2em}
table{border-collapse:collapse;font-size:12px;margin:0.4em 0}td,th{border:1px solid #ccc;
padding:2px 5px}th{background:#eee}td{font-variant-numeric:tabular-nums}tr.flag{background:#ffe3e3}
td.n{text-align:right;white-space:nowrap}img{max-width:100%}figure{margin:1em 0}figcaption{font-size:13px;max-width:70em}
.note,.verdict{background:#f5f5ff;padding:0.5em}.files{color:#777;font-size:11px}
pre.doc{white-space:pre-wrap;background:#fafafa;padding:0.5em;font-size:12px}
table.front{width:100%;table-layout:fixed}table.front td{white-space:nowrap;overflow:hidden;
text-overflow:ellipsis}table.front td.n{text-align:right}table.front td.what{color:#777}
table.front td div{white-space:normal;display:-webkit-box;-webkit-line-clamp:2;
-webkit-box-orient:vertical;overflow:hidden}
table.manifest{font-size:11px}p.intro{font-size:13px;margin:0.3em 0}"""


def find_studies(explicit: Path | None = None) -> Path:
    """studies/ of the source tree: given, or next to the package's source (editable install),
    or in the working directory."""
    candidates = [explicit] if explicit else []
    candidates += [Path(__file__).resolve().parents[2] / "studies", Path.cwd() / "studies"]
    for c in candidates:
        if c is not None and (c / "ch4_tables.py").is_file():
            return c
    raise FileNotFoundError("studies/ not found: run from the repository root or pass "
                            "--studies PATH")


def load_study(folder: Path, name: str):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
    spec = importlib.util.spec_from_file_location(f"mbdk_study_{name}", folder / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def is_flagged(row: dict) -> bool:
    """A row where the study found the book (or a printed form) wrong: the studies' verdicts are
    FLAG (a book value beyond its rounding), WRONG or DIFFER (a printed formula), or a sentence
    beginning "book " (scene_checks names the book's slip)."""
    v = row.get("verdict")
    if not isinstance(v, str):
        return False
    return v.strip().upper() in ("FLAG", "WRONG", "DIFFER") or v.startswith("book ")


def flagged_rows(tables: list[dict]) -> list[dict]:
    """The study's flagged rows, each once (a study may list them again in a table of its own)."""
    seen, out = set(), []
    for t in tables:
        for r in t["rows"]:
            if is_flagged(r):
                key = json.dumps(r, sort_keys=True, default=str)
                if key not in seen:
                    seen.add(key)
                    out.append(r)
    return out


def _row_label(row: dict) -> str:
    """A flagged row named by the first of its identifying columns (which table, equation,
    method or quantity), as the study's table names it."""
    keys = ("table", "equation", "eq", "formula", "row", "method", "quantity", "h")
    return " ".join(str(row[k]) for k in keys if row.get(k) not in (None, ""))


def findings(summary: dict) -> list[str]:
    """What the study found, most important first: the lines it gives ("findings"), its
    verdict, and the count of flagged rows."""
    lines = [str(f) for f in summary.get("findings", [])]
    if summary.get("verdict"):
        lines.append(str(summary["verdict"]))
    flags = flagged_rows(summary["tables"])
    if flags:
        n = len(flags)
        # one entry per flagged item, with how many rows flag it (an equation checked term
        # by term flags several rows)
        labels = Counter(_row_label(r) for r in flags)
        lines.insert(0, f"{n} printed value{'s' if n != 1 else ''} of the book flagged: "
                     + "; ".join(k + (f" (x{c})" if c > 1 else "") for k, c in labels.items()))
    return lines


def figures(summary: dict, out: Path) -> list[dict]:
    """The study's figures as {"path", "caption"}; a figure given as a bare path is captioned
    with its file name."""
    figs = []
    for f in summary.get("figures", []):
        if isinstance(f, dict):
            path, cap = Path(f["path"]), f.get("caption") or Path(f["path"]).stem
        else:
            path, cap = Path(f), Path(f).stem.replace("_", " ")
        figs.append({"path": path, "caption": cap})
    return figs


def _rel(p, base: Path) -> str:
    return html.escape(Path(p).resolve().relative_to(base.resolve()).as_posix())


def _table_html(t: dict, out_dir: Path) -> str:
    cols, rows = t["columns"], t["rows"]
    links = " · ".join(f"<a href='{_rel(t[k], out_dir)}'>{html.escape(Path(t[k]).name)}</a>"
                       for k in ("csv", "md"))
    cells = format_rows(rows, cols)
    shown = list(range(len(rows)))
    head = ""
    if len(rows) > INLINE_ROWS:
        # the head, and every flagged row below it: a flag is what the reader came for
        shown = sorted(set(range(HEAD_ROWS)) | {i for i, r in enumerate(rows) if is_flagged(r)})
        head = (f"<p class='files'>{len(shown)} of {len(rows)} rows shown (the first "
                f"{HEAD_ROWS} and every flagged one); all rows: "
                f"<a href='{_rel(t['csv'], out_dir)}'>{html.escape(Path(t['csv']).name)}</a></p>")
    out = [f"<h3>{html.escape(t['title'])}</h3>", f"<p class='files'>{links}</p>", head,
           "<table><thead><tr>" + "".join(f"<th>{html.escape(c)}</th>" for c in cols)
           + "</tr></thead><tbody>"]
    for i in shown:
        cls = " class='flag'" if is_flagged(rows[i]) else ""
        # numbers right-aligned on one line (a wrapped "2.3e-\n06" misreads), text wraps
        out.append(f"<tr{cls}>" + "".join(
            f"<td class='n'>{html.escape(x)}</td>" if isinstance(rows[i].get(c), numbers.Number)
            else f"<td>{html.escape(x)}</td>" for c, x in zip(cols, cells[i])) + "</tr>")
    out.append("</tbody></table>")
    if t.get("notes"):
        out.append(f"<p class='note'>{html.escape(t['notes'])}</p>")
    return "\n".join(out)


def _flags_that_matter(flags: str) -> str:
    """The compiler options that change the numbers or the speed (optimisation, target, floating
    point, language standard), not the build's include and output paths."""
    keep = [f for f in str(flags).split() if f.startswith(("-O", "-m", "-f", "-std", "-g"))
            and "/" not in f and not f.startswith(("-fdiagnostics", "-fpre-include",
                                                   "-fintrinsic-modules-path"))]
    return " ".join(keep) or "(none)"


def _manifest_html(m: dict) -> str:
    """The run's manifest as a table: what produced every number of the report."""
    rows = [("mbdk version", m.get("version")), ("compiler", m.get("compiler")),
            ("compiler flags", _flags_that_matter(m.get("compiler_flags", ""))),
            ("numpy", m.get("numpy")), ("Python", m.get("python")),
            ("machine", m.get("machine")), ("quick run", m.get("quick")),
            ("generated", m.get("generated")), ("seconds", m.get("total_seconds"))]
    # two fields a row keeps the manifest a few lines high on the front page
    pairs = [rows[i:i + 2] for i in range(0, len(rows), 2)]
    body = "".join("<tr>" + "".join(f"<th>{html.escape(k)}</th><td>{html.escape(str(v))}</td>"
                                     for k, v in p) + "</tr>" for p in pairs)
    return (f"<table class='manifest'>{body}</table>"
            "<p class='files'><a href='manifest.json'>manifest.json</a> (all fields)</p>")


def _page(title: str, body: str) -> str:
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}"
            f"</title><style>{_STYLE}</style></head><body>\n{body}\n</body></html>\n")


def _study_page(name: str, summary: dict, doc: str, seconds: float, out: Path) -> str:
    found = findings(summary)
    parts = ["<p class='files'><a href='index.html'>report front page</a></p>",
             f"<h1>{html.escape(summary['title'])}</h1>",
             f"<p class='files'>studies/{name}.py · {seconds:.1f} s</p>"]
    if found:
        parts.append("<ul class='findings'>" + "".join(f"<li>{html.escape(f)}</li>"
                                                       for f in found) + "</ul>")
    parts.append(f"<details><summary>What the study does</summary><pre class='doc'>"
                 f"{html.escape(doc)}</pre></details>")
    # a study's own HTML (scene_motion's animations), as it wrote it
    parts += [str(h) for h in summary.get("html", [])]
    for fig in figures(summary, out):
        rel = _rel(fig["path"], out)
        parts.append(f"<figure><img src='{rel}' alt='{html.escape(fig['path'].stem)}'>"
                     f"<figcaption>{html.escape(fig['caption'])}</figcaption></figure>")
    for t in summary["tables"]:
        parts.append(_table_html(t, out))
    return _page(summary["title"], "\n".join(parts))


def _hard_cases_html(entries: list[dict]) -> str:
    """The hard cases the studies met (drift, stiffness, singular poses, redundant joints,
    gimbal lock), a line each with a link to the study that met it: what a reader who doubts
    the kernel looks for first. Each study names its own (its summary's "hard_cases")."""
    rows = [(case, line, e["name"]) for e in entries
            for case, line in (e.get("hard_cases") or {}).items()]
    if not rows:
        return ""
    body = "".join(f"<tr><td><a href='{n}.html'>{html.escape(c)}</a></td>"
                   f"<td title='{html.escape(str(x))}'>{html.escape(str(x))}</td></tr>"
                   for c, x, n in rows)
    return ("<table class='front hard'><colgroup><col style='width:15%'><col></colgroup>"
            f"<thead><tr><th>hard case</th><th>what the runs met</th></tr></thead>"
            f"<tbody>{body}</tbody></table>")


def _front_page(entries: list[dict], manifest: dict) -> str:
    rows = []
    for e in entries:
        if e["findings"]:
            first = e["findings"][0]
            rest = f" (+{len(e['findings']) - 1} more)" if len(e["findings"]) > 1 else ""
            full, cls = " | ".join(e["findings"]), ""
        else:
            # a study that flags nothing: say what it checks, in grey
            first, rest, cls = e.get("what", ""), "", " class='what'"
            full = first
        rows.append(f"<tr><td><a href='{e['name']}.html'>{html.escape(e['title'])}</a></td>"
                    f"<td class='n'>{e['flagged'] or ''}</td>"
                    f"<td{cls} title='{html.escape(full)}'><div>{html.escape(first + rest)}"
                    "</div></td>"
                    "</tr>")
    body = f"""<h1>mbdk study report</h1>
<p class='intro'>Every number was computed by the kernel in this run. Each study has a page of
its own with its figures and tables; rows where the book's printed value disagrees beyond its
rounding are highlighted there, with why. "flagged": printed values the study found wrong.</p>
<table class='front'><colgroup><col style='width:30%'><col style='width:5%'><col></colgroup>
<thead><tr><th>study</th><th>flagged</th><th>what it found</th></tr></thead>
<tbody>{''.join(rows)}</tbody></table>
{_hard_cases_html(entries)}
{_manifest_html(manifest)}"""
    return _page("mbdk study report", body)


def build_report(out: Path, quick: bool = False, studies: Path | None = None,
                 only: list[str] | None = None) -> Path:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    folder = find_studies(studies)
    entries = []
    started = time.perf_counter()
    names = [n for n in STUDIES if not only or n in only]
    bar = progress_bar(len(names), "report", "study")
    for i, name in enumerate(names, 1):
        print_line(f"[{i}/{len(names)}] {name} ...")
        if bar is not None:
            bar.set_postfix_str(name)
        t0 = time.perf_counter()
        mod = load_study(folder, name)
        summary = mod.run(out / name, quick)
        dt = time.perf_counter() - t0
        print_line(f"[{i}/{len(names)}] {name}: {len(summary['tables'])} tables, "
                   f"{len(summary['figures'])} figures, {dt:.1f} s")
        if bar is not None:
            bar.update(1)
        doc = (mod.__doc__ or "").strip()
        (out / f"{name}.html").write_text(_study_page(name, summary, doc, dt, out))
        entries.append({"name": name, "title": summary["title"], "findings": findings(summary),
                        "flagged": len(flagged_rows(summary["tables"])),
                        "hard_cases": summary.get("hard_cases") or {},
                        "what": " ".join(doc.split("\n\n")[0].split())})
    manifest = {**build_info(), "quick": quick,
                "generated": time.strftime("%Y-%m-%d %H:%M:%S"),
                "total_seconds": round(time.perf_counter() - started, 1)}
    if bar is not None:
        bar.close()
    (out / "manifest.json").write_text(json.dumps(manifest, indent=2))
    index = out / "index.html"
    index.write_text(_front_page(entries, manifest))
    print(f"report: {index} ({manifest['total_seconds']} s)")
    return index
