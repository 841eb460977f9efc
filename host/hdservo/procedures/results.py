"""Result records of the test procedures, their JSON form and plots.

Every procedure returns a :class:`Result`:

* ``headline`` - the figures later tools compare (``hdservo compare``/``report``):
  ``min_smooth_rate_deg_s``, ``positioning_accuracy_arcsec``,
  ``repeatability_arcsec``, ``stabilisation_rms_arcsec``, ``bandwidth_hz``,
  ``peak_torque_Nm`` and the gear figures (``k1_Nm_per_rad``,
  ``hysteresis_loss_arcmin``, ``lost_motion_arcmin``, ``starting_torque_Nm``,
  ``transmission_accuracy_arcmin``, ``resonance_hz``) where applicable;
* ``figures`` - everything else the procedure measured (JSON-able);
* ``series`` - arrays for the plots (not written to JSON);
* ``conditions`` - what ran: rig set-up, amplitudes, durations, pacing.

:func:`write_json` writes ``{"format": "hdservo-test", "version": 1, ...}``
through a temporary file (no half-written output).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Optional

from ..fileio import json_ready, save_figure_atomic, write_json_atomic
from ..plotting import pyplot

FORMAT = "hdservo-test"
VERSION = 1


@dataclass
class Result:
    """One procedure's outcome (see the module docstring)."""

    name: str
    headline: dict[str, Any] = field(default_factory=dict)
    figures: dict[str, Any] = field(default_factory=dict)
    conditions: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    series: dict[str, Any] = field(default_factory=dict)
    plot: Optional[Callable[["Result", Path, str], list[Path]]] = None
    #: who measured it (controller and feedback configuration): the plots' overall title when set
    label: str = ""

    def to_json(self) -> dict[str, Any]:
        """JSON-able dict (``series`` and ``plot`` left out)."""
        return {"procedure": self.name, "headline": json_ready(self.headline), "figures": json_ready(self.figures),
                "conditions": json_ready(self.conditions), "notes": list(self.notes)}

    def summary(self) -> str:
        """One human line per headline figure."""
        lines = [f"{self.name}:"]
        for k, v in self.headline.items():
            lines.append(f"  {k:32s} {_fmt(v)}")
        for n in self.notes:
            lines.append(f"  note: {n}")
        return "\n".join(lines)


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def write_json(path: "str | os.PathLike[str]", results: list[Result], meta: dict[str, Any]) -> Path:
    """Write all results (atomic, strict JSON: :func:`hdservo.fileio.write_json_atomic`)."""
    p = Path(path)
    doc = {"format": FORMAT, "version": VERSION, **json_ready(meta),
           "results": {r.name: r.to_json() for r in results},
           "headline": json_ready({k: v for r in results for k, v in r.headline.items()})}
    p.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(p, doc)
    return p


def save_figure(fig: Any, out_dir: Path, stem: str, fmt: str = "png", label: str = "") -> list[Path]:
    """Save a matplotlib figure as PNG (and PDF when fmt includes it) atomically; returns the paths.

    ``label`` (e.g. the controller and feedback configuration that measured it) becomes the
    figure's overall title.
    """
    plt = pyplot()
    out_dir.mkdir(parents=True, exist_ok=True)
    if label:
        fig.suptitle(label, fontsize=10, fontweight="bold")
        fig.tight_layout()
    paths = []
    for ext in ("png", "pdf") if fmt == "pdf" else ("png",):
        paths.append(save_figure_atomic(fig, out_dir / f"{stem}.{ext}", dpi=110))
    plt.close(fig)
    return paths


def figure(rows: int = 1, cols: int = 1, size: tuple[float, float] = (8.0, 5.0)) -> tuple[Any, Any]:
    """A matplotlib figure with the non-interactive backend."""
    return pyplot().subplots(rows, cols, figsize=size, squeeze=False)


__all__ = ["FORMAT", "VERSION", "Result", "figure", "save_figure", "write_json"]
