"""``hdservo identify {friction,stiffness,hysteresis,te,frf,all}``: identify the axis.

Sources (one of):

``--sim AXIS.toml``   run the experiments on the simulator (default: the reference axis)
``--data LOG.csv``    recorded experiment logs (repeatable; each sidecar names its experiment)
``--drive``           a drive over CAN (python-can settings ``-i/-c/-b``, ``--node``): hook,
                      wired when host/hdservo/drive.py is ready

Outputs: ``-o MODEL.toml`` (axis/model, SI keys), ``--json REPORT.json``,
``--plots DIR`` (PNG per fit), ``--save-data DIR`` (experiment logs), the
Preisach table image beside the model (``MODEL.preisach.bin``).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..cli import UserError

NAME = "identify"
HELP = "identify friction, stiffness, hysteresis, transmission error and FRF of an axis"


def register(p: argparse.ArgumentParser) -> None:
    from ..ident.pipeline import TARGETS
    p.add_argument("target", choices=TARGETS, help="what to identify")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--sim", metavar="AXIS.toml", help="run the experiments on the simulator with this axis "
                     "file (or 'reference'); the default source")
    src.add_argument("--data", metavar="LOG.csv", action="append", type=Path,
                     help="recorded experiment log (repeatable)")
    src.add_argument("--drive", action="store_true", help="run on a drive over CAN (hook; not wired yet)")
    can = p.add_argument_group("drive (python-can settings)")
    can.add_argument("-i", "--interface", help="python-can interface (e.g. socketcand, socketcan)")
    can.add_argument("-c", "--channel", help="python-can channel (e.g. vcan0)")
    can.add_argument("-b", "--bitrate", type=int, help="bit rate, bit/s")
    can.add_argument("--node", type=int, default=1, help="CANopen node id (default 1)")
    p.add_argument("--seed", type=int, default=1, help="simulator noise seed (default 1)")
    p.add_argument("--gain", action="append", default=[], metavar="NAME=VALUE",
                   help="drive gain override for the closed-loop experiments (repeatable), e.g. vel_kp=27.5")
    p.add_argument("--torque-max", type=float, default=67.0, metavar="NM",
                   help="stiffness-cycle amplitude, N.m output (>= 1.3 T2; default 67)")
    p.add_argument("--rated-torque", type=float, metavar="NM", help="rated torque for lost motion (+-4 %%)")
    p.add_argument("-o", "--output", type=Path, metavar="MODEL.toml", help="write the identified model")
    p.add_argument("--json", type=Path, metavar="PATH", help="write the JSON report")
    p.add_argument("--plots", type=Path, metavar="DIR", help="write PNG plots here")
    p.add_argument("--save-data", type=Path, metavar="DIR", help="write the experiment logs here")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")


def run(args: argparse.Namespace) -> int:
    from ..ident import experiments as ex
    from ..ident import model_toml, pipeline, report

    def progress(msg: str) -> None:
        if not args.quiet:
            print(f"[identify] {msg}", file=sys.stderr, flush=True)

    for out in (args.output, args.json):
        if out is not None and not out.parent.exists():
            raise UserError(f"{out}: directory {out.parent} does not exist")
    runner = None
    data: dict[str, ex.ExperimentData] = {}
    if args.drive:
        runner = ex.drive_runner(interface=args.interface, channel=args.channel, bitrate=args.bitrate,
                                 node=args.node)
    elif args.data:
        for path in args.data:
            if not path.is_file():
                raise UserError(f"{path}: log file not found")
            d = ex.ExperimentData.load(path)
            data[d.kind] = d
    else:
        gains = {}
        for g in args.gain:
            k, sep, v = g.partition("=")
            try:
                gains[k] = float(v)
            except ValueError:
                raise UserError(f"--gain {g}: expected NAME=NUMBER") from None
            if not sep or not k:
                raise UserError(f"--gain {g}: expected NAME=NUMBER")
        runner = ex.SimRunner(axis=args.sim or "reference", seed=args.seed, progress=progress, gains=gains)
    settings = pipeline.Settings(torque_max_Nm=args.torque_max, rated_torque_Nm=args.rated_torque)
    pl = pipeline.Pipeline(runner=runner, settings=settings, progress=progress, data=data)
    pl.run(args.target)
    summ = pipeline.summary(pl.results)
    ratio = next(iter(pl.data.values())).gear_ratio if pl.data else 0.0
    if args.save_data:
        args.save_data.mkdir(parents=True, exist_ok=True)
        for kind, d in pl.data.items():
            d.save(args.save_data / f"{kind}.csv")
    if args.output:
        pz = pl.results.get("preisach")
        if pz is not None:
            binp = args.output.with_suffix(".preisach.bin")
            tmp = binp.with_name(f".{binp.name}.tmp")
            tmp.write_bytes(pz["table"].to_bytes())
            tmp.replace(binp)
            pz["file"] = binp.name
        model_toml.write_toml(args.output, model_toml.model_sections(pl.results, ratio),
                              header=f"Identified by hdservo identify {args.target} "
                                     f"(source: {args.sim or ('data' if args.data else 'drive')}).\n"
                                     "Units in the key names (SI). friction_total is output-referred.")
    plots = report.plot_all(pl.results, args.plots) if args.plots else []
    if args.json:
        report.write_json(args.json, {"target": args.target, "results": summ, "timings_s": pl.timings,
                                      "plots": plots})
    _print_summary(summ)
    return 0


def _print_summary(s: dict) -> None:
    from ..ident.pipeline import arcmin
    if "stribeck" in s:
        f = s["stribeck"]
        print(f"friction: Fs +{f['fs_pos_Nm']:.4g}/-{f['fs_neg_Nm']:.4g} N.m, Fc +{f['fc_pos_Nm']:.4g}/-"
              f"{f['fc_neg_Nm']:.4g} N.m, vs {f['vs_rad_s']:.4g} rad/s, delta {f['delta']:.3g}, "
              f"viscous {f['viscous_Nms_per_rad']:.4g} N.m.s/rad")
    if "stribeck_online" in s:
        o = s["stribeck_online"]
        print(f"online Stribeck: within {100 * o['tolerance']:.0f} % of batch after {o['samples_to_tol']} samples, "
              f"{o['sweep_time_s_to_tol']} s of {o['sweep_time_s_total']:.1f} s sweep")
    if "stiffness" in s:
        k = s["stiffness"]
        print(f"stiffness: K1/K2/K3 {k['k1_Nm_per_rad']:.4g}/{k['k2_Nm_per_rad']:.4g}/{k['k3_Nm_per_rad']:.4g} "
              f"N.m/rad, T1/T2 {k['t1_Nm']:.4g}/{k['t2_Nm']:.4g} N.m; hysteresis loss "
              f"{arcmin(k['hysteresis_loss_rad']):.3f}' ; lost motion "
              f"{arcmin(k['lost_motion_rad'] or 0):.3f}'")
    if "te" in s:
        t = s["te"]
        i = t["wg_orders"].index(2) if 2 in t["wg_orders"] else 0
        print(f"TE: 2xWG {arcmin(t['wg_amp_rad'][i]):.4f}' phase {t['wg_phase_rad'][i]:.4f} rad, "
              f"p-p {arcmin(t['peak_to_peak_rad']):.3f}'")
    if "frf" in s:
        for f in s["frf"]:
            print(f"FRF ({f['amplitude_rad_s']:g} rad/s): anti-resonance {f['f_antiresonance_Hz']:.3f} Hz, "
                  f"resonance {f['f_resonance_Hz']:.3f} Hz")
    if "preisach" in s:
        p = s["preisach"]
        print(f"Preisach: L = {p['levels']}, {p['forcs']} FORCs, held-out minor loops RMS "
              f"{100 * p['minor_loops']['rms_over_width']:.2f} % of loop width (quantised "
              f"{100 * p['minor_loops_quantised']['rms_over_width']:.2f} %), CRC 0x{p['crc']:08x}")
