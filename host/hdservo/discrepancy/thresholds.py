"""Size thresholds per signal set, from the calibration logs by the false-alarm rule.

The workflow names an effect only when it removes at least ``frac_min`` of a residual's
variance (:func:`hdservo.discrepancy.workflow.significant`).  A log's signal set (both
encoders, the motor encoder alone, the output encoder alone) changes how much of a clean
log's residual a wrong candidate can take up, so the threshold is set per signal set on
the clean logs of the corpus' calibration seeds (docs/discrepancy.md, "Calibration"):

    frac_min[set] = max(default, q-quantile(largest_sizes[set]) + margin)

where ``largest_sizes[set]`` holds, per clean calibration log of that set, the largest
size among its first ranking's significant candidates (0 when none is significant).  A
set with fewer than ``min_logs`` clean logs keeps the default: below 1/(1 - q) logs (20
for q = 0.95) the q-quantile is the largest value itself, one log's outlier.

The rule's inputs (those sizes, the seeds they come from, ``q``, ``margin``, the default)
are package data, ``data/discrepancy_thresholds.json``, written by
``tests/results/48_discrepancy_calibration.py`` (``HDSERVO_CALIB_PACKAGE=1``); the
thresholds are computed from them here, so the file states both what was measured and
what follows from it.
"""
from __future__ import annotations

import json
import math
from functools import lru_cache
from typing import Any, Iterable, Mapping

import numpy as np

from ..errors import UserError
from ..resources import data_path

#: The package data file of the rule's inputs.
FILE_NAME = "discrepancy_thresholds.json"
#: Signal sets with a threshold.
SETS: tuple[str, ...] = ("both", "motor", "output")


def rule(largest_sizes: Iterable[float], default: float, quantile: float, margin: float,
         min_logs: int = 0) -> float:
    """The false-alarm rule for one signal set.

    Parameters
    ----------
    largest_sizes : iterable of float
        Per clean calibration log, the largest size (explained fraction, 0-1) of its
        significant candidates, 0 when it has none.
    default : float
        The workflow's default threshold (explained fraction), never undercut.
    quantile : float
        False-alarm quantile (0.95: at most 5 % of such clean logs stay above it).
    margin : float
        Added to the quantile: the rule is ``size >= threshold``.
    min_logs : int
        Fewest clean logs the quantile is taken on; fewer keep ``default``.

    Returns
    -------
    float
        The threshold (explained fraction); ``default`` without logs or when the quantile
        is 0 (no clean log had a significant candidate up to that quantile).
    """
    v = [float(x) for x in largest_sizes if x is not None and math.isfinite(float(x))]
    if not v or len(v) < min_logs:
        return float(default)
    x = float(np.quantile(v, quantile))
    return max(float(default), x + margin) if x > 0 else float(default)


def from_inputs(doc: Mapping[str, Any]) -> dict[str, float]:
    """Thresholds per signal set from the rule's inputs (the package data's layout).

    Parameters
    ----------
    doc : mapping
        ``default``, ``quantile``, ``margin``, ``min_logs`` (0 when absent) and
        ``largest_sizes`` (signal set -> list of explained fractions, one per clean
        calibration log).
    """
    d, q, m = float(doc["default"]), float(doc["quantile"]), float(doc["margin"])
    n = int(doc.get("min_logs", 0))
    sizes = doc.get("largest_sizes") or {}
    return {a: rule(sizes.get(a, []), d, q, m, n) for a in SETS}


@lru_cache(maxsize=1)
def load() -> dict[str, Any]:
    """The rule's inputs from the package data (see the module docstring).

    Raises
    ------
    UserError
        The file is missing or not the expected JSON (one line: which file, what).
    """
    p = data_path(FILE_NAME)
    try:
        doc = json.loads(p.read_text())
    except (OSError, ValueError) as e:
        raise UserError(f"{p}: cannot read the discrepancy thresholds ({e}); expected the JSON written by "
                        "tests/results/48_discrepancy_calibration.py") from None
    missing = [k for k in ("default", "quantile", "margin", "largest_sizes") if k not in doc]
    if missing:
        raise UserError(f"{p}: expected keys {', '.join(missing)} in the discrepancy thresholds")
    return doc


def frac_min_by_signals() -> dict[str, float]:
    """Size threshold per signal set where it differs from the default (from :func:`load`)."""
    doc = load()
    return {a: t for a, t in from_inputs(doc).items() if t != float(doc["default"])}
