"""``hdservo discrepancy LOG.csv [--model MODEL.toml] --json OUT.json --out-dir DIR``.

Fits the baseline axis model to a log (or takes its structure from MODEL.toml), then
names the missing effects one at a time, most evident first, while they are
significant (docs/discrepancy.md).  MODEL.toml::

    [model]
    structure = "two_mass"      # or "rigid"
    offset = false              # constant torque offset in the baseline (default: rigid yes, two-mass no)
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import tomllib
from pathlib import Path
from typing import Any

from ..errors import UserError

NAME = "discrepancy"
HELP = "find and name the physics a baseline axis model lacks (model-discrepancy workflow)"


def register(p: argparse.ArgumentParser) -> None:
    p.add_argument("log", type=Path, help="log CSV (the log format of docs/sim.md) with its JSON sidecar")
    p.add_argument("--model", type=Path, help="baseline model TOML ([model] structure, offset)")
    p.add_argument("--json", type=Path, required=True, metavar="OUT.json", help="result JSON to write")
    p.add_argument("--out-dir", type=Path, metavar="DIR", help="directory for the PNG plots")
    p.add_argument("--plots", dest="out_dir", type=Path, help=argparse.SUPPRESS)   # older spelling


def read_model(path: Path) -> dict[str, Any]:
    """Read and check a baseline model TOML; one-line UserError on bad input."""
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise UserError(f"{path}: cannot read: {e.strerror or e}") from None
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as e:
        line = raw[: e.start].count(b"\n") + 1
        raise UserError(f"{path}:{line}: expected UTF-8 TOML text, found byte 0x{raw[e.start]:02x}") from None
    except tomllib.TOMLDecodeError as e:
        raise UserError(f"{path}: expected TOML: {e}") from None
    m = data.get("model")
    if not isinstance(m, dict):
        raise UserError(f"{path}: expected a [model] table")
    unknown = set(m) - {"structure", "offset"}
    if unknown:
        raise UserError(f"{path}: [model]: unknown key '{sorted(unknown)[0]}' (expected structure, offset)")
    st = m.get("structure", "two_mass")
    if st not in ("two_mass", "rigid"):
        raise UserError(f"{path}: [model] structure: expected \"two_mass\" or \"rigid\", found {st!r}")
    off = m.get("offset")
    if off is not None and not isinstance(off, bool):
        raise UserError(f"{path}: [model] offset: expected true or false, found {off!r}")
    return {"structure": st, "offset": off}


#: Log rate the workflow's tables were measured at and down to, Hz (10 kHz and, every 5th
#: sample, 2 kHz: the same names; at 1 kHz Stribeck friction is found in 1 of 4 held-out logs).
MIN_VALIDATED_RATE_HZ = 2000.0


def run(args: argparse.Namespace) -> int:
    from .. import logio
    from ..fileio import write_json_atomic
    from ..discrepancy import signals, workflow
    model = read_model(args.model) if args.model else {"structure": None, "offset": None}
    log = logio.read_log(args.log)
    sig = signals.from_log(log, model["structure"])
    res = workflow.run(sig, offset=model["offset"])
    out = res.to_json()
    out["log"] = str(args.log)
    out["structure"] = sig.kind
    notes = list(res.notes)
    if 1.0 / sig.dt < MIN_VALIDATED_RATE_HZ:
        notes.append(f"log sampled at {1.0 / sig.dt:.0f} Hz, below the {MIN_VALIDATED_RATE_HZ:.0f} Hz the workflow is "
                     "validated at: Stribeck friction and small effects are less reliable (docs/discrepancy.md)")
    out["notes"] = notes
    if args.out_dir:
        from ..discrepancy.plots import write_plots
        out["plots"] = [str(p) for p in write_plots(res, args.out_dir)]
    write_json_atomic(args.json, out)
    u = sig.units["torque"]
    au = sig.units["angle"]
    sim0 = res.sim_rms_history[0]
    print(f"{args.log}: {sig.kind} baseline, equation-error RMS {res.rms_history[0]:.4g} {u}, "
          + (f"simulation-error RMS {sim0:.4g} {au}" if math.isfinite(sim0) else "not simulable (see note)"))
    for it in res.iterations:
        ev = it["evidence"]
        sf = ev.get("sim_explained_fraction")
        sb = it["sim_rms_before_rad"]
        print(f"  + {it['named_effect']}: {it['rms_before']:.4g} -> {it['rms_after']:.4g} {u}, simulation "
              f"{f'{sb:.4g}' if math.isfinite(sb) else '-'} -> {it['sim_rms_after_rad']:.4g} {au} "
              f"(delta BIC {ev['delta_bic']:.0f} + {ev.get('sim_delta_bic') or 0:.0f}, explained "
              f"{100 * ev['explained_fraction']:.0f} % / {100 * (sf or 0):.0f} %)")
        g = it.get("rms_gap") or {}
        if g.get("residual") and g.get("before") is not None and g.get("after") is not None:
            gu = u if g["residual"] == "equation" else au
            sh = ("closed (at the noise floor)" if g.get("closed")
                  else f"shrink {g['shrink']:.2f}x" if g.get("shrink") is not None else "no gap above the floor")
            print(f"    RMS gap ({g['residual']} error over where it acts, above its floor): "
                  f"{g['before']:.4g} -> {g['after']:.4g} {gu}, {sh}")
    if not res.iterations:
        print("  no significant missing effect")
    for n in notes:
        print(f"[discrepancy] note: {n}", file=sys.stderr)
    return 0
