"""``hdservo download MODEL.toml``: compensator parameters and tables from an identified model, to a drive.

The model (``hdservo identify -o MODEL.toml``) is mapped onto the axis keys
:func:`hdservo.compsetup.compensator_params` reads (output-referred
``[friction_total]`` -> one lumped friction side, ``[friction_motor]``
sigma0/sigma1 x N^2, stiffness, Maxwell-slip elements, the four largest TE
harmonics, FRF inertias); keys the model does not have come from ``--axis``
(default: the reference axis) and are listed.  Then, with the power stage off:

* the drive parameters (SDO, 0x28xx by name) are written and read back;
* 0x5100:2 (friction group: Stribeck + LuGre) and 0x5100:3 (TE group) are
  downloaded as parameter groups (all or nothing on the drive) and read back;
* 0x5100:1, the identified twist -> torque Preisach image ``MODEL.preisach.bin``
  (named in ``[preisach_drive_table] file``), is checked here (magic, sizes, CRC,
  diagonal), downloaded and read back.

Any refusal or read-back mismatch is one error line and exit status 2; what
was already written stays (each table is atomic on the drive).  ``--enable``
sets ``cb_enable`` afterwards.  What was written is in force in RAM; ``--save``
stores it (0x1010: parameters, groups and the Preisach table) and checks that
the drive reports the table saved (0x5101:3), so it survives a power cycle.

The drive is the one python-can's settings name (``-i/-c/-b``, else its config file and
``CAN_*`` variables); without any of them the command refuses.  ``--sim [AXIS]`` (or
``-i virtual-drive``) starts a simulated drive for a dry run (said on stderr; it stops when
the command ends).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from ..download import plan_download, write_verified
from ..errors import UserError
from . import progress_lines

NAME = "download"
HELP = "write compensator parameters and tables computed from an identified model to a drive (verified)"

def register(p: argparse.ArgumentParser) -> None:
    from ..drive import add_bus_arguments
    p.add_argument("model", type=Path, metavar="MODEL.toml", help="identified model (hdservo identify -o)")
    add_bus_arguments(p)
    p.add_argument("--axis", default="reference", metavar="AXIS.toml",
                   help="axis file for the keys the model lacks (default: reference)")
    p.add_argument("--preisach", type=Path, metavar="TABLE.bin",
                   help="Preisach image to download (default: the one the model names, if any)")
    p.add_argument("--no-tables", action="store_true", help="parameters only")
    p.add_argument("--skip-missing", action="store_true",
                   help="skip parameters the drive's dictionary does not have (older firmware), listing them; "
                        "default: that is an error")
    p.add_argument("--enable", default=None, metavar="NAMES",
                   help="comma-separated compensators to switch on afterwards (stribeck,lugre,maxwell,preisach,"
                        "te,backstep,dob,compliance); default: leave cb_enable")
    p.add_argument("--save", action="store_true",
                   help="store everything in the drive's NVM afterwards (0x1010; power stage off), verified by 0x5101:3")
    p.add_argument("--table-version", type=int, default=1, metavar="N", help="table version written into the groups (1..2147483647; the drive saves it with the parameters)")
    p.add_argument("--json", type=Path, metavar="PATH", help="write what was downloaded as JSON")


def run(args: argparse.Namespace) -> int:
    from ..drive import Drive, DriveError, choose_drive
    from ..ident.drive_runner import VirtualDrive

    progress = progress_lines("download")

    if args.json is not None and not args.json.parent.exists():
        raise UserError(f"{args.json}: directory {args.json.parent} does not exist")
    if not 0 < args.table_version <= 0x7FFFFFFF:
        raise UserError(f"--table-version {args.table_version}: expected 1..2147483647")
    enable = None
    if args.enable is not None:
        from ..compsetup import enable_mask
        try:
            enable = enable_mask([x for x in args.enable.split(",") if x])
        except ValueError as e:
            raise UserError(f"--enable: {e}") from None
    plan = plan_download(args.model, args.axis, args.preisach, args.table_version)
    target = choose_drive(args)
    for n in plan["notes"]:
        progress(f"note: {n}")
    bus = target.bus
    vd = None
    drive = None
    try:
        if bus is None:
            target.announce("download")
            vd = VirtualDrive(axis=target.axis or "reference", rig=False, node_id=args.node_id, pacing="realtime",
                              profile=target.profile)
            bus = {"interface": "socketcand", "channel": "can0", "host": "127.0.0.1", "port": vd.port}
        try:
            drive = Drive.connect(args.node_id, **bus)
            from ..drive_caps import check
            check(drive, "download", ("cia402", "hdservo.parameters")
                  + (("hdservo.tables",) if not args.no_tables else ()))
            drive.start()
        except DriveError as e:
            raise UserError(f"drive: {e}") from None
        done = write_verified(drive, plan, tables=not args.no_tables, progress=progress,
                              skip_missing=args.skip_missing)
        if done["missing"]:
            progress(f"note: not on this drive, skipped: {', '.join(done['missing'])}")
        if enable is not None:
            try:
                drive.set_param("cb_enable", float(enable))
                if int(drive.get_param("cb_enable")) != enable:
                    raise UserError("cb_enable: read-back differs")
            except DriveError as e:
                raise UserError(f"cb_enable: {e}") from None
        saved = None
        if args.save:
            progress("0x1010 save to NVM")
            try:
                drive.save()
                saved = drive.store_status()
            except DriveError as e:
                raise UserError(f"save refused by the drive: {e}") from None
            if not saved["table_saved"]:
                raise UserError("save: the drive reports the Preisach table in force as not saved (0x5101:3 = 0)")
    finally:
        if drive is not None:
            drive.close()
        if vd is not None:
            vd.stop()
    summary = {"saved": saved is not None, "model": str(args.model), "params_written": done["params"], "tables": done["tables"],
               "skipped_missing": done["missing"],
               "preisach_file": str(plan["preisach_file"]) if plan["preisach_file"] else None,
               "notes": plan["notes"], "cb_enable": enable,
               "params": plan["params"], "groups": {str(k): v for k, v in plan["groups"].items()}}
    if args.json is not None:
        from ..fileio import write_json_atomic
        write_json_atomic(args.json, summary)
    print(f"downloaded {done['params']} parameters and tables "
          f"{', '.join(f'0x5100:{s}' for s in done['tables']) or '(none)'}; every item read back and verified; "
          + ("saved to NVM" if saved is not None else "in RAM only (--save keeps it over a power cycle)"))
    return 0
