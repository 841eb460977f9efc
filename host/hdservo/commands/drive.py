"""``hdservo drive info``: what a CANopen drive offers (:mod:`hdservo.drive_caps`).

Reads 0x1000 device type, 0x1018 identity and 0x6502 supported modes, probes the CiA
301/402 objects (feedback, set-points, PDOs, SYNC) and, on the hdservo firmware only,
its vendor extensions; prints one report, and for each drive command whether this drive
has what it needs.  ``--json PATH`` writes the same as JSON.  The drive is the one
python-can's settings name (``-i/-c/-b``, its config file, ``CAN_*``); ``--sim [AXIS]``
a simulated one (``--sim generic:AXIS``: the generic CiA 402 profile).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..errors import UserError
from ..fileio import write_json_atomic

NAME = "drive"
HELP = "what the drive offers: identity, CiA 402 modes, feedback and set-point objects, PDOs, SYNC, vendor extensions"


def register(p: argparse.ArgumentParser) -> None:
    """Options of ``hdservo drive info``."""
    from ..drive import add_bus_arguments
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    i = sub.add_parser("info", help="capability report of the drive (0x1000, 0x1018, 0x6502, objects probed)")
    i.add_argument("--json", type=Path, metavar="PATH", help="write the report as JSON")
    i.add_argument("--eds", type=Path, metavar="FILE.eds",
                   help="the drive's EDS, for which objects may be PDO-mapped (default: hdservo's EDS)")
    add_bus_arguments(i)


def run(args: argparse.Namespace) -> int:
    """Probe the drive and print (and optionally write) its capabilities."""
    import canopen

    from ..drive import DriveError, choose_drive
    from ..drive_caps import probe
    from ..ident.drive_runner import chosen_drive

    if args.json is not None and not args.json.parent.exists():
        raise UserError(f"--json {args.json}: directory {args.json.parent} does not exist")
    if args.eds is not None and not args.eds.is_file():
        raise UserError(f"--eds {args.eds}: no such file")
    if args.eds is not None:
        try:
            canopen.import_od(str(args.eds))
        except Exception as e:          # noqa: BLE001 - any parse failure of a user file is one line
            raise UserError(f"--eds {args.eds}: not a readable EDS ({type(e).__name__}: {str(e)[:100]})") from None
    target = choose_drive(args)
    if target.bus is None:
        target.announce("drive")
    try:
        with chosen_drive(target, args.node_id) as drive:
            caps = probe(drive.node.sdo, eds=args.eds)
    except (DriveError, canopen.SdoCommunicationError) as e:
        raise UserError(f"drive: {e}") from None
    if caps.device_type is None:
        raise UserError(f"node {args.node_id}: no device type 0x1000: not a CANopen device")
    if args.json is not None:
        write_json_atomic(args.json, {"node_id": args.node_id, **caps.to_json()})
    for line in caps.lines():
        print(line)
    sys.stdout.flush()
    return 0
