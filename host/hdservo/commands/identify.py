"""``hdservo identify {friction,stiffness,hysteresis,te,frf,all}``: identify the axis.

Sources (one of):

(default)             the drive python-can's settings name, over CAN: ``-i/-c/-b`` (+ socketcand
                      ``--host/--port``), else python-can's config file / ``CAN_*`` variables;
                      without any of them the command refuses (no silent simulation)
``--sim [AXIS]``      a simulated drive over CAN, exactly like a real drive: ``hdservo-sim serve``
                      of the reference axis (or AXIS: 'minimal' or a TOML file), lock-step pacing,
                      test-rig interface, started on a loopback port (said on stderr), always
                      stopped; the same as ``-i virtual-drive``
``--offline AXIS``    the simulator binding in this process (no CAN, no drive)
``--data LOG.csv``    recorded experiment logs (repeatable; each sidecar names its experiment)

Outputs: ``-o MODEL.toml`` (axis/model, SI keys), ``--json REPORT.json``,
``--out-dir DIR`` (PNG per fit), ``--save-data DIR`` (experiment logs), the
Preisach table image beside the model (``MODEL.preisach.bin``).
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..errors import UserError
from . import progress_lines

#: what the standard-objects path identifies (the others need a locked output)
STD_TARGETS = ("friction", "te", "frf")

NAME = "identify"
HELP = "identify friction, stiffness, hysteresis, transmission error and FRF of an axis"


def register(p: argparse.ArgumentParser) -> None:
    from ..drive import add_bus_arguments
    from ..ident.pipeline import TARGETS
    p.add_argument("target", choices=TARGETS, help="what to identify")
    src = p.add_argument_group("source (default: the drive of the python-can settings below)")
    src.add_argument("--offline", metavar="AXIS", help="run the experiments on the simulator binding in this "
                     "process (no CAN, no drive) with this axis ('reference', 'minimal' or an axis TOML file)")
    src.add_argument("--data", metavar="LOG.csv", action="append", type=Path,
                     help="recorded experiment log (repeatable)")
    can = p.add_argument_group("drive (python-can settings; default: python-can's config file / CAN_* variables)")
    add_bus_arguments(can)
    can.add_argument("--no-rig", action="store_true",
                     help="with --sim only: do not use the simulated drive's test-rig interface; the locked-output "
                          "experiments then run on the simulator binding (said in the JSON report)")
    std = p.add_argument_group("any CiA 402 drive (docs/generic-drive.md)")
    std.add_argument("--standard-objects", action="store_true",
                     help="run the experiments through CiA 402 standard objects only (host-streamed CSV set-points, "
                          "synchronous TPDOs of 0x6064/0x606C/0x6077 [+0x60E4:1]); targets friction, te, frf; with "
                          "--sim the virtual drive runs its generic profile")
    std.add_argument("--gear-ratio", type=float, metavar="N",
                     help="with --standard-objects: gear ratio (motor turns per output turn) when the drive has no "
                          "0x6091")
    std.add_argument("--sync-period", type=float, metavar="S",
                     help="with --standard-objects: SYNC period, s (default 0.001; --sim: 0.001)")
    std.add_argument("--bus-bitrate", type=float, metavar="BIT_S", default=None,
                     help="with --standard-objects: bitrate for the bus-load check (default: -b, else 1000000)")
    onl = p.add_argument_group("online Stribeck identification in the drive (docs/identification.md)")
    onl.add_argument("--online", action="store_true",
                     help="friction on a drive only: after the batch fit, switch on the drive's own estimator "
                          "(fe_enable), run a normal motion profile (moves and reversals 0.01..10 deg/s) and "
                          "watch the estimate (0x5200) converge over CAN against the batch fit")
    onl.add_argument("--online-s", type=float, default=20.0, metavar="S",
                     help="with --online: profile time, s of drive time (default 20)")
    p.add_argument("--seed", type=int, default=None,
                   help="with --sim or --offline only: simulator noise seed (default 1)")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="drive gain override for the closed-loop experiments (repeatable), e.g. vel_kp=27.5")
    p.add_argument("--gain", dest="set", action="append", help=argparse.SUPPRESS)   # older spelling
    p.add_argument("--torque-max", type=float, default=67.0, metavar="NM",
                   help="the gear's torque, N.m output (>= 1.3 T2; default 67): the stiffness-cycle "
                   "amplitude and the lowest drive torque limit the experiments run with")
    p.add_argument("--rated-torque", type=float, metavar="NM", help="rated torque for lost motion (+-4 %%)")
    p.add_argument("-o", "--output", type=Path, metavar="MODEL.toml", help="write the identified model")
    p.add_argument("--json", type=Path, metavar="PATH", help="write the JSON report")
    p.add_argument("--out-dir", type=Path, metavar="DIR", help="write PNG plots here")
    p.add_argument("--plots", dest="out_dir", type=Path, help=argparse.SUPPRESS)   # older spelling
    p.add_argument("--save-data", type=Path, metavar="DIR", help="write the experiment logs here")


def run(args: argparse.Namespace) -> int:
    from ..drive import DriveError
    try:
        return _run(args)
    except DriveError as e:
        raise UserError(f"drive: {e}") from None


def _run(args: argparse.Namespace) -> int:
    from ..ident import experiments as ex

    progress = progress_lines("identify")

    for out in (args.output, args.json):
        if out is not None and not out.parent.exists():
            raise UserError(f"{out}: directory {out.parent} does not exist")
    runner = None
    data: dict[str, ex.ExperimentData] = {}
    gains = {}
    for g in args.set:
        k, sep, v = g.partition("=")
        try:
            gains[k] = float(v)
        except ValueError:
            raise UserError(f"--set {g}: expected NAME=NUMBER") from None
        if not sep or not k:
            raise UserError(f"--set {g}: expected NAME=NUMBER")
    bus_given = [f"--{a}" for a in ("interface", "channel", "bitrate", "host", "port", "sim")
                 if getattr(args, a) is not None] + (["--no-rig"] if args.no_rig else [])
    if args.offline is not None and args.data:
        raise UserError("--offline and --data are two sources: give one")
    if (args.offline is not None or args.data) and bus_given:
        raise UserError(f"{', '.join(bus_given)}: drive options do not go with "
                        f"{'--offline' if args.offline is not None else '--data'}")
    if args.data and args.seed is not None:
        raise UserError("--seed is the simulator's noise seed: it goes with --sim or --offline, not --data")
    seed = 1 if args.seed is None else args.seed
    if args.online_s != 20.0 and not args.online:
        raise UserError("--online-s: an option of --online")
    if args.online:
        if args.target != "friction":
            raise UserError(f"--online: the drive estimates friction only; identify {args.target} has no --online")
        if args.offline is not None or args.data or args.standard_objects:
            which = "--offline" if args.offline is not None else "--data" if args.data else "--standard-objects"
            raise UserError(f"--online runs the drive's own estimator over CAN: it does not go with {which}")
        if not (math.isfinite(args.online_s) and 1.0 <= args.online_s <= 3600.0):
            raise UserError(f"--online-s {args.online_s}: expected seconds in [1, 3600]")
    std_opts = [f"--{k.replace('_', '-')}" for k in ("gear_ratio", "sync_period", "bus_bitrate")
                if getattr(args, k) is not None]
    if std_opts and not args.standard_objects:
        raise UserError(f"{', '.join(std_opts)}: options of --standard-objects")
    if args.standard_objects:
        if args.offline is not None or args.data:
            raise UserError("--standard-objects runs on a drive: it does not go with --offline or --data")
        if args.target not in STD_TARGETS:
            need = ("the motor and the output angle together (not among the standard objects)"
                    if args.target == "lost_motion" else "the output locked and a torque sensor (a test rig)")
            raise UserError(f"identify {args.target}: needs {need}; "
                            f"--standard-objects identifies {', '.join(STD_TARGETS)}")
        if args.no_rig or args.set:
            raise UserError(f"{'--no-rig' if args.no_rig else '--set'}: not an option of --standard-objects "
                            "(no rig, no vendor parameters)")
        for k in ("gear_ratio", "sync_period", "bus_bitrate"):
            v = getattr(args, k)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise UserError(f"--{k.replace('_', '-')} {v}: expected a positive number")
    session = None
    target = None
    if args.data:
        for path in args.data:
            if not path.is_file():
                raise UserError(f"{path}: log file not found")
            d = ex.ExperimentData.load(path)
            if d.kind in data:
                raise UserError(f"{path}: a second '{d.kind}' log (one log per experiment)")
            data[d.kind] = d
        source = "data"
    elif args.offline is not None:
        runner = ex.SimRunner(axis=args.offline, seed=seed, progress=progress, gains=gains)
        source = f"simulator {args.offline}"
    else:
        from ..drive import choose_drive
        target = choose_drive(args, sim_only=("seed", "no_rig"))
        if args.standard_objects and target.virtual and args.gear_ratio is None:
            raise UserError("--standard-objects: the generic virtual drive has no 0x6091: give --gear-ratio")
        if target.virtual:
            source = f"virtual drive over CAN (axis {target.axis_name})"
            target.announce("identify")
        else:
            source = f"{target.describe()} node {args.node_id}"
        if args.standard_objects:
            from ..ident.std_runner import StdSession
            extra: dict = {"progress": progress, "gear_ratio": args.gear_ratio}
            if args.sync_period is not None:
                extra["sync_period_s"] = args.sync_period
            bitrate = args.bus_bitrate or (target.bus or {}).get("bitrate") or 1e6
            extra["bitrate"] = float(bitrate)
            if target.virtual:
                periods = 10 if args.sync_period is None else args.sync_period / 1e-4
                if abs(periods - round(periods)) > 1e-9 or round(periods) < 1:
                    raise UserError(f"--sync-period {args.sync_period}: the virtual drive needs a multiple of 0.0001 s")
                session = StdSession(node_id=args.node_id, axis=target.axis or "reference", seed=seed,
                                     sync_periods=int(round(periods)), **extra)
                source = f"virtual drive, generic CiA 402 profile (axis {target.axis_name}), standard objects"
            else:
                session = StdSession(bus=target.bus, node_id=args.node_id, **extra)
                source += ", standard objects"
        else:
            session = ex.drive_runner(bus=target.bus, node_id=args.node_id, axis=target.axis or "reference",
                                      seed=seed, progress=progress, rig=not args.no_rig, gains=gains,
                                      profile=target.profile)
    if session is not None:
        from ..drive_caps import CapabilityError
        try:
            runner = session.__enter__()
        except CapabilityError as e:
            if args.standard_objects or args.target not in STD_TARGETS:
                raise
            raise UserError(f"{e}; --standard-objects identifies {args.target} through the CiA 402 standard "
                            "objects") from None
        try:
            pl = _run_pipeline(args, runner, data, progress)
            notes = list(runner.notes)
        finally:
            session.__exit__(None, None, None)
    else:
        pl = _run_pipeline(args, runner, data, progress)
        notes = []
    online = None
    if args.online:
        online = _run_online(args, target, pl, seed, progress)
    _write_outputs(args, pl, source, notes, online)
    return 0


def _run_online(args: argparse.Namespace, target: object, pl: object, seed: int, progress) -> dict:
    """The drive's online Stribeck identification against the batch fit just made (thin: the library)."""
    from ..ident.stribeck_online import online_identification
    from ..procedures.runner import Target
    batch = pl.results.get("stribeck")
    if batch is None:
        raise UserError("--online: the batch friction fit gave no Stribeck result to compare with")
    progress(f"online: the drive's estimator during {args.online_s:g} s of a normal motion profile")
    tgt = Target(bus=target.bus, node_id=args.node_id, axis=target.axis or "reference", seed=seed)
    try:
        return online_identification(tgt, batch, args.online_s, progress=lambda m: progress(f"online: {m}"))
    except RuntimeError as e:
        raise UserError(f"--online: {e}") from None


def _run_pipeline(args: argparse.Namespace, runner: object, data: dict, progress) -> object:
    import numpy as np

    from ..ident import pipeline
    settings = pipeline.Settings(torque_max_Nm=args.torque_max, rated_torque_Nm=args.rated_torque,
                                 fixed_gains=tuple(k.partition("=")[0] for k in args.set))
    pl = pipeline.Pipeline(runner=runner, settings=settings, progress=progress, data=data)
    if runner is not None:
        pl.run(args.target)
        return pl
    # logs given with --data: whatever in them the fits cannot use is the user's input, one line
    try:
        pl.run(args.target)
    except UserError as e:
        files = ", ".join(str(p) for p in args.data)
        if any(str(p) in str(e) or p.name in str(e) for p in args.data):
            raise
        raise UserError(f"{files}: {e}") from None
    except (ArithmeticError, IndexError, KeyError, LookupError, TypeError, ValueError,
            np.linalg.LinAlgError) as e:
        files = ", ".join(str(p) for p in args.data)
        raise UserError(f"{files}: cannot identify {args.target} from these logs "
                        f"({type(e).__name__}: {str(e)[:120] or 'no detail'})") from None
    return pl


def _write_outputs(args: argparse.Namespace, pl, source: str, notes: list[str], online: dict | None = None) -> None:
    from ..fileio import write_bytes_atomic, write_json_atomic
    from ..ident import model_toml, pipeline, report
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
            write_bytes_atomic(binp, pz["table"].to_bytes())
            pz["file"] = binp.name
        model_toml.write_toml(args.output, model_toml.model_sections(pl.results, ratio),
                              header=f"Identified by hdservo identify {args.target} "
                                     f"(source: {source}).\n"
                                     "Units in the key names (SI). friction_total is output-referred.")
    plots = report.plot_all(pl.results, args.out_dir) if args.out_dir else []
    if args.json:
        write_json_atomic(args.json, {"target": args.target, "source": source, "notes": notes,
                                      "experiment_sources": {k: d.meta.get("source") for k, d in pl.data.items()},
                                      "results": summ, "timings_s": pl.timings, "plots": plots,
                                      **({"stribeck_drive_online": online} if online is not None else {})})
    for n in notes:
        print(f"note: {n}")
    _print_summary(summ)
    if online is not None:
        _print_online(online)


def _print_online(o: dict) -> None:
    f, e = o["final"], o["final_rel_error"]
    t = o["time_to_target_s"]
    print(f"drive online Stribeck: Fs +{f['fs_pos_Nm']:.4g}/-{f['fs_neg_Nm']:.4g} N.m, Fc +{f['fc_pos_Nm']:.4g}/-"
          f"{f['fc_neg_Nm']:.4g} N.m, vs +{f['vs_pos_rad_s']:.4g}/-{f['vs_neg_rad_s']:.4g} rad/s after "
          f"{f['t_s']:.1f} s of profile; vs batch: levels within {100 * max(abs(e[k]) for k in e if k.endswith('_Nm')):.1f} %, "
          f"vs within {100 * max(abs(e['vs_pos_rad_s']), abs(e['vs_neg_rad_s'])):.1f} %; "
          f"common-mode scale {f.get('scale', 1.0):.3f}, bias {f.get('bias_Nm', 0.0):+.4g} N.m; "
          + (f"inside the targets (5 %, 15 %) from {t:.1f} s" if t is not None else "not inside the targets (5 %, 15 %)"))


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
    if "presliding" in s:
        p = s["presliding"]
        s1 = p["sigma1_Nms_per_rad"]
        print(f"LuGre presliding (motor side): sigma0 {p['sigma0_Nm_per_rad']:.4g} N.m/rad, breakaway "
              f"+{p['breakaway_pos_Nm']:.4g}/-{p['breakaway_neg_Nm']:.4g} N.m, sigma1 "
              + (f"{s1:.3g} N.m.s/rad (rule)" if s1 is not None else "not identified"))
    if "lost_motion" in s:
        m = s["lost_motion"]
        print(f"lost motion at reversals (Maxwell-slip on the output travel): {m['lost_motion_arcsec']:.3g}\" "
              f"over {m['n_elements']} elements, fit residual {m['rms_residual_rad'] * 206264.8:.3g}\" RMS")
    if "preisach" in s:
        p = s["preisach"]
        g = p.get("gear_table", {})
        print(f"Preisach: torque -> twist L = {p['levels']}, {p['forcs']} FORCs, held-out minor loops RMS "
              f"{100 * p['minor_loops']['rms_over_width']:.2f} % of loop width; drive table twist -> torque "
              f"L = {g.get('levels', p['levels'])} (torque at the held-out twist "
              f"{100 * p['minor_loops_quantised']['rms_over_width']:.2f} % of loop width), CRC 0x{p['crc']:08x}")
