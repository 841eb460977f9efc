"""``hdservo report``: one self-contained HTML file from a small synthetic compare run (JSON + PNGs).

Checks that the page parses, holds the headline table with the targets marked,
embeds every plot (each ``<img>`` is a data URI whose bytes are the plot file,
which exists and holds a drawing), references nothing external, and that bad
input (a missing or blank plot, broken JSON) is one error line, exit 2 and no
output file.
"""
from __future__ import annotations

import base64
import html.parser
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hdservo import compare as cmp
from hdservo.cli import main
from hdservo.procedures.results import Result, figure, save_figure, write_json
from hdservo.report import ReportError, check_png, verify_report

#: synthetic headline figures: (pid, best)
VALUES = {"min_smooth_rate_deg_s": (0.01, 0.001), "positioning_accuracy_arcsec": (12.0, 4.0),
          "repeatability_arcsec": (2.7, 1.5), "stabilisation_rms_arcsec": (1200.0, 15.0), "bandwidth_hz": (8.6, 9.0),
          "peak_torque_Nm": (60.8, 60.8)}


def _plot(d: Path, stem: str, k: float) -> Path:
    fig, ax = figure(size=(3.0, 2.0))
    a = ax[0][0]
    x = np.linspace(0, 1, 50)
    a.plot(x, np.sin(2 * np.pi * k * x))
    a.set_xlabel("time (s)")
    a.set_ylabel("error (arcsec)")
    return save_figure(fig, d, stem)[0]


def _compare_dir(tmp: Path) -> Path:
    """A compare output as hdservo.compare writes it: two controllers, two procedures each, plots."""
    out = tmp / "cmp"
    ctl: dict[str, Any] = {}
    for i, name in enumerate(("pid", "best")):
        results = []
        plots = []
        for proc, keys in (("positioning", ("positioning_accuracy_arcsec", "repeatability_arcsec")),
                           ("stabilisation", ("stabilisation_rms_arcsec",))):
            r = Result(proc, headline={k: VALUES[k][i] for k in keys}, figures={"runs": 5, "f_Hz": [1.0, 2.0],
                                                                       "per_target": {"10": {"A_arcsec": 1.5}}},
                       conditions={"setup": "axis"}, notes=[f"note of {name}/{proc}"])
            results.append(r)
            plots.append(str(_plot(out / name / "plots", proc, 1 + i).relative_to(out)))
        write_json(out / name / "test.json", results, {"target": "synthetic", "compensators": []})
        head = {k: v for r in results for k, v in r.headline.items()}
        head.update({k: VALUES[k][i] for k in ("min_smooth_rate_deg_s", "bandwidth_hz", "peak_torque_Nm")})
        ctl[name] = {"name": name, "compensators": [] if name == "pid" else ["lugre"], "gains": {},
                     "feedback": "full-closed", "components": [] if name == "pid" else ["lugre"],
                     "description": f"{name} controller", "headline": head, "json": f"{name}/test.json",
                     "plots": plots, "failures": {}}
    figs = {}
    for f in cmp.FIGURES:
        vals = {c: d["headline"].get(f.key) for c, d in ctl.items()}
        figs[f.key] = {"label": f.label, "short": f.short, "unit": f.unit, "lower_is_better": f.lower_is_better,
                       "target": f.target, "target_text": f.target_text(), "values": vals,
                       "meets_target": {c: f.meets(v) for c, v in vals.items()},
                       "vs_pid": {"best": f.verdict(vals["best"], vals["pid"])}}
    doc: dict[str, Any] = {"format": "hdservo-compare", "version": 1, "reference": "pid", "best": "best",
                           "conditions": {"target": "synthetic"}, "controllers": ctl, "figures": figs}
    doc["comparison_plots"] = [str(p.relative_to(out)) for p in cmp.comparison_plots(doc, out / "plots")]
    doc["verdict"] = cmp.verdict(doc)
    (out / "compare.json").write_text(json.dumps(doc))
    return out


class _Page(html.parser.HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.imgs: list[dict[str, str]] = []
        self.tags: list[str] = []
        self.cells: list[str] = []
        self._in_td = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append(tag)
        a = {k: v or "" for k, v in attrs}
        if tag == "img":
            self.imgs.append(a)
        for k in ("href", "src"):
            if k in a and not a[k].startswith(("data:", "#")):
                raise AssertionError(f"external reference {k}={a[k]!r}")
        self._in_td = tag == "td"
        if self._in_td:
            self.cells.append("")

    def handle_endtag(self, tag: str) -> None:
        if tag == "td":
            self._in_td = False

    def handle_data(self, data: str) -> None:
        if self._in_td:
            self.cells[-1] += data


def test_report_is_self_contained_and_embeds_every_plot(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = _compare_dir(tmp_path)
    page_path = tmp_path / "report.html"
    assert main([ "report", str(out / "compare.json"), "-o", str(page_path)]) == 0
    text = page_path.read_text()
    p = _Page()
    p.feed(text)
    assert text.startswith("<!DOCTYPE html>") and "</html>" in text
    assert "script" not in p.tags and "link" not in p.tags
    # every plot on disk is in the page, once, with the same bytes; each holds a drawing
    on_disk = sorted(str(q.relative_to(tmp_path)) for q in out.rglob("*.png"))
    # 2 controllers x 2 procedures + one chart per headline figure + the ablation chart
    assert len(on_disk) == 4 + len(cmp.FIGURES) + 1
    sources = sorted(i["data-source"] for i in p.imgs)       # relative to the HTML file
    assert sources == on_disk
    assert sorted(verify_report(page_path)) == sorted(tmp_path / s for s in on_disk)
    for img in p.imgs:
        f = tmp_path / img["data-source"]
        assert f.is_file() and f.stat().st_size > 1000
        prefix = "data:image/png;base64,"
        assert img["src"].startswith(prefix)
        assert base64.b64decode(img["src"][len(prefix):]) == f.read_bytes()
        w, h = check_png(f)
        assert (int(img["width"]), int(img["height"])) == (w, h)
    # headline table: values, targets, met / not met, verdict
    cells = [c.strip() for c in p.cells]
    assert "<= 20 arcsec" in cells and "<= 0.001 deg/s" in cells
    assert "1200 \u2717" in cells and "15 \u2713" in cells          # stabilisation: PID misses, best meets
    assert "2.7 \u2717" in cells and "1.5 \u2713" in cells
    assert text.count('class="better"') >= 4 and 'class="same"' in text   # peak torque: same
    assert "note of best/stabilisation" in text
    assert "wrote" in capsys.readouterr().out


def test_report_of_a_single_test_run(tmp_path: Path) -> None:
    out = _compare_dir(tmp_path)
    page = tmp_path / "one.html"
    assert main(["report", "--test", str(out / "pid" / "test.json"), "--test-plots", str(out / "pid" / "plots"),
                 "-o", str(page)]) == 0
    p = _Page()
    p.feed(page.read_text())
    assert sorted(Path(i["data-source"]).name for i in p.imgs) == ["positioning.png", "stabilisation.png"]


@pytest.mark.parametrize("damage", ["missing", "blank", "not_png", "bad_json"])
def test_bad_input_is_one_line_and_no_output(tmp_path: Path, capsys: pytest.CaptureFixture, damage: str) -> None:
    out = _compare_dir(tmp_path)
    victim = out / "best" / "plots" / "stabilisation.png"
    if damage == "missing":
        victim.unlink()
    elif damage == "blank":
        fig, _ = figure(size=(3.0, 2.0))
        fig.patch.set_facecolor("white")
        fig.axes[0].set_axis_off()
        save_figure(fig, victim.parent, victim.stem)
    elif damage == "not_png":
        victim.write_bytes(b"GIF89a not a png at all" * 10)
    else:
        (out / "compare.json").write_text('{"format": "hdservo-compare",\n "controllers": [1, }')
    page = tmp_path / "report.html"
    capsys.readouterr()
    assert main(["report", str(out / "compare.json"), "-o", str(page)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("hdservo report: error:")
    assert ("compare.json" if damage == "bad_json" else "stabilisation.png") in err[0]
    if damage == "bad_json":
        assert "line 2" in err[0]
    assert not page.exists()
    assert not list(tmp_path.glob(".report.html.*"))


def test_verify_report_finds_a_changed_plot(tmp_path: Path) -> None:
    out = _compare_dir(tmp_path)
    page = tmp_path / "report.html"
    assert main(["report", str(out / "compare.json"), "-o", str(page)]) == 0
    _plot(out / "pid" / "plots", "positioning", 7.0)          # redrawn after the report was written
    with pytest.raises(ReportError, match="differs"):
        verify_report(page)


def test_check_png_rejects_blank_and_accepts_a_plot(tmp_path: Path) -> None:
    good = _plot(tmp_path, "good", 1.0)
    assert check_png(good)[0] > 100
    import matplotlib.image as mpimg
    blank = tmp_path / "blank.png"
    mpimg.imsave(blank, np.ones((50, 80, 3)))
    with pytest.raises(ReportError, match="blank"):
        check_png(blank)


class _Structure(html.parser.HTMLParser):
    """Anchors, contents links, figures with their captions, and the text of every table cell."""

    def __init__(self) -> None:
        super().__init__()
        self.ids: list[str] = []
        self.links: list[str] = []
        self.figures: list[dict[str, str]] = []
        self.headings: list[str] = []
        self.cells: list[str] = []
        self._where: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = {k: v or "" for k, v in attrs}
        if "id" in a:
            self.ids.append(a["id"])
        if tag == "a" and a.get("href", "").startswith("#"):
            self.links.append(a["href"][1:])
        if tag == "figure":
            self.figures.append({"caption": "", "alt": ""})
        if tag == "img" and self.figures:
            self.figures[-1]["alt"] = a.get("alt", "")
        if tag in ("td", "th", "figcaption", "h2", "h3"):
            self._where.append(tag)
            if tag in ("td", "th"):
                self.cells.append("")
            if tag in ("h2", "h3"):
                self.headings.append("")

    def handle_endtag(self, tag: str) -> None:
        if self._where and self._where[-1] == tag:
            self._where.pop()

    def handle_data(self, data: str) -> None:
        if not self._where:
            return
        if self._where[-1] in ("td", "th"):
            self.cells[-1] += data
        elif self._where[-1] == "figcaption":
            self.figures[-1]["caption"] += data
        else:
            self.headings[-1] += data


def test_report_has_contents_captions_titles_and_readable_tables(tmp_path: Path) -> None:
    out = _compare_dir(tmp_path)
    page = tmp_path / "report.html"
    assert main(["report", str(out / "compare.json"), "-o", str(page)]) == 0
    s = _Structure()
    s.feed(page.read_text())
    # a table of contents whose every link lands on an anchor of the page, and every section is listed
    assert len(s.links) >= 8
    assert set(s.links) <= set(s.ids), set(s.links) - set(s.ids)
    assert len(s.ids) == len(set(s.ids))                                  # anchors are unique
    assert {"headline-figures", "controllers-and-conditions"} <= set(s.links)
    # every figure has a caption that says what the plot shows (more than its file name)
    assert len(s.figures) == 4 + len(cmp.FIGURES) + 1
    for f in s.figures:
        words = f["caption"].split("(")[0].split()
        assert len(words) >= 5, f["caption"]
        assert f["alt"].strip()
    caps = " ".join(f["caption"] for f in s.figures)
    assert "positional deviation at each target" in caps.lower()
    # section titles name the controller and its feedback configuration
    assert any(h.startswith("best: PID + lugre, full-closed feedback") for h in s.headings), s.headings
    assert any(h.startswith("pid: PID alone, full-closed feedback") for h in s.headings), s.headings
    # tables: readable labels, no raw dotted or snake_case keys
    import re
    raw_key = re.compile(r"\b[a-z]\w+\.\w+|\b[a-z]+_[A-Za-z_]+\b")      # per_target.10, A_arcsec (not N.m)
    offenders = [c for c in s.cells if raw_key.search(c)]
    assert offenders == []
    assert "per target / 10 / A [arcsec]" in s.cells
    assert "positioning accuracy [arcsec]" in s.cells
