"""The one report builder (hdservo.report.builder): anchors, contents, captions, readable keys."""
from __future__ import annotations

import re

import pytest

from hdservo.report.builder import Document, Raw, quantity_rows, readable


def _doc() -> Document:
    d = Document("Axis report")
    d.heading("Results")
    d.heading("Results", level=3)                      # the same title twice gets two anchors
    d.table(["quantity", "value"], quantity_rows({"positioning": {"A_arcsec": 1.5, "runs": 5}, "f_Hz": 2.0}))
    d.figure("plots/positioning.png", "Positional deviation at each target, every run")
    d.para(Raw("<b>bold</b> &amp; more"))
    return d


def test_readable_keys() -> None:
    assert readable("positioning_accuracy_arcsec") == "positioning accuracy [arcsec]"
    assert readable("per_target.10.A_arcsec") == "per target / 10 / A [arcsec]"
    assert readable("min_smooth_rate_deg_s") == "min smooth rate [deg/s]"
    assert readable("k1_Nm_per_rad") == "k1 [N.m/rad]"
    assert readable("max_accel_deg_s2") == "max accel [deg/s^2]"
    assert readable("stabilisation_arcsec_rms") == "stabilisation [arcsec RMS]"
    assert readable("s") == "s"                        # a lone unit-like word stays a word


def test_markdown_contents_link_to_anchors() -> None:
    md = _doc().markdown()
    links = re.findall(r"\]\(#([\w-]+)\)", md)
    anchors = re.findall(r'<a id="([\w-]+)"></a>', md)
    assert links == ["results", "results-2"] and anchors == links
    assert "| positioning / A [arcsec] | 1.5 |" in md
    assert "*Positional deviation at each target, every run*" in md
    assert "**bold** " not in md and "bold & more" in md           # trusted HTML becomes plain text


def test_html_contents_link_to_anchors() -> None:
    page = _doc().html()
    links = re.findall(r'href="#([\w-]+)"', page)
    ids = re.findall(r'id="([\w-]+)"', page)
    assert links == ["results", "results-2"] and set(links) <= set(ids)
    assert "<figcaption>Positional deviation at each target, every run</figcaption>" in page


def test_a_figure_without_caption_is_refused() -> None:
    with pytest.raises(ValueError, match="caption"):
        Document("x").figure("a.png", "  ")
