"""The one document builder of the package's reports: headings with anchors, a table of
contents, paragraphs, tables with readable row labels and captioned figures, rendered as
self-contained HTML or as Markdown.

A report is a :class:`Document`: blocks are added in reading order and every heading gets
a unique anchor, so the table of contents (written after the title) links to each section.
Figures always carry a caption that says what the plot shows.  Dotted keys of nested
result dicts (``per_target.10.A_arcsec``) are shown as readable labels
(``per target / 10 / A [arcsec]``, :func:`readable`).
"""
from __future__ import annotations

import html
import re
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, Optional, Sequence, Union

#: Key suffixes naming a unit (longest first): ``positioning_accuracy_arcsec`` -> ``[arcsec]``.
UNIT_SUFFIXES: tuple[tuple[str, str], ...] = (
    ("_Nm_per_rad", "N.m/rad"), ("_Nms_per_rad", "N.m.s/rad"), ("_kgm2", "kg.m^2"), ("_arcsec_rms", "arcsec RMS"),
    ("_deg_s2", "deg/s^2"), ("_deg_s", "deg/s"),
    ("_rad_s", "rad/s"), ("_Nm_s", "N.m/s"), ("_arcsec", "arcsec"), ("_arcmin", "arcmin"), ("_permille", "per mille"),
    ("_pct", "%"), ("_deg", "deg"), ("_rad", "rad"), ("_Nm", "N.m"), ("_Hz", "Hz"), ("_hz", "Hz"), ("_dB", "dB"),
    ("_db", "dB"), ("_ms", "ms"), ("_s", "s"),
)


def readable(key: str) -> str:
    """A result key as a reader's label: dots become `` / ``, underscores spaces, a unit suffix ``[unit]``.

    ``"positioning_accuracy_arcsec"`` -> ``"positioning accuracy [arcsec]"``;
    ``"per_target.10.A_arcsec"`` -> ``"per target / 10 / A [arcsec]"``.
    """
    parts = []
    for part in str(key).split("."):
        unit = ""
        for suffix, u in UNIT_SUFFIXES:
            if part.endswith(suffix) and len(part) > len(suffix):
                part, unit = part[: -len(suffix)], u
                break
        text = part.replace("_", " ").strip()
        parts.append(f"{text} [{unit}]" if unit else text)
    return " / ".join(parts)


def fmt(v: Any) -> str:
    """A value for a table cell: numbers to 4 significant digits, None -> ``none``, yes/no, short lists."""
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
        return "{" + ", ".join(f"{readable(k)}: {fmt(x)}" for k, x in list(v.items())[:8]) + \
            (", ..." if len(v) > 8 else "") + "}"
    return str(v)


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


def quantity_rows(d: Mapping[str, Any], skip_long: int = 24) -> list[list[Any]]:
    """``[[readable label, value], ...]`` of a nested result dict (lists longer than ``skip_long`` left out)."""
    return [[readable(k), v] for k, v in flatten(d) if not (isinstance(v, list) and len(v) > skip_long)]


def esc(x: Any) -> str:
    """HTML-escaped text of ``x``."""
    return html.escape(str(x), quote=True)


class Raw(str):
    """Trusted HTML inline text (not escaped in HTML; its tags are dropped in Markdown)."""


# ------------------------------------------------------------------------------------ blocks

@dataclass
class Heading:
    """A section title; ``anchor`` is its unique id."""

    level: int
    text: str
    anchor: str


@dataclass
class Para:
    """A paragraph (``kind``: ``""``, ``note`` or ``fail``)."""

    text: Union[str, Raw]
    kind: str = ""


@dataclass
class Table:
    """A table; ``classes`` per cell (HTML only: ``met``, ``better`` ...)."""

    header: Sequence[str]
    rows: list[Sequence[Any]]
    classes: Optional[list[Sequence[str]]] = None


@dataclass
class Figure:
    """A plot: ``src`` is what the page shows (a data URI or a relative path), ``caption`` what it shows."""

    src: str
    caption: str
    source: str = ""
    width: Optional[int] = None
    height: Optional[int] = None


@dataclass
class Details:
    """A collapsed group of blocks (HTML ``<details>``; a plain paragraph title in Markdown)."""

    summary: str
    blocks: list[Any] = field(default_factory=list)


Block = Union[Heading, Para, Table, Figure, Details]


def _slug(text: str) -> str:
    s = re.sub(r"[^a-z0-9]+", "-", str(text).lower()).strip("-")
    return s or "section"


class Document:
    """A report under construction (see the module docstring).

    Parameters
    ----------
    title : str
        The page title (the only level-1 heading).
    """

    def __init__(self, title: str) -> None:
        self.title = title
        self.blocks: list[Block] = []
        self._anchors: set[str] = set()

    def heading(self, text: str, level: int = 2) -> str:
        """Add a section title (level 2 or 3: listed in the contents); returns its anchor."""
        base = _slug(text)
        anchor, n = base, 2
        while anchor in self._anchors:
            anchor, n = f"{base}-{n}", n + 1
        self._anchors.add(anchor)
        self.blocks.append(Heading(level, text, anchor))
        return anchor

    def para(self, text: Union[str, Raw], kind: str = "") -> None:
        """Add a paragraph (plain text is escaped; :class:`Raw` is trusted HTML)."""
        self.blocks.append(Para(text, kind))

    def table(self, header: Sequence[str], rows: Iterable[Sequence[Any]],
              classes: Optional[Iterable[Sequence[str]]] = None) -> Table:
        """Add a table (cells formatted by :func:`fmt`; :class:`Raw` cells are trusted HTML)."""
        t = Table(list(header), [list(r) for r in rows], None if classes is None else [list(c) for c in classes])
        self.blocks.append(t)
        return t

    def figure(self, src: str, caption: str, source: str = "", width: Optional[int] = None,
               height: Optional[int] = None) -> Figure:
        """Add a plot with a caption that says what it shows (an empty caption is an error)."""
        if not caption.strip():
            raise ValueError(f"figure {source or src[:40]}: a figure needs a caption")
        f = Figure(src, caption, source, width, height)
        self.blocks.append(f)
        return f

    def details(self, summary: str, blocks: Sequence[Block]) -> None:
        """Add a collapsed group (e.g. the full measured figures of a procedure)."""
        self.blocks.append(Details(summary, list(blocks)))

    def contents(self) -> list[Heading]:
        """The headings listed in the table of contents (levels 2 and 3, in order)."""
        return [b for b in self.blocks if isinstance(b, Heading) and b.level in (2, 3)]

    # ---------------------------------------------------------------------------- HTML
    def html(self, css: str = "", intro: Sequence[Union[str, Raw]] = ()) -> str:
        """The whole page: title, ``intro`` paragraphs, the contents, then every block."""
        body = [f"<h1 id=\"top\">{esc(self.title)}</h1>"]
        body += [f"<p class=\"note\">{_inline_html(p)}</p>" for p in intro]
        body.append(self._toc_html())
        body += [_block_html(b) for b in self.blocks]
        return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
                f"<title>{esc(self.title)}</title><style>{css}</style></head><body>\n" + "\n".join(body)
                + "\n</body></html>\n")

    def _toc_html(self) -> str:
        out = ["<nav class=\"toc\"><h2 id=\"contents\">Contents</h2><ul>"]
        open_sub = False
        for h in self.contents():
            if h.level == 3 and not open_sub:
                out.append("<ul>")
                open_sub = True
            elif h.level == 2 and open_sub:
                out.append("</ul>")
                open_sub = False
            out.append(f"<li><a href=\"#{esc(h.anchor)}\">{esc(h.text)}</a></li>")
        if open_sub:
            out.append("</ul>")
        out.append("</ul></nav>")
        return "".join(out)

    # ---------------------------------------------------------------------------- Markdown
    def markdown(self, intro: Sequence[str] = ()) -> str:
        """The report as Markdown: title, ``intro``, the contents as links, then every block."""
        out = [f"# {self.title}", ""]
        for p in intro:
            out += [_inline_md(p), ""]
        out += ["## Contents", ""]
        for h in self.contents():
            out.append(("  " if h.level == 3 else "") + f"- [{h.text}](#{h.anchor})")
        out.append("")
        for b in self.blocks:
            out += _block_md(b)
        return "\n".join(out).rstrip("\n") + "\n"


def _inline_html(t: Union[str, Raw]) -> str:
    return str(t) if isinstance(t, Raw) else esc(t)


def _inline_md(t: Union[str, Raw]) -> str:
    return html.unescape(re.sub(r"<[^>]+>", "", str(t))) if isinstance(t, Raw) else str(t)


def _cell_html(c: Any) -> str:
    return str(c) if isinstance(c, Raw) else esc(fmt(c))


def _block_html(b: Block) -> str:
    if isinstance(b, Heading):
        return f"<h{b.level} id=\"{esc(b.anchor)}\">{esc(b.text)}</h{b.level}>"
    if isinstance(b, Para):
        cls = f" class=\"{b.kind}\"" if b.kind else ""
        return f"<p{cls}>{_inline_html(b.text)}</p>"
    if isinstance(b, Table):
        out = ["<table><thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in b.header) + "</tr></thead><tbody>"]
        for i, row in enumerate(b.rows):
            cells = []
            for j, c in enumerate(row):
                cl = ["num"] if isinstance(c, (int, float)) and not isinstance(c, bool) else []
                if b.classes is not None and b.classes[i][j]:
                    cl.append(b.classes[i][j])
                attr = f' class="{" ".join(cl)}"' if cl else ""
                cells.append(f"<td{attr}>{_cell_html(c)}</td>")
            out.append("<tr>" + "".join(cells) + "</tr>")
        out.append("</tbody></table>")
        return "\n".join(out)
    if isinstance(b, Figure):
        size = "" if b.width is None else f' width="{b.width}" height="{b.height}"'
        src = f" (<code>{esc(b.source)}</code>)" if b.source else ""
        data = f' data-source="{esc(b.source)}"' if b.source else ""
        return (f'<figure><img src="{esc(b.src)}"{size} alt="{esc(b.caption)}"{data}>'
                f"<figcaption>{esc(b.caption)}{src}</figcaption></figure>")
    if isinstance(b, Details):
        return (f"<details><summary>{esc(b.summary)}</summary>" + "\n".join(_block_html(x) for x in b.blocks)
                + "</details>")
    raise TypeError(f"not a report block: {type(b).__name__}")


def _cell_md(c: Any) -> str:
    text = _inline_md(c) if isinstance(c, Raw) else fmt(c)
    return text.replace("|", "\\|").replace("\n", " ")


def _block_md(b: Block) -> list[str]:
    if isinstance(b, Heading):
        return [f"{'#' * b.level} {b.text} <a id=\"{b.anchor}\"></a>", ""]
    if isinstance(b, Para):
        return [_inline_md(b.text), ""]
    if isinstance(b, Table):
        out = ["| " + " | ".join(b.header) + " |", "|" + "---|" * len(b.header)]
        out += ["| " + " | ".join(_cell_md(c) for c in row) + " |" for row in b.rows]
        return out + [""]
    if isinstance(b, Figure):
        return [f"![{b.caption}]({b.src})", "", f"*{b.caption}*", ""]
    if isinstance(b, Details):
        out = [f"**{b.summary}**", ""]
        for x in b.blocks:
            out += _block_md(x)
        return out
    raise TypeError(f"not a report block: {type(b).__name__}")


__all__ = ["Details", "Document", "Figure", "Heading", "Para", "Raw", "Table", "UNIT_SUFFIXES", "esc", "flatten",
           "fmt", "quantity_rows", "readable"]
