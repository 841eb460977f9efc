"""One describing-function analysis per nonlinearity: N(A) table, limit cycles, margins."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable, Dict, Optional

import numpy as np

from .catalogue import Entry
from .limitcycle import find_limit_cycles, loop_metrics, margins_vs_amplitude
from .loop import LoopModel, freqresp
from . import plots

#: Frequency grid of the analysis (rad/s): 0.01 Hz .. 5 kHz.
OMEGA = 2 * math.pi * np.logspace(-2, np.log10(5000.0), 1500)


def _c(z: complex) -> Dict[str, float]:
    return {"re": float(z.real), "im": float(z.imag), "abs": float(abs(z)),
            "phase_deg": float(math.degrees(math.atan2(z.imag, z.real)))}


def analyse(entry: Entry, model: LoopModel, plot_dir: Optional[Path] = None, fmt: str = "png",
            progress: Callable[[str], None] | None = None) -> Dict[str, Any]:
    """Analyse one nonlinearity in the loop.

    Parameters
    ----------
    entry : Entry
        Nonlinearity, insertion point and amplitude sweep.
    model : LoopModel
        Linear loop.
    plot_dir : pathlib.Path, optional
        Write ``<name>_nyquist``, ``<name>_df``, ``<name>_margins`` plots here.
    fmt : str
        ``"png"`` or ``"pdf"``.
    progress : callable, optional
        Receives one-line progress messages.

    Returns
    -------
    dict
        JSON-ready result.
    """
    say = progress or (lambda s: None)
    nl, A = entry.nl, entry.amplitudes
    say(f"{entry.name}: N(A) at {A.size} amplitudes")
    N = nl.df_array(A)
    H = model.H(entry.insertion)
    Hv = freqresp(H, OMEGA)[0, 0]
    say(f"{entry.name}: limit cycles")
    cycles = find_limit_cycles(H, nl, A, OMEGA)
    say(f"{entry.name}: margins against amplitude")
    O = freqresp(model.open_system(entry.insertion), OMEGA)
    rows = margins_vs_amplitude(O, OMEGA, nl, A)
    nominal = loop_metrics(O, OMEGA, model.linear_gain(entry.insertion))
    out: Dict[str, Any] = {
        "nonlinearity": nl.to_dict(),
        "insertion": entry.insertion,
        "amplitude_unit": nl.input_unit,
        "df_unit": f"{nl.output_unit}/{nl.input_unit}" if nl.output_unit != nl.input_unit else "1",
        "df": [{"amplitude": float(a), **_c(n)} for a, n in zip(A, N)],
        "limit_cycles": [c.to_dict() for c in cycles],
        "margins_vs_amplitude": rows,
        "linear_model_margins": nominal,
    }
    if plot_dir is not None:
        hu = f"({nl.input_unit})/({nl.output_unit})" if nl.output_unit != nl.input_unit else "1"
        files = {k: plot_dir / f"{entry.name}_{k}.{fmt}" for k in ("nyquist", "df", "margins")}
        hc = [complex(freqresp(H, np.array([c.omega_rad_s]))[0, 0, 0]) for c in cycles]
        plots.nyquist_plot(files["nyquist"], entry.name, Hv, N, [c.to_dict() for c in cycles], hc, hu)
        plots.df_plot(files["df"], entry.name, A, N, nl.input_unit, out["df_unit"])
        plots.margins_plot(files["margins"], entry.name, rows, nl.input_unit, nominal)
        out["plots"] = {k: str(v) for k, v in files.items()}
    return out
