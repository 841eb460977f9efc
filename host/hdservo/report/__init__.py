"""One self-contained HTML report from the JSON and plots of ``hdservo compare`` / ``test`` / ``identify``.

:func:`build_report` reads

* an ``hdservo-compare`` document (``OUT/compare.json``; its paths are relative to it)
  or one or more ``hdservo-test`` documents (``hdservo test --json``, with ``plots`` dirs),
* optionally the ``hdservo identify --json`` report (its plot list) and the
  ``hdservo download --json`` record,

and writes one HTML file: tables of every headline figure (targets of
docs/reference-axis.md marked met / not met, verdict against the PID baseline),
each procedure's conditions, figures and notes, and every plot embedded as a
base64 PNG data URI (no external file, script or style sheet).  Every plot is
checked before it is embedded: it must exist, be a PNG and not be blank
(:func:`check_png`); the ``<img>`` keeps the source path in ``data-source``.

Bad input raises :class:`ReportError` (one line naming the file) and leaves no output.
"""
from __future__ import annotations

import base64
import datetime as _dt
import html
import html.parser
import json
import os
from pathlib import Path
from typing import Any, Iterable, Mapping, Optional, Sequence

import numpy as np

from ..fileio import write_text_atomic
from ..plotting import pyplot

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


class ReportError(ValueError):
    """Bad report input (one line)."""


# ------------------------------------------------------------------------------------ inputs

def load_json(path: Path, formats: Optional[Sequence[str]] = None) -> dict[str, Any]:
    """Read a JSON document; with ``formats`` its ``format`` field must be one of them.

    Raises
    ------
    ReportError
        Missing, unreadable or not JSON, or the wrong format.
    """
    if not path.is_file():
        raise ReportError(f"{path}: no such file")
    try:
        doc = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as e:
        raise ReportError(f"{path}: cannot read ({e})") from None
    except json.JSONDecodeError as e:
        raise ReportError(f"{path}: line {e.lineno} column {e.colno}: not JSON ({e.msg})") from None
    if not isinstance(doc, dict):
        raise ReportError(f"{path}: expected a JSON object")
    if formats is not None and doc.get("format") not in formats:
        raise ReportError(f"{path}: expected format {' or '.join(formats)}, got {doc.get('format')!r}")
    return doc


def check_png(path: Path) -> tuple[int, int]:
    """Check that ``path`` is a PNG that holds a drawing (not one flat colour); returns (width, height), px.

    Raises
    ------
    ReportError
        Missing, not a PNG, undecodable or blank.
    """
    if not path.is_file():
        raise ReportError(f"{path}: plot file not found")
    data = path.read_bytes()
    if not data.startswith(PNG_MAGIC):
        raise ReportError(f"{path}: not a PNG file")
    try:
        pyplot()                                  # the backend, before any matplotlib module
        import matplotlib.image as mpimg
        img = np.asarray(mpimg.imread(path))
    except Exception as e:   # noqa: BLE001 - any decoder failure is a bad file
        raise ReportError(f"{path}: PNG does not decode ({e})") from None
    if img.ndim < 2 or img.shape[0] < 10 or img.shape[1] < 10:
        raise ReportError(f"{path}: PNG too small to be a plot ({img.shape})")
    rgb = img[..., :3] if img.ndim == 3 else img
    if float(np.ptp(rgb)) == 0.0:
        raise ReportError(f"{path}: PNG is blank (one colour)")
    return int(img.shape[1]), int(img.shape[0])


# ------------------------------------------------------------------------------------ html helpers

CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;margin:2em auto;max-width:1100px;color:#222;
line-height:1.4;padding:0 1em}
h1{font-size:1.6em;border-bottom:2px solid #345}h2{font-size:1.3em;margin-top:2em;border-bottom:1px solid #aaa}
h3{font-size:1.1em;margin-top:1.4em}table{border-collapse:collapse;margin:.6em 0;font-size:.9em}
th,td{border:1px solid #bbb;padding:.25em .6em;text-align:left;vertical-align:top}th{background:#eef}
td.num{text-align:right;font-variant-numeric:tabular-nums}.met{background:#d9f2d9}.notmet{background:#f7d4d4}
.better{color:#1a7a1a;font-weight:600}.worse{color:#b02020;font-weight:600}.same{color:#666}
figure{margin:1em 0;page-break-inside:avoid}figure img{max-width:100%;border:1px solid #ddd}
figcaption{font-size:.85em;color:#555}.note{color:#555;font-size:.9em}.fail{color:#b02020}
code{background:#f3f3f3;padding:0 .2em}
"""


def esc(x: Any) -> str:
    """HTML-escaped text of ``x``."""
    return html.escape(str(x), quote=True)


def fmt(v: Any) -> str:
    """A number to 4 significant digits; None -> ``none``; lists shortened."""
    if v is None:
        return "none"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, (list, tuple)):
        items = [fmt(x) for x in v[:8]]
        return "[" + ", ".join(items) + (", ..." if len(v) > 8 else "") + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}: {fmt(x)}" for k, x in list(v.items())[:8]) + (", ..." if len(v) > 8 else "") + "}"
    return str(v)


def table(header: Sequence[str], rows: Iterable[Sequence[Any]], classes: Optional[Iterable[Sequence[str]]] = None) -> str:
    """An HTML table; cells are escaped unless they are ``Raw``; numbers right-aligned."""
    out = ["<table><thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr></thead><tbody>"]
    cls_rows = list(classes) if classes is not None else None
    for i, row in enumerate(rows):
        cells = []
        for j, c in enumerate(row):
            cl = []
            if isinstance(c, (int, float)) and not isinstance(c, bool):
                cl.append("num")
            if cls_rows is not None and cls_rows[i][j]:
                cl.append(cls_rows[i][j])
            attr = f' class="{" ".join(cl)}"' if cl else ""
            text = c if isinstance(c, Raw) else esc(fmt(c))
            cells.append(f"<td{attr}>{text}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


class Raw(str):
    """Trusted HTML (not escaped by :func:`table`)."""


def flatten(d: Mapping[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    """Nested dict -> ``[("a.b", value), ...]`` (lists kept as values)."""
    out: list[tuple[str, Any]] = []
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out += flatten(v, key + ".")
        else:
            out.append((key, v))
    return out


class Images:
    """Embeds checked PNGs; remembers every file used (``used``).

    Parameters
    ----------
    base : Path
        Directory of the HTML file: ``data-source`` paths are relative to it.
    """

    def __init__(self, base: Path) -> None:
        self.used: list[Path] = []
        self.base = base

    def figure(self, path: Path, caption: str, source: str = "") -> str:
        """``<figure>`` with the PNG as a data URI (after :func:`check_png`); ``source`` is shown in the caption."""
        w, h = check_png(path)
        rel = os.path.relpath(path.resolve(), self.base.resolve())
        b64 = base64.b64encode(path.read_bytes()).decode("ascii")
        self.used.append(path)
        return (f'<figure><img src="data:image/png;base64,{b64}" width="{w}" height="{h}" '
                f'alt="{esc(caption)}" data-source="{esc(rel)}"><figcaption>{esc(caption)} '
                f'(<code>{esc(source or rel)}</code>)</figcaption></figure>')


# ------------------------------------------------------------------------------------ sections

def _headline_section(cmp: Mapping[str, Any]) -> str:
    ref, best = cmp["reference"], cmp["best"]
    names = list(cmp["controllers"])
    header = (["figure", "unit", "target"] + names + ([f"{best} vs {ref}"] if best != ref else [])
              + ["best measured"])
    rows, cls = [], []
    for key, f in cmp["figures"].items():
        row: list[Any] = [Raw(f"{esc(f['label'])}<br><code>{esc(key)}</code>"), f["unit"], f["target_text"]]
        c = ["", "", ""]
        for n in names:
            v = f["values"].get(n)
            met = f["meets_target"].get(n)
            row.append(Raw(esc(fmt(v)) + ("" if met is None else (" &#10003;" if met else " &#10007;"))))
            c.append("" if met is None else ("met" if met else "notmet"))
        if best != ref:
            vd = f["vs_" + ref].get(best, "n/a")
            row.append(Raw(f'<span class="{esc(vd)}">{esc(vd)}</span>'))
            c.append("")
        row.append(f.get("best_measured") or "-")
        c.append("")
        rows.append(row)
        cls.append(c)
    v = cmp.get("verdict", {})
    lines = ["<h2>Headline figures</h2>",
             "<p>Targets: the requirements of the reference axis. Green &#10003; = target met, red &#10007; = not met; "
             "&lsquo;none&rsquo; = no value (e.g. no rung of the rate ladder was smooth, or the procedure failed). "
             f"The verdict column compares <b>{esc(best)}</b> (the compensated axis) with <b>{esc(ref)}</b>; "
             "&lsquo;best measured&rsquo; names the controller with the best value of each figure.</p>",
             table(header, rows, cls)]
    if v.get("targets_met"):
        met = [k for k, ok in v["targets_met"].items() if ok]
        miss = [k for k, ok in v["targets_met"].items() if not ok]
        lines.append(f"<p><b>{esc(best)}</b>: {len(met)} of {len(v['targets_met'])} targets met"
                     + (f"; not met: {esc(', '.join(miss))}" if miss else "") + ". "
                     f"Better than {esc(ref)} on every figure: <b>{'yes' if v.get('better_everywhere') else 'no'}</b>"
                     f" (not worse anywhere: {'yes' if v.get('not_worse_anywhere') else 'no'}).</p>")
    return "\n".join(lines)


def _ablation_section(cmp: Mapping[str, Any]) -> str:
    """Per feedback configuration: every row's value and ratio to the fair PID of that configuration, per figure."""
    keys = list(cmp["figures"])
    fbs: list[str] = []
    for d in cmp["controllers"].values():
        if d.get("feedback", "full-closed") not in fbs:
            fbs.append(d.get("feedback", "full-closed"))
    ab = cmp.get("ablation", {})
    out = ["<h2>Ablation: each row against the fair PID</h2>",
           "<p>Every row runs with the loop gains of the compensated set and the stabilisation in the gyro mode "
           "(the fair PID); the ratio is the row's value over the fair PID's value in the same feedback "
           "configuration (for the bandwidth and the peak torque higher is better, for every other figure "
           "lower). Motion strategies (hold logic, one-direction final approach) are their own rows; "
           "&lsquo;pid-hold&rsquo; is an extra row (the PID design gains in position hold), not a baseline.</p>"]
    if ab.get("rule"):
        out.append(f"<p>Rule: {esc(ab['rule'])}.</p>")
    for fb in fbs:
        names = [n for n, d in cmp["controllers"].items() if d.get("feedback", "full-closed") == fb]
        base = "pid" if fb == "full-closed" else f"pid@{fb}"
        info = ab.get("feedbacks", {}).get(fb, {})
        out.append(f"<h3>{esc(fb)}</h3>")
        if info:
            out.append(f"<p>Best combination: <b>{esc(' + '.join(info.get('best', [])) or 'none')}</b>.</p>"
                       "<details><summary>why (the rule per compensator)</summary><ul>"
                       + "".join(f"<li>{esc(w)}</li>" for w in info.get("rule", [])) + "</ul></details>")
        header = ["row", "components"] + [f"{cmp['figures'][k].get('short') or k} ({cmp['figures'][k]['unit']})"
                                          for k in keys]
        rows, cls = [], []
        for n in names:
            d = cmp["controllers"][n]
            row: list[Any] = [n, ", ".join(d.get("components", [])) or "none"]
            c = ["", ""]
            for k in keys:
                f = cmp["figures"][k]
                v = f["values"].get(n)
                r = f.get("ratio_to_pid", {}).get(n)
                txt = fmt(v) + ("" if r is None or n == base else f" ({r:.3g}x)")
                row.append(txt)
                good = None
                if r is not None and n != base:
                    better = r < 0.99 if f.get("lower_is_better", True) else r > 1.01
                    worse = r > 1.01 if f.get("lower_is_better", True) else r < 0.99
                    good = "better" if better else ("worse" if worse else None)
                c.append(good or "")
            rows.append(row)
            cls.append(c)
        out.append(table(header, rows, cls))
    return "\n".join(out)


def _controllers_section(cmp: Mapping[str, Any]) -> str:
    rows = []
    for n, d in cmp["controllers"].items():
        fails = "; ".join(f"{p}: {' '.join(x)}" for p, x in d.get("failures", {}).items())
        rows.append([n, ", ".join(d.get("compensators", [])) or "none",
                     ", ".join(f"{k} = {fmt(v)}" for k, v in d.get("gains", {}).items()) or "drive defaults",
                     d.get("description", ""), fails or "-"])
    c = cmp.get("conditions", {})
    cond = table(["condition", "value"], [[k, v] for k, v in c.items()])
    return ("<h2>Controllers and conditions</h2>"
            + table(["controller", "compensators", "gains (table units)", "description", "failures"], rows) + cond)


def _test_doc_section(doc: Mapping[str, Any], base: Path, plots: Sequence[str], title: str, imgs: Images) -> str:
    """Every procedure of an ``hdservo-test`` document: headline, figures, conditions, notes, plots."""
    out = [f"<h2>{esc(title)}</h2>"]
    by_stem = {Path(p).stem: p for p in plots}
    shown: set[str] = set()
    for name, r in doc.get("results", {}).items():
        out.append(f"<h3>{esc(title.split(':')[0])} &mdash; {esc(name)}</h3>")
        if r.get("headline"):
            out.append(table(["headline figure", "value"], [[k, v] for k, v in r["headline"].items()]))
        for n in r.get("notes", []):
            cls = "fail" if n.startswith("failed:") else "note"
            out.append(f'<p class="{cls}">{esc(n)}</p>')
        flat = [(k, v) for k, v in flatten(r.get("figures", {})) if not (isinstance(v, list) and len(v) > 24)]
        if flat:
            out.append("<details><summary>measured figures</summary>"
                       + table(["figure", "value"], [[k, v] for k, v in flat]) + "</details>")
        if r.get("conditions"):
            out.append("<details><summary>conditions</summary>"
                       + table(["condition", "value"], [[k, v] for k, v in flatten(r["conditions"])]) + "</details>")
        for stem, rel in sorted(by_stem.items()):
            if stem == name or stem.startswith(name + "_"):
                out.append(imgs.figure(base / rel, f"{title.split(':')[0]}: {stem}", rel))
                shown.add(stem)
    rest = [s for s in sorted(by_stem) if s not in shown]
    if rest:                                      # plots not named after a procedure: still every plot
        out.append(f"<h3>{esc(title.split(':')[0])} &mdash; further plots</h3>")
        out += [imgs.figure(base / by_stem[s], f"{title.split(':')[0]}: {s}", by_stem[s]) for s in rest]
    return "\n".join(out)


def _identify_section(ident: Mapping[str, Any], ident_path: Path, imgs: Images) -> str:
    out = ["<h2>Identification</h2>", f"<p>Source: {esc(ident.get('source', '?'))}; target "
           f"{esc(ident.get('target', '?'))}.</p>"]
    res = ident.get("results", {})
    rows = [[k, v] for k, v in flatten(res) if not (isinstance(v, list) and len(v) > 24)]
    if rows:
        out.append(table(["identified quantity (SI units in the names)", "value"], rows))
    for n in ident.get("notes", []):
        out.append(f'<p class="note">{esc(n)}</p>')
    for p in ident.get("plots", []):
        pp = Path(p)
        path = pp if pp.is_absolute() or pp.exists() else ident_path.parent / pp
        for alt in (ident_path.parent / pp.parent.name / pp.name, ident_path.parent / pp.name):
            if not path.exists() and alt.exists():
                path = alt
        out.append(imgs.figure(path, f"identification: {pp.stem}", str(p)))
    return "\n".join(out)


def _download_section(dl: Mapping[str, Any]) -> str:
    rows = [["parameters written and read back", dl.get("params_written")],
            ["tables (0x5100 subs)", dl.get("tables")], ["Preisach file", dl.get("preisach_file")],
            ["cb_enable", dl.get("cb_enable")], ["notes", "; ".join(dl.get("notes", [])) or "-"]]
    return "<h2>Download to the drive</h2>" + table(["item", "value"], rows)


# ------------------------------------------------------------------------------------ build

def build_report(out: Path, compare: Optional[Path] = None, tests: Sequence[Path] = (),
                 test_plots: Sequence[Path] = (), identify: Optional[Path] = None,
                 download: Optional[Path] = None, title: str = "hdservo report",
                 summary_lines: Sequence[str] = ()) -> dict[str, Any]:
    """Write the HTML report to ``out`` (atomically); returns ``{"path", "plots", "bytes"}``.

    Parameters
    ----------
    out : Path
        The HTML file.
    compare : Path, optional
        ``hdservo-compare`` JSON (plots and per-controller JSON relative to it).
    tests : sequence of Path
        ``hdservo-test`` JSON documents (used when there is no ``compare``, or in addition).
    test_plots : sequence of Path
        Plot directories of ``tests`` (same order; every PNG named after a procedure is embedded).
    identify, download : Path, optional
        ``hdservo identify --json`` / ``hdservo download --json`` records.
    title : str
        Page title.
    summary_lines : sequence of str
        Extra lines shown at the top (e.g. the demo's run time).

    Raises
    ------
    ReportError
        Any bad input (missing/corrupt JSON or plot); nothing is written then.
    """
    if compare is None and not tests:
        raise ReportError("nothing to report: give an hdservo-compare JSON or hdservo-test JSON files")
    imgs = Images(out.parent)
    body: list[str] = [f"<h1>{esc(title)}</h1>",
                       f"<p class=\"note\">Generated {esc(_dt.datetime.now().strftime('%Y-%m-%d %H:%M'))} by "
                       "<code>hdservo report</code>. Angles in arcsec (1&Prime; = 1/3600 deg), rates in deg/s, "
                       "torques in N.m, frequencies in Hz.</p>"]
    for s in summary_lines:
        body.append(f"<p>{esc(s)}</p>")
    if compare is not None:
        cmp = load_json(compare, ["hdservo-compare"])
        for k in ("controllers", "figures", "reference", "best"):
            if k not in cmp:
                raise ReportError(f"{compare}: no '{k}' (not written by hdservo compare)")
        base = compare.parent
        body.append(_headline_section(cmp))
        body.append(_ablation_section(cmp))
        if cmp.get("comparison_plots"):
            body.append("<h2>Comparison charts</h2>")
            for rel in cmp["comparison_plots"]:
                body.append(imgs.figure(base / rel, f"comparison: {Path(rel).stem}", rel))
        body.append(_controllers_section(cmp))
    if identify is not None:
        body.append(_identify_section(load_json(identify), identify, imgs))
    if download is not None:
        body.append(_download_section(load_json(download)))
    if compare is not None:
        for name, d in cmp["controllers"].items():
            tpath = base / d["json"]
            tdoc = load_json(tpath, ["hdservo-test"])
            body.append(_test_doc_section(tdoc, base, d.get("plots", []), f"{name}: {d.get('description', '')}",
                                          imgs))
    for i, tp in enumerate(tests):
        tdoc = load_json(tp, ["hdservo-test"])
        pdir = test_plots[i] if i < len(test_plots) else None
        plots: list[str] = []
        base_t = tp.parent
        if pdir is not None:
            if not pdir.is_dir():
                raise ReportError(f"{pdir}: plot directory not found")
            base_t = pdir
            plots = sorted(p.name for p in pdir.glob("*.png"))
        label = ", ".join(tdoc.get("compensators") or []) or "PID"
        body.append(_test_doc_section(tdoc, base_t, plots, f"{tp.stem}: {label} ({tdoc.get('target', '')})", imgs))
    page = ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{esc(title)}</title><style>{CSS}</style></head><body>\n" + "\n".join(body)
            + "\n</body></html>\n")
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out, page)
    return {"path": out, "plots": [str(p) for p in imgs.used], "bytes": len(page.encode("utf-8"))}


class _ImgParser(html.parser.HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.imgs: list[dict[str, str]] = []
        self.external: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, Optional[str]]]) -> None:
        a = {k: v or "" for k, v in attrs}
        if tag == "img":
            self.imgs.append(a)
        if tag in ("script", "link", "iframe", "object", "embed"):
            self.external.append(f"<{tag}>")
        for k in ("src", "href"):
            if k in a and not a[k].startswith(("data:", "#")):
                self.external.append(f"{k}={a[k]}")


def verify_report(path: Path) -> list[Path]:
    """Check a written report: self-contained, every ``<img>`` a PNG data URI whose plot file exists
    (``data-source``, relative to the HTML), holds a drawing and has the same bytes; returns the plot files.

    Raises
    ------
    ReportError
        The first problem found.
    """
    if not path.is_file():
        raise ReportError(f"{path}: no such file")
    p = _ImgParser()
    p.feed(path.read_text(encoding="utf-8"))
    if p.external:
        raise ReportError(f"{path}: refers to something outside the file ({p.external[0]})")
    files = []
    prefix = "data:image/png;base64,"
    for img in p.imgs:
        src = img.get("data-source", "")
        f = path.parent / src
        if not src or not img.get("src", "").startswith(prefix):
            raise ReportError(f"{path}: an image without a PNG data URI or data-source ({src or '?'})")
        check_png(f)
        if base64.b64decode(img["src"][len(prefix):]) != f.read_bytes():
            raise ReportError(f"{path}: embedded image differs from {f}")
        files.append(f)
    return files


__all__ = ["ReportError", "build_report", "check_png", "load_json", "verify_report"]
