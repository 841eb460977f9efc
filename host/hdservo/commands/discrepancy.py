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
    p.add_argument("--axis", type=Path, metavar="AXIS.toml",
                   help="your simulator axis file (docs/sim.md): the named effects go into a copy of it "
                        "(default: the identified baseline)")
    p.add_argument("--axis-out", type=Path, metavar="DIR",
                   help="directory for AXIS.updated.toml and the axis file of every model (default: the JSON's)")
    p.add_argument("--no-simulator", action="store_true",
                   help="do not write axis files nor replay them through the simulator")


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
    # no structure: the log's default (two-mass with both angles, rigid with one), so that
    # `offset = false` alone works on a one-encoder log
    st = m.get("structure")
    if st is not None and st not in ("two_mass", "rigid"):
        raise UserError(f"{path}: [model] structure: expected \"two_mass\" or \"rigid\", found {st!r}")
    off = m.get("offset")
    if off is not None and not isinstance(off, bool):
        raise UserError(f"{path}: [model] offset: expected true or false, found {off!r}")
    return {"structure": st, "offset": off}


def run(args: argparse.Namespace) -> int:
    from .. import logio
    from ..fileio import write_json_atomic
    from ..discrepancy import signals, validity, workflow
    model = read_model(args.model) if args.model else {"structure": None, "offset": None}
    # a user's own log: the documented columns and gear_ratio + sample_period_s suffice
    log = logio.read_log(args.log, require_tag=False)
    sig = signals.from_log(log, model["structure"])
    cols = signals.resolve_columns(log)
    rotary = sig.units["angle"] == "rad"      # a linear axis' metres have no bits per revolution
    rng = validity.log_range(log.meta, sig.dt,
                             log[cols["motor_angle_rad"]] if rotary and "motor_angle_rad" in cols else None,
                             log[cols["load_angle_rad"]] if rotary and "load_angle_rad" in cols else None)
    warn = validity.warning(str(args.log), rng)
    if warn:
        print(f"[discrepancy] warning: {warn}", file=sys.stderr)
    coarse = validity.twist_note(str(args.log), rng, sig.ratio, validity.twist_p99(sig)) if sig.has_load else None
    if coarse:
        print(f"[discrepancy] note: {coarse}", file=sys.stderr)
    if args.axis is not None and not args.no_simulator:
        from ..discrepancy.closeloop import read_axis
        read_axis(args.axis)                 # a bad axis file is refused before the long analysis
    res = workflow.run(sig, offset=model["offset"])
    closed = None
    if not args.no_simulator:
        from ..discrepancy import closeloop
        stem = args.axis.stem if args.axis is not None else args.log.stem
        closed = closeloop.close(res, args.axis_out or args.json.resolve().parent, stem, args.axis)
        closeloop.apply(res, closed)
    out = res.to_json()
    out["log"] = str(args.log)
    out["structure"] = sig.kind
    out["validated_range"] = {"rate_Hz": list(validity.RATE_HZ), "motor_encoder_bits": list(validity.MOTOR_BITS),
                              "output_encoder_bits": list(validity.LOAD_BITS),
                              "log": {"rate_Hz": rng.rate_Hz, "motor_encoder_bits": rng.motor_bits,
                                      "output_encoder_bits": rng.load_bits},
                              "inside": warn is None}
    out["validated_range"]["log"]["twist_resolution_rad"] = validity.twist_resolution(rng, sig.ratio) if sig.has_load \
        else None
    out["notes"] = list(res.notes) + ([warn] if warn else []) + ([coarse] if coarse else [])
    if closed is not None:
        out["simulator"] = closeloop.to_json(closed)
    if args.out_dir:
        from ..discrepancy.plots import write_plots
        out["plots"] = [str(p) for p in write_plots(res, args.out_dir)]
        if closed is not None:
            from ..discrepancy.plots import write_simulator_overlay
            out["plots"] += [str(p) for p in write_simulator_overlay(res, closed, args.out_dir)]
    write_json_atomic(args.json, out)
    u = sig.units["torque"]
    au = sig.units["angle"]
    sim0 = res.sim_rms_history[0]
    print(f"{args.log}: {sig.kind} baseline, equation-error RMS {res.rms_history[0]:.4g} {u}, "
          + (f"simulation-error RMS {sim0:.4g} {au}" if math.isfinite(sim0) else "not simulable (see note)"))
    for it in res.iterations:
        ev = it["evidence"]
        sf = ev.get("sim_explained_fraction")
        sb = it["model_sim_rms_before_rad"]
        print(f"  + {it['named_effect']}: {it['rms_before']:.4g} -> {it['rms_after']:.4g} {u}, simulation "
              f"{f'{sb:.4g}' if math.isfinite(sb) else '-'} -> {it['model_sim_rms_after_rad']:.4g} {au} "
              f"(delta BIC {ev['delta_bic']:.0f} + {ev.get('sim_delta_bic') or 0:.0f}, explained "
              f"{100 * ev['explained_fraction']:.0f} % / {100 * (sf or 0):.0f} %)")
        g = it.get("rms_gap") or {}
        if g.get("residual") and g.get("before") is not None and g.get("after") is not None:
            gu = u if g["residual"] == "equation" else au
            sh = ("closed (at the noise floor)" if g.get("closed")
                  else f"shrink {g['shrink']:.2f}x" if g.get("shrink") is not None else "no gap above the floor")
            print(f"    RMS gap ({g['residual']} error over where it acts, above its floor): "
                  f"{g['before']:.4g} -> {g['after']:.4g} {gu}, {sh}")
        if "sim_rms_after_rad" in it:
            b, a = it["sim_rms_before_rad"], it["sim_rms_after_rad"]
            print(f"    simulator ({it['axis_after'] or 'not replayable'}): "
                  f"{f'{b:.4g}' if b is not None and math.isfinite(b) else '-'} -> "
                  f"{f'{a:.4g}' if a is not None and math.isfinite(a) else '-'} {au}")
    if closed is not None:
        for d in closed.dropped:
            print(f"  - {d['named_effect']} dropped: {d['reason']}")
        if closed.updated is not None:
            print(f"  updated axis file: {closed.updated}")
    if not res.iterations:
        print("  no significant missing effect")
    from ..discrepancy import NOT_IDENTIFIABLE
    hidden = [e for e, v in res.identifiability.items() if v != "identifiable"]
    if hidden:
        print(f"  {NOT_IDENTIFIABLE} ({res.angles} encoder{'s' if res.angles == 'both' else ''} + torque): "
              + ", ".join(hidden))
    for e, parts in res.not_identifiable_parts.items():
        for part, why in parts.items():
            print(f"  {e}: its {part} part is {NOT_IDENTIFIABLE} ({why})")
    for n in res.notes:
        print(f"[discrepancy] note: {n}", file=sys.stderr)
    return 0
