"""``hdservo record``: stream process data from a drive into a decoded CSV log and a raw CAN log.

Configures the default streaming TPDOs (loop tick + output angle / motor angle /
motor torque) at ``--rate`` Hz, records for ``--duration`` seconds and writes

* ``OUT.csv`` with the log columns of docs/sim.md (``t_s``, ``load_angle_rad``,
  ``motor_angle_rad``, ``motor_torque_Nm``) and its ``OUT.json`` sidecar (format tag,
  gear ratio and encoder resolutions read from the drive, sample period, firmware
  version, node, the drive tick of ``t_s`` = 0, lost ticks, and every drive parameter
  in SI units with the parameter layout hash), so the log goes straight into
  ``hdservo discrepancy`` or any other log reader;
* ``OUT.log``, the raw frames in ``candump -L`` format (python-can ``.log``).
Lost loop ticks are counted and reported (and in the sidecar).

The drive is the one python-can's settings name (``-i/-c/-b``, else its config file and
``CAN_*`` variables); without any of them the command refuses.  ``--sim [AXIS]`` (or
``-i virtual-drive``) records a simulated drive started for the command (said on stderr).
"""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import can

from .. import logio
from ..errors import UserError
from ..drive import LOOP_HZ, TURN, Drive, DriveError, add_bus_arguments, align_motor_turns, choose_drive
from ..phase import unwrap_phase, unwrap_tick

NAME = "record"
#: the streamed objects a sample needs (EDS names; decoded by the EDS's TPDO maps)
STREAMED = ("load_phase", "motor_phase", "motor_torque")
HELP = "record streamed process data to CSV (+ raw candump log)"


def register(p: argparse.ArgumentParser) -> None:
    """Bus options plus rate, duration and output."""
    add_bus_arguments(p)
    p.add_argument("--rate", type=float, default=2000.0,
                   help="samples per second (divides 10 kHz; default 2000: hdservo discrepancy wants >= 2 kHz)")
    p.add_argument("--duration", type=float, default=2.0, help="seconds to record")
    p.add_argument("-o", "--output", required=True, metavar="LOG.csv", help="CSV to write (also LOG.json, LOG.log)")


def drive_info(drive: Drive) -> dict[str, object]:
    """Sidecar keys that describe the drive a log comes from (the log format of docs/sim.md).

    ``gear_ratio``, ``motor_encoder_counts_per_rev`` / ``load_encoder_counts_per_rev``
    (2^bits of the drive's encoder parameters), ``firmware_version`` (0x100A),
    ``param_layout_hash`` (0x5101:5) and ``drive_params``: every drive parameter in SI
    units (the configuration the log was recorded with).
    """
    from ..driveconfig import si_of
    from ..params_gen import BY_NAME
    params = {name: si_of(p, int(drive.read(p.index, p.sub))) for name, p in BY_NAME.items()}
    return {"gear_ratio": float(params["gear_ratio"]),
            "motor_encoder_counts_per_rev": 2 ** int(params["motor_enc_bits"]),
            "load_encoder_counts_per_rev": 2 ** int(params["output_enc_bits"]),
            "firmware_version": str(drive.read(0x100A, 0)),
            "param_layout_hash": f"0x{int(drive.read(0x5101, 5)):08X}",
            "drive_params": params}


def run(args: argparse.Namespace) -> int:
    """Record and decode."""
    period = LOOP_HZ / args.rate if args.rate > 0 else 0
    if args.rate <= 0 or abs(period - round(period)) > 1e-9 or not 1 <= round(period) <= 65535:
        raise UserError(f"--rate {args.rate}: expected 10000/n Hz for an integer n (e.g. 2000, 1000, 500)")
    if args.duration <= 0:
        raise UserError("--duration must be positive")
    out = Path(args.output)
    target = choose_drive(args)
    vd = None
    if target.bus is None:
        from ..ident.drive_runner import VirtualDrive
        target.announce("record")
        vd = VirtualDrive(axis=target.axis or "reference", rig=False, node_id=args.node_id, pacing="realtime",
                          profile=target.profile)
    try:
        return _record(args, out, target.bus if vd is None else
                       {"interface": "socketcand", "channel": "can0", "host": "127.0.0.1", "port": vd.port})
    finally:
        if vd is not None:
            vd.stop()


def _record(args: argparse.Namespace, out: Path, bus: dict[str, Any]) -> int:
    """Record from the drive on ``bus`` (python-can settings) and write the log."""
    period = LOOP_HZ / args.rate
    try:
        drive = Drive.connect(node_id=args.node_id, **bus)
    except DriveError as e:
        raise UserError(str(e)) from None
    frames: list[can.Message] = []
    with drive:
        try:
            from ..drive_caps import check
            check(drive, "record")
            drive.start()
            info = drive_info(drive)
            drive.configure_stream(int(round(period)))
            writer_msgs = frames

            class _Raw(can.Listener):
                def on_message_received(self, msg: can.Message) -> None:
                    writer_msgs.append(msg)

            raw = _Raw()
            drive.network.notifier.add_listener(raw)
            by_tick: dict[int, dict[str, int]] = {}
            last = None
            for fr in drive.stream(args.duration):
                last = unwrap_tick(last, fr.tick)      # a recording across the tick's wrap stays in order
                by_tick.setdefault(last, {}).update(fr.values)
            drive.network.notifier.remove_listener(raw)
            drive.configure_stream(0)
        except DriveError as e:
            raise UserError(str(e)) from None
    ticks = sorted(by_tick)
    rows = []
    la = ma = None
    lost = 0
    step = int(round(period))
    for i, t in enumerate(ticks):
        d = by_tick[t]
        if i and (t - ticks[i - 1]) != step:
            lost += (t - ticks[i - 1]) // step - 1
        if not all(k in d for k in STREAMED):
            continue
        first = ma is None
        la = unwrap_phase(la, d["load_phase"])
        ma = unwrap_phase(ma, d["motor_phase"])
        if first:       # the motor's whole turns since power-on are not in the PDO
            ma = align_motor_turns(ma, la, float(info["gear_ratio"]))
        tq = d["motor_torque"] / 65536.0
        rows.append([t, la * TURN, ma * TURN, tq])
    if len(rows) < 2:
        raise UserError(f"{len(rows)} complete samples received in {args.duration} s: nothing to write to {out}")
    t0 = rows[0][0]
    meta = {"sample_period_s": step / LOOP_HZ, "source": "hdservo record (CANopen TPDO stream)",
            "node_id": args.node_id, "lost_ticks": lost, "samples": len(rows), "t0_tick": t0, **info}
    cols = ["t_s", "load_angle_rad", "motor_angle_rad", "motor_torque_Nm"]
    data = {c: [r[i] for r in rows] for i, c in enumerate(cols)}
    data["t_s"] = [(t - t0) / LOOP_HZ for t in data["t_s"]]
    out.parent.mkdir(parents=True, exist_ok=True)
    logio.write_log(out, data, meta)
    with can.Logger(str(out.with_suffix(".log"))) as lg:
        for m in frames:
            lg.on_message_received(m)
    print(f"{len(rows)} samples at {args.rate:g} Hz, {lost} lost ticks -> {out}")
    return 0 if lost == 0 else 1
