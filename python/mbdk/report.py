"""The study report: runs every script in studies/ and assembles one HTML page with their
tables (book disagreements highlighted) and figures, headed by the build manifest."""
from __future__ import annotations

import html
import importlib.util
import json
import sys
import time
from pathlib import Path

from ._compiled import print_line, progress_bar
from .analysis.tables import fmt
from .ode import build_info

#: the studies in report order (file names in studies/)
STUDIES = ["ch4_tables", "pendulum", "phase_portraits", "work_precision", "error_control",
           "benchmark_rk4", "stability", "scene_drift", "scene_checks", "ch3_pendulum", "index3",
           "pipeline_cost", "step_control", "ch5_formulas", "ch6_numbers", "gear_wear",
           "knee_wear", "rigid_body", "spatial_scenes", "symbolic_check", "sweep_scaling", "fuzz"]


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


def _table_html(t: dict, out_dir: Path) -> str:
    cols = t["columns"]
    links = " · ".join(f"<a href='{html.escape(str(Path(t[k]).relative_to(out_dir)))}'>"
                       f"{html.escape(Path(t[k]).name)}</a>" for k in ("csv", "md"))
    out = [f"<h3>{html.escape(t['title'])}</h3>",
           f"<p class='files'>{links}</p>",
           "<table><thead><tr>" + "".join(f"<th>{html.escape(c)}</th>" for c in cols)
           + "</tr></thead><tbody>"]
    for r in t["rows"]:
        cls = " class='flag'" if r.get("verdict") == "FLAG" else ""
        out.append(f"<tr{cls}>" + "".join(f"<td>{html.escape(fmt(r.get(c)))}</td>" for c in cols)
                   + "</tr>")
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
    body = "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(str(v))}</td></tr>"
                   for k, v in rows)
    return (f"<table class='manifest'>{body}</table>"
            "<p class='files'><a href='manifest.json'>manifest.json</a> (all fields)</p>")


def build_report(out: Path, quick: bool = False, studies: Path | None = None,
                 only: list[str] | None = None) -> Path:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    folder = find_studies(studies)
    sections = []
    started = time.perf_counter()
    names = [n for n in STUDIES if not only or n in only]
    bar = progress_bar(len(names), "report", "study")
    for i, name in enumerate(names, 1):
        print_line(f"[{i}/{len(names)}] {name} ...")
        if bar is not None:
            bar.set_postfix_str(name)
        t0 = time.perf_counter()
        summary = load_study(folder, name).run(out / name, quick)
        dt = time.perf_counter() - t0
        print_line(f"[{i}/{len(names)}] {name}: {len(summary['tables'])} tables, "
                   f"{len(summary['figures'])} figures, {dt:.1f} s")
        if bar is not None:
            bar.update(1)
        doc = (load_study(folder, name).__doc__ or "").strip()
        parts = [f"<h2 id='{name}'>{html.escape(summary['title'])}</h2>",
                 f"<pre class='doc'>{html.escape(doc)}</pre>",
                 f"<p class='files'>studies/{name}.py · {dt:.1f} s</p>"]
        if summary.get("verdict"):
            parts.append(f"<p class='verdict'>{html.escape(summary['verdict'])}</p>")
        for fig in summary["figures"]:
            rel = Path(fig).relative_to(out)
            parts.append(f"<figure><img src='{html.escape(str(rel))}' alt='{html.escape(rel.stem)}'>"
                         f"<figcaption>{html.escape(rel.name)}</figcaption></figure>")
        for t in summary["tables"]:
            parts.append(_table_html(t, out))
        sections.append((name, summary["title"], "\n".join(parts)))
    manifest = {**build_info(), "quick": quick,
                "generated": time.strftime("%Y-%m-%d %H:%M:%S"),
                "total_seconds": round(time.perf_counter() - started, 1)}
    if bar is not None:
        bar.close()
    (out / "manifest.json").write_text(json.dumps(manifest, indent=2))
    toc = "".join(f"<li><a href='#{n}'>{html.escape(t)}</a></li>" for n, t, _ in sections)
    page = f"""<!doctype html><html><head><meta charset='utf-8'><title>mbdk study report</title>
<style>body{{font-family:sans-serif;max-width:1300px;margin:auto;padding:1em}}
table{{border-collapse:collapse;font-size:12px;margin:0.5em 0}}td,th{{border:1px solid #ccc;padding:2px 5px}}
th{{background:#eee}}tr.flag{{background:#ffe3e3}}img{{max-width:100%}}.note,.verdict{{background:#f5f5ff;padding:0.5em}}
.files{{color:#777;font-size:11px}}pre.doc{{white-space:pre-wrap;background:#fafafa;padding:0.5em}}</style></head><body>
<h1>mbdk study report</h1>
<p>Every number below was computed by the kernel in this run; rows where the book's printed value
disagrees beyond its rounding are highlighted and the note says why. Every error is shown with the
CPU time it took.</p>
{_manifest_html(manifest)}
<ul>{toc}</ul>
{''.join(s for _, _, s in sections)}
</body></html>"""
    index = out / "index.html"
    index.write_text(page)
    print(f"report: {index} ({manifest['total_seconds']} s)")
    return index
