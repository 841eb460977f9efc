"""Check a named rigid-axis effect on EMPS with the authors' IDIM-LS chain.

The workflow runs on the exported EMPS log with its own (generic) processing.  The
benchmark's figure of merit, the training relative force error 100 ||y - X theta|| / ||y||,
is defined on the authors' chain (:func:`hdservo.emps.build_system`: 100 Hz zero-phase
Butterworth, central differences, decimation by 10, every sample).  This module adds the
columns of the named effect to the symmetric observation matrix [qdd, qd, sgn qd, 1]
and re-solves there, so the number is comparable with the published 4.08 % (symmetric)
and 3.11 % (direction-asymmetric).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .. import emps
from ..errors import UserError


def effect_columns(name: str, params: dict[str, Any], qd: np.ndarray) -> list[np.ndarray]:
    """Columns of a named effect on the EMPS velocity ``qd`` (m/s)."""
    if name == "asymmetric_friction":
        return [np.abs(qd)]
    if name == "stribeck_friction":
        vs = float(params["vs_out_rad_s"])
        return [np.exp(-(qd / vs) ** 2) * np.sign(qd)]
    raise UserError(f"effect '{name}' has no EMPS IDIM-LS form here (only friction effects)")


def idim_relative_error(rec: emps.EmpsRecord, name: str | None, params: dict[str, Any] | None = None) -> dict[str, Any]:
    """Relative force error (%) of the symmetric model plus the named effect, authors' chain."""
    base = emps.build_system(rec, "symmetric")
    sym = emps.solve(base)
    if name is None:
        return {"relative_error_pct": sym.relative_error_pct, "params": sym.params()}
    _, qd, _ = emps.derivatives(rec.position_m, rec.sample_period_s)
    cols = [emps.matlab_decimate(c[emps.DROP_SAMPLES:], emps.DECIMATION)
            for c in effect_columns(name, params or {}, qd)]
    X = np.column_stack([base.X] + cols)
    theta = np.linalg.lstsq(X, base.y, rcond=None)[0]
    e = base.y - X @ theta
    return {"relative_error_pct": float(100 * np.linalg.norm(e) / np.linalg.norm(base.y)),
            "symmetric_relative_error_pct": sym.relative_error_pct,
            "theta": [float(v) for v in theta],
            "columns": ["M", "Fv", "Fc", "offset"] + [f"{name}_{i}" for i in range(len(cols))]}
