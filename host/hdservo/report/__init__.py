"""One self-contained HTML report from the JSON and plots of ``hdservo compare`` / ``test`` / ``identify``.

:func:`build_report` reads

* an ``hdservo-compare`` document (``OUT/compare.json``; its paths are relative to it)
  or one or more ``hdservo-test`` documents (``hdservo test --json``, with ``plots`` dirs),
* optionally the ``hdservo identify --json`` report (its plot list) and the
  ``hdservo download --json`` record,

and writes one HTML file, built by :class:`hdservo.report.builder.Document`: a
table of contents linking to every section, tables of every headline figure
(targets of docs/reference-axis.md marked met / not met, verdict against the
fair PID), each procedure's conditions, figures and notes under a title naming
the controller and its feedback configuration, and every plot embedded as a
base64 PNG data URI (no external file, script or style sheet) with a caption
saying what it shows (:data:`PLOT_CAPTIONS`).  Every plot is
checked before it is embedded: it must exist, be a PNG and not be blank
(:func:`check_png`); the ``<img>`` keeps the source path in ``data-source``.

Bad input raises :class:`ReportError` (one line naming the file) and leaves no output.
"""
from __future__ import annotations

import base64
import datetime as _dt
import html.parser
import json
import os
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

import numpy as np

from ..fileio import write_text_atomic
from ..plotting import pyplot
from .builder import Document, Para, Raw, Table, esc, fmt, quantity_rows, readable

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
figcaption{font-size:.85em;color:#555}nav.toc{background:#f6f7fa;border:1px solid #dde;padding:.2em 1em;margin:1em 0}
nav.toc h2{margin-top:.4em;border:0;font-size:1.1em}nav.toc ul{margin:.2em 0}.note{color:#555;font-size:.9em}.fail{color:#b02020}
code{background:#f3f3f3;padding:0 .2em}
"""


#: What each plot shows, by file stem (procedure plots are named after the procedure).
PLOT_CAPTIONS: dict[str, str] = {
    "min-rate": "window rate over commanded rate in each fixed-angle window, one line per rung of the rate "
                "ladder (smooth motion stays near 1)",
    "stabilisation": "inertial pointing error over time while the base moves",
    "positioning": "positional deviation at each target, every run (A and R in the title)",
    "peak-torque": "output torque against the commanded output torque, up to the drive's torque limit",
    "bandwidth": "closed-loop response theta_L / theta_ref, magnitude and phase against frequency "
                 "(the bandwidth is the -3 dB frequency)",
    "tracking": "tracking error over time, one panel per sinusoidal rate",
    "settling": "output minus target after each move's reference arrives, with the settling band",
    "frf": "frequency response from motor torque to motor angle against frequency",
    "stiffness": "torque against output twist with the output locked (torsional stiffness), with the fit "
                 "where one was made",
    "hysteresis": "gear torque against output twist over full torque cycles (hysteresis loop)",
    "lost-motion": "gear torque against output twist around zero torque (lost motion)",
    "starting-torque": "motor rotation against the input torque command steps (starting torque)",
    "transmission": "transmission error against output angle over the revolutions",
    "friction_stribeck": "friction torque against velocity with the fitted Stribeck curve, and the fit residual",
    "presliding": "input friction against motor angle with the LuGre presliding fit, and the residual",
    "te": "transmission error against wave-generator angle with the fitted harmonics, and the residual",
    "preisach_minor_loops": "minor hysteresis loops not used in the fit: measured and predicted by the "
                            "Preisach model, and the error",
}


def plot_caption(stem: str, who: str = "") -> str:
    """What the plot ``stem`` shows, followed by who measured it (``who``: controller and configuration)."""
    if stem.startswith("compare_"):
        what = f"{readable(stem[len('compare_'):])} of every controller row, with its target"
    elif stem.startswith("ablation_"):
        what = (f"ablation, {stem[len('ablation_'):]} feedback: each row's value over the fair PID's value, "
                "per figure (green better, red worse)")
    else:
        base = next((k for k in sorted(PLOT_CAPTIONS, key=len, reverse=True)
                     if stem == k or stem.startswith(k + "_")), None)
        what = PLOT_CAPTIONS[base] if base else f"{readable(stem)} (plot of this run)"
        if base and stem != base:
            what += f" ({readable(stem[len(base) + 1:])})"
    what = what[0].upper() + what[1:]
    return f"{what}. {who}." if who else f"{what}."


class Images:
    """Embeds checked PNGs as report figures; remembers every file used (``used``).

    Parameters
    ----------
    base : Path
        Directory of the HTML file: ``data-source`` paths are relative to it.
    """

    def __init__(self, base: Path) -> None:
        self.used: list[Path] = []
        self.base = base

    def add(self, doc: Document, path: Path, caption: str) -> None:
        """Add the PNG at ``path`` (after :func:`check_png`) to ``doc`` as a data-URI figure."""
        w, h = check_png(path)
        rel = os.path.relpath(path.resolve(), self.base.resolve())
        b64 = base64.b64encode(path.read_bytes()).decode("ascii")
        self.used.append(path)
        doc.figure(f"data:image/png;base64,{b64}", caption, source=rel, width=w, height=h)


def controller_title(name: str, d: Mapping[str, Any]) -> str:
    """``name``: the controller (compensators, or the PID alone) and its feedback configuration."""
    comps = list(d.get("components") or d.get("compensators") or [])
    ctl = "PID + " + " + ".join(comps) if comps else "PID alone"
    fb = d.get("feedback", "full-closed")
    return f"{name}: {ctl}, {fb} feedback"


# ------------------------------------------------------------------------------------ sections

def _headline_section(doc: Document, cmp: Mapping[str, Any]) -> None:
    ref, best = cmp["reference"], cmp["best"]
    names = list(cmp["controllers"])
    header = (["figure", "unit", "target"] + names + ([f"{best} vs {ref}"] if best != ref else [])
              + ["best measured"])
    rows, cls = [], []
    for key, f in cmp["figures"].items():
        row: list[Any] = [f["label"], f["unit"], f["target_text"]]
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
    doc.heading("Headline figures")
    doc.para(Raw("Targets: the requirements of the reference axis. Green &#10003; = target met, red &#10007; = not "
                 "met; &lsquo;none&rsquo; = no value (e.g. no rung of the rate ladder was smooth, or the procedure "
                 f"failed). The verdict column compares <b>{esc(best)}</b> (the compensated axis) with "
                 f"<b>{esc(ref)}</b>; &lsquo;best measured&rsquo; names the controller with the best value of each "
                 "figure."))
    doc.table(header, rows, cls)
    if v.get("targets_met"):
        met = [k for k, ok in v["targets_met"].items() if ok]
        miss = [readable(k) for k, ok in v["targets_met"].items() if not ok]
        doc.para(Raw(f"<b>{esc(best)}</b>: {len(met)} of {len(v['targets_met'])} targets met"
                     + (f"; not met: {esc(', '.join(miss))}" if miss else "") + ". "
                     f"Better than {esc(ref)} on every figure: <b>{'yes' if v.get('better_everywhere') else 'no'}</b>"
                     f" (not worse anywhere: {'yes' if v.get('not_worse_anywhere') else 'no'})."))


def _ablation_rows(cmp: Mapping[str, Any], names: Sequence[str], base: str) -> tuple[list[list[Any]], list[list[str]]]:
    """Each row's value and ratio to ``base`` per figure, with better/worse classes."""
    rows, cls = [], []
    for n in names:
        d = cmp["controllers"][n]
        row: list[Any] = [n, ", ".join(d.get("components", [])) or "none"]
        c = ["", ""]
        for k, f in cmp["figures"].items():
            v = f["values"].get(n)
            r = f.get("ratio_to_pid", {}).get(n)
            row.append(fmt(v) + ("" if r is None or n == base else f" ({r:.3g}x)"))
            good = None
            if r is not None and n != base:
                better = r < 0.99 if f.get("lower_is_better", True) else r > 1.01
                worse = r > 1.01 if f.get("lower_is_better", True) else r < 0.99
                good = "better" if better else ("worse" if worse else None)
            c.append(good or "")
        rows.append(row)
        cls.append(c)
    return rows, cls


def _ablation_section(doc: Document, cmp: Mapping[str, Any]) -> None:
    """Per feedback configuration: every row's value and ratio to the fair PID of that configuration, per figure."""
    fbs: list[str] = []
    for d in cmp["controllers"].values():
        if d.get("feedback", "full-closed") not in fbs:
            fbs.append(d.get("feedback", "full-closed"))
    ab = cmp.get("ablation", {})
    doc.heading("Ablation: each row against the fair PID")
    doc.para(Raw("Every row runs with the loop gains of the compensated set and the stabilisation in the gyro mode "
                 "(the fair PID); the ratio is the row's value over the fair PID's value in the same feedback "
                 "configuration (for the bandwidth and the peak torque higher is better, for every other figure "
                 "lower). Motion strategies (hold logic, one-direction final approach) are their own rows; "
                 "&lsquo;pid-hold&rsquo; is an extra row (the PID design gains in position hold), not a baseline."))
    if ab.get("rule"):
        doc.para(f"Rule: {ab['rule']}.")
    for fb in fbs:
        names = [n for n, d in cmp["controllers"].items() if d.get("feedback", "full-closed") == fb]
        base = "pid" if fb == "full-closed" else f"pid@{fb}"
        info = ab.get("feedbacks", {}).get(fb, {})
        doc.heading(f"Ablation, {fb} feedback", level=3)
        if info:
            doc.para(Raw(f"Best combination: <b>{esc(' + '.join(info.get('best', [])) or 'none')}</b>."))
            doc.details("why (the forward selection step by step, and each part left out)",
                        [Para(w) for w in info.get("rule", [])])
        header = ["row", "components"] + [f"{f.get('short') or f['label']} ({f['unit']})"
                                          for f in cmp["figures"].values()]
        rows, cls = _ablation_rows(cmp, names, base)
        doc.table(header, rows, cls)


def _controllers_section(doc: Document, cmp: Mapping[str, Any]) -> None:
    rows = []
    for n, d in cmp["controllers"].items():
        fails = "; ".join(f"{p}: {' '.join(x)}" for p, x in d.get("failures", {}).items())
        rows.append([n, ", ".join(d.get("compensators", [])) or "none", d.get("feedback", "full-closed"),
                     ", ".join(f"{k} = {fmt(v)}" for k, v in d.get("gains", {}).items()) or "drive defaults",
                     d.get("description", ""), fails or "-"])
    doc.heading("Controllers and conditions")
    doc.table(["controller", "compensators", "feedback", "gains (table units)", "description", "failures"], rows)
    doc.table(["condition", "value"], quantity_rows(cmp.get("conditions", {})))


def _test_doc_section(doc: Document, tdoc: Mapping[str, Any], base: Path, plots: Sequence[str], title: str,
                      imgs: Images) -> None:
    """Every procedure of an ``hdservo-test`` document: headline, figures, conditions, notes, plots."""
    doc.heading(title)
    who = title.split(":")[0]
    by_stem = {Path(p).stem: p for p in plots}
    shown: set[str] = set()
    for name, r in tdoc.get("results", {}).items():
        doc.heading(f"{who}: {name}", level=3)
        if r.get("headline"):
            doc.table(["headline figure", "value"], quantity_rows(r["headline"]))
        for n in r.get("notes", []):
            doc.para(n, "fail" if n.startswith("failed:") else "note")
        flat = quantity_rows(r.get("figures", {}))
        if flat:
            doc.details("measured figures", [Table(["figure", "value"], flat)])
        if r.get("conditions"):
            doc.details("conditions", [Table(["condition", "value"], quantity_rows(r["conditions"]))])
        for stem, rel in sorted(by_stem.items()):
            if stem == name or stem.startswith(name + "_"):
                imgs.add(doc, base / rel, plot_caption(stem, title))
                shown.add(stem)
    rest = [s for s in sorted(by_stem) if s not in shown]
    if rest:                                      # plots not named after a procedure: still every plot
        doc.heading(f"{who}: further plots", level=3)
        for s in rest:
            imgs.add(doc, base / by_stem[s], plot_caption(s, title))


def _identify_section(doc: Document, ident: Mapping[str, Any], ident_path: Path, imgs: Images) -> None:
    doc.heading("Identification")
    doc.para(f"Source: {ident.get('source', '?')}; target {ident.get('target', '?')}.")
    rows = quantity_rows(ident.get("results", {}))
    if rows:
        doc.table(["identified quantity", "value"], rows)
    for n in ident.get("notes", []):
        doc.para(n, "note")
    for p in ident.get("plots", []):
        pp = Path(p)
        path = pp if pp.is_absolute() or pp.exists() else ident_path.parent / pp
        for alt in (ident_path.parent / pp.parent.name / pp.name, ident_path.parent / pp.name):
            if not path.exists() and alt.exists():
                path = alt
        imgs.add(doc, path, plot_caption(pp.stem, f"identification of {ident.get('target', 'the axis')}"))


def _download_section(doc: Document, dl: Mapping[str, Any]) -> None:
    rows = [["parameters written and read back", dl.get("params_written")],
            ["tables (0x5100 subs)", dl.get("tables")], ["Preisach file", dl.get("preisach_file")],
            ["compensators enabled (cb_enable)", dl.get("cb_enable")], ["notes", "; ".join(dl.get("notes", [])) or "-"]]
    doc.heading("Download to the drive")
    doc.table(["item", "value"], rows)


def _compare_sections(doc: Document, compare: Path, imgs: Images) -> dict[str, Any]:
    """The headline, ablation, comparison charts and controllers of an ``hdservo-compare`` document."""
    cmp = load_json(compare, ["hdservo-compare"])
    for k in ("controllers", "figures", "reference", "best"):
        if k not in cmp:
            raise ReportError(f"{compare}: no '{k}' (not written by hdservo compare)")
    _headline_section(doc, cmp)
    _ablation_section(doc, cmp)
    if cmp.get("comparison_plots"):
        doc.heading("Comparison charts")
        for rel in cmp["comparison_plots"]:
            imgs.add(doc, compare.parent / rel, plot_caption(Path(rel).stem))
    _controllers_section(doc, cmp)
    return cmp


def _test_sections(doc: Document, tests: Sequence[Path], test_plots: Sequence[Path], imgs: Images) -> None:
    """One section per ``hdservo-test`` document given on its own."""
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
        title = controller_title(tp.stem, tdoc)
        if tdoc.get("target"):
            title += f" ({tdoc['target']})"
        _test_doc_section(doc, tdoc, base_t, plots, title, imgs)


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
    doc = Document(title)
    intro: list[Any] = [Raw(f"Generated {esc(_dt.datetime.now().strftime('%Y-%m-%d %H:%M'))} by "
                            "<code>hdservo report</code>. Angles in arcsec (1&Prime; = 1/3600 deg), rates in deg/s, "
                            "torques in N.m, frequencies in Hz."), *summary_lines]
    cmp = _compare_sections(doc, compare, imgs) if compare is not None else None
    if identify is not None:
        _identify_section(doc, load_json(identify), identify, imgs)
    if download is not None:
        _download_section(doc, load_json(download))
    if cmp is not None and compare is not None:
        for name, d in cmp["controllers"].items():
            tdoc = load_json(compare.parent / d["json"], ["hdservo-test"])
            title_c = controller_title(name, d) + (f" ({d['description']})" if d.get("description") else "")
            _test_doc_section(doc, tdoc, compare.parent, d.get("plots", []), title_c, imgs)
    _test_sections(doc, tests, test_plots, imgs)
    page = doc.html(CSS, intro)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out, page)            # no half-written page; the user's umask
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


__all__ = ["PLOT_CAPTIONS", "ReportError", "build_report", "check_png", "controller_title", "load_json",
           "plot_caption", "verify_report"]
