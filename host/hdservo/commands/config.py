"""``hdservo config``: drive parameters over CAN -- dump to a file, restore from it, get, set, save, status.

* ``dump [-o FILE]``: every drive parameter in SI units as TOML (stdout without ``-o``),
  signed with the drive's parameter layout hash (0x5101:5), and every CANopen / CiA 402
  setting 0x1010 saves (``[objects]``: SYNC, heartbeats, PDO communication and mapping,
  option codes, windows; COB-IDs relative to the node written as ``$NODEID+...``);
* ``restore FILE [--save] [--force]``: the file is checked whole first (signature,
  types, ranges; unknown names listed, not fatal), then every value is written and read
  back -- the objects in CiA 301 PDO order (PDO invalid, mapping cleared, entries,
  count, communication parameters, COB-ID last), ``$NODEID`` resolved for the target
  node; ``--save`` stores them (0x1010) and checks the drive's store status;
* ``get NAME...`` / ``set NAME=VALUE... [--save]``: single parameters in SI units;
* ``save``: 0x1010 (parameters, the Preisach table in force, the CANopen settings);
* ``status``: what the drive's last boot loaded from NVM (0x5101) and the flash wear
  (0x5102: page erases, the most erased page against its 10 000 cycles, the save rate
  limit's credit and refusals).

Changes apply at once and are in RAM until saved.  Any refusal is one error line and
exit status 2; a restore stops at the first write the drive refuses and writes back the
values the drive had before (read first), so a refused file changes nothing.
The drive is the one python-can's settings name (``-i/-c/-b``, else its config file and
``CAN_*`` variables); without any of them the command refuses.  ``--sim [AXIS]`` (or
``-i virtual-drive``) starts a simulated drive for a dry run, said on stderr; it stops with
the command.
"""
from __future__ import annotations

import argparse
import datetime
import sys
from pathlib import Path
from typing import Any, Callable

from ..errors import UserError
from ..fileio import write_json_atomic, write_text_atomic

NAME = "config"
HELP = ("drive parameters and CANopen settings over CAN: dump to a TOML file, restore it (checked, read back), "
        "get, set, save, status")


def register(p: argparse.ArgumentParser) -> None:
    from ..drive import add_bus_arguments
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    d = sub.add_parser("dump", help="write every drive parameter (SI units) and CANopen setting as TOML")
    d.add_argument("-o", "--output", type=Path, metavar="FILE.toml", help="file to write (default: stdout)")
    d.add_argument("--out", dest="output", type=Path, help=argparse.SUPPRESS)   # older spelling
    r = sub.add_parser("restore", help="write a dumped file back (checked first, read back)")
    r.add_argument("file", type=Path, metavar="FILE.toml")
    r.add_argument("--force", action="store_true",
                   help="accept a file of another parameter layout (values matched by name, still checked)")
    r.add_argument("--save", action="store_true", help="store in NVM afterwards (0x1010)")
    g = sub.add_parser("get", help="print parameters in SI units")
    g.add_argument("names", nargs="+", metavar="NAME")
    s = sub.add_parser("set", help="set parameters in SI units (read back)")
    s.add_argument("pairs", nargs="+", metavar="NAME=VALUE")
    s.add_argument("--save", action="store_true", help="store in NVM afterwards (0x1010)")
    sub.add_parser("save", help="store parameters, Preisach table and CANopen settings in NVM (0x1010)")
    st = sub.add_parser("status", help="what the drive's last boot loaded from NVM (0x5101) and its flash wear (0x5102)")
    for x in (g, st):
        x.add_argument("--json", type=Path, metavar="PATH", help="also write what is printed as JSON")
    for x in sub.choices.values():
        add_bus_arguments(x)


def _save(drive: Any) -> str:
    from ..drive import DriveError
    try:
        drive.save()
        st = drive.store_status()
    except DriveError as e:
        raise UserError(f"save refused by the drive: {e}") from None
    return "saved to NVM (0x1010)" + ("" if st["table_saved"] else "; the Preisach table in force is NOT saved")


def _write_verified(drive: Any, raw: dict[str, int]) -> int:
    """Write raw words (name -> raw) and read each back; returns how many."""
    from ..drive import DriveError
    from ..params_gen import BY_NAME
    n = 0
    for name, v in raw.items():
        p = BY_NAME[name]
        try:
            drive.write(p.index, p.sub, v)
            back = int(drive.read(p.index, p.sub))
        except DriveError as e:
            raise UserError(f"{name} (0x{p.index:04X}:{p.sub}): refused by the drive after {n} written: {e}") from None
        if back != v:
            raise UserError(f"{name} (0x{p.index:04X}:{p.sub}): read back {back}, wrote {v}")
        n += 1
    return n


def _write_objects(drive: Any, objects: dict[tuple[int, int], int]) -> int:
    """Write stored objects in CiA 301 PDO order and read every one back; returns how many."""
    from ..drive import DriveError
    from ..driveconfig import STORED_AT, restore_writes

    def writes() -> None:
        n = 0
        for index, sub, v in restore_writes(objects):
            try:
                drive.write(index, sub, v)
            except DriveError as e:
                raise UserError(f"{STORED_AT[(index, sub)].name} (0x{index:04X}:{sub}) = 0x{v:X}: refused by the "
                                f"drive after {n} writes: {e}") from None
            n += 1
    try:
        drive.reconfigure(writes)      # PRE-OPERATIONAL while PDOs change, then the new mapping is loaded
    except DriveError as e:
        raise UserError(f"drive: {e}") from None
    for (index, sub), v in objects.items():
        back = int(drive.read(index, sub))
        if back != v:
            raise UserError(f"{STORED_AT[(index, sub)].name} (0x{index:04X}:{sub}): read back 0x{back:X}, wrote 0x{v:X}")
    return len(objects)


def _dump(drive: Any, args: argparse.Namespace) -> str:
    from ..driveconfig import STORED_AT, to_toml
    from ..params_gen import BY_NAME
    raw = {name: int(drive.read(p.index, p.sub)) for name, p in BY_NAME.items()}
    objects = {key: int(drive.read(*key)) for key in STORED_AT}
    h = int(drive.read(0x5101, 5))
    name = str(drive.read(0x1008, 0))
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    text = to_toml(raw, h, f"hdservo drive configuration (hdservo config dump), {stamp}\n"
                           f"drive: {name}, node {args.node_id}; {len(raw)} parameters, SI units; "
                           f"{len(objects)} CANopen settings", objects, args.node_id)
    if args.output is None:
        sys.stdout.write(text)
        return ""
    write_text_atomic(args.output, text)           # no half-written file
    return f"wrote {len(raw)} parameters and {len(objects)} CANopen settings to {args.output}"


def _restore(drive: Any, args: argparse.Namespace, progress: Callable[[str], None]) -> str:
    from ..driveconfig import read_file
    from ..params_gen import BY_NAME
    try:
        parsed = read_file(args.file, drive_hash=int(drive.read(0x5101, 5)), force=args.force,
                           node_id=args.node_id)
    except ValueError as e:
        raise UserError(str(e)) from None
    if parsed.unknown:
        progress(f"note: not parameters or settings of this drive, skipped: {', '.join(parsed.unknown)}")
    # what the drive has now, to put back if it refuses a value half-way
    old_raw = {name: int(drive.read(BY_NAME[name].index, BY_NAME[name].sub)) for name in parsed.raw}
    old_obj = {key: int(drive.read(*key)) for key in parsed.objects}
    try:
        n = _write_verified(drive, parsed.raw)
        k = _write_objects(drive, parsed.objects)
    except Exception as e:  # noqa: BLE001 - any failure (refusal, read-back, timeout, bus) rolls back
        why = _failure(e)
        try:
            _write_verified(drive, old_raw)
            _write_objects(drive, old_obj)
        except Exception as e2:  # noqa: BLE001
            raise UserError(f"{why}; putting the previous values back failed too: {_failure(e2)}") from None
        raise UserError(f"{why}; the previous values are back") from None
    msg = f"restored {n} parameters and {k} CANopen settings from {args.file}, every one read back"
    return msg + ("; " + _save(drive) if args.save else "; in RAM only (--save keeps them over a power cycle)")


def _failure(e: BaseException) -> str:
    """One line for a failure inside a restore: a UserError as it is, anything else named by its kind."""
    from ..drive import DriveError
    if isinstance(e, UserError):
        return str(e)
    if isinstance(e, DriveError):
        return f"drive: {e}"
    return f"{type(e).__name__}: {e}"


def _pairs(pairs: list[str]) -> dict[str, int]:
    from ..driveconfig import raw_of
    from ..params_gen import BY_NAME
    raw: dict[str, int] = {}
    for s in pairs:
        name, eq, val = s.partition("=")
        p = BY_NAME.get(name)
        if not eq or p is None:
            raise UserError(f"{s!r}: expected NAME=VALUE with NAME a drive parameter (docs/parameters.md)")
        try:
            v = float(val)
        except ValueError:
            raise UserError(f"{name}={val!r}: expected a number in {p.unit}") from None
        if not p.min <= v <= p.max:
            raise UserError(f"{name} = {v} outside [{p.min}, {p.max}] {p.unit}")
        raw[name] = raw_of(p, v)
    return raw


def _act(drive: Any, args: argparse.Namespace, pairs: dict[str, float],
         progress: Callable[[str], None], doc: dict[str, Any]) -> list[str]:
    """Carry out the action on a started drive; the lines to print (``get`` / ``status`` also fill ``doc``,
    their ``--json`` document)."""
    from dataclasses import asdict
    from ..driveconfig import read_nvm_wear, si_of
    from ..params_gen import BY_NAME
    lines: list[str] = []
    if args.action == "dump":
        lines.append(_dump(drive, args))
    elif args.action == "restore":
        lines.append(_restore(drive, args, progress))
    elif args.action == "get":
        for n in args.names:
            p = BY_NAME[n]
            v = si_of(p, int(drive.read(p.index, p.sub)))
            lines.append(f"{n} = {v!r}  # {p.unit}")
            doc.setdefault("params", {})[n] = {"value": v, "unit": p.unit}
    elif args.action == "set":
        lines.append(f"set {_write_verified(drive, pairs)} parameters, read back")
        if args.save:
            lines.append(_save(drive))
    elif args.action == "save":
        lines.append(_save(drive))
    else:
        st = drive.store_status()
        lines.append(f"parameters: {st['params']}; Preisach table: {st['table']} "
                     f"({'saved' if st['table_saved'] else 'in force but not saved'}); "
                     f"CANopen settings: {st['objects']}")
        refused = int(drive.read(0x5101, 6))
        if refused:
            lines.append(f"CANopen settings refused at boot by 0x{refused >> 8:04X}:{refused & 0xFF} "
                         f"(the drive runs the defaults)")
        wear = read_nvm_wear(drive)
        lines.append(wear.line())
        doc.update({"store": st, "objects_refused_by": f"0x{refused >> 8:04X}:{refused & 0xFF}" if refused else None,
                    "nvm_wear": asdict(wear)})
    return lines


def run(args: argparse.Namespace) -> int:
    from ..drive import DriveError, choose_drive
    from ..ident.drive_runner import chosen_drive
    from ..params_gen import BY_NAME

    def progress(msg: str) -> None:
        print(f"[config] {msg}", file=sys.stderr, flush=True)

    if args.action == "dump" and args.output is not None and not args.output.parent.exists():
        raise UserError(f"{args.output}: directory {args.output.parent} does not exist")
    json_out = getattr(args, "json", None)
    if json_out is not None and (json_out.is_dir() or not json_out.parent.exists()):
        raise UserError(f"--json {json_out}: " + ("is a directory" if json_out.is_dir()
                                                   else f"directory {json_out.parent} does not exist"))
    if args.action == "get":
        bad = [n for n in args.names if n not in BY_NAME]
        if bad:
            raise UserError(f"not drive parameters: {', '.join(bad)} (docs/parameters.md)")
    pairs = _pairs(args.pairs) if args.action == "set" else {}
    target = choose_drive(args)
    if target.bus is None:
        target.announce("config")
    try:
        with chosen_drive(target, args.node_id) as drive:
            from ..drive_caps import check
            check(drive, "config")
            drive.start()
            doc: dict[str, Any] = {}
            lines = _act(drive, args, pairs, progress, doc)
    except DriveError as e:
        raise UserError(f"drive: {e}") from None
    for line in lines:
        if line:
            print(line)
    if json_out is not None:
        write_json_atomic(json_out, {"action": args.action, "node_id": args.node_id, **doc})
    return 0
