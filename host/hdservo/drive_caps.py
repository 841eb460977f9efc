"""What a CANopen drive offers: CiA 301/402 capability detection, and the checks commands make.

Any CiA 402 drive answers the same standard objects, so hdservo asks it what it has
before a command starts, instead of failing part-way through:

* **identity**: 0x1000 device type (low 16 bits: the device profile, 402 for a drive;
  high 16 bits: the type, e.g. 0x0002 servo), 0x1018 vendor id / product code /
  revision / serial, 0x1008 device name;
* **modes**: 0x6502 supported drive modes (bit 0 PP, 2 PV, 3 TQ, 5 HM, 6 IP, 7 CSP,
  8 CSV, 9 CST; bits 16-31 manufacturer modes);
* **objects**: each standard object of interest is read once by SDO upload; an abort
  0x06020000 (no object) or 0x06090011 (no sub-index) means absent, any other abort
  (e.g. write-only) means present.  Feedback (0x6064 position, 0x606C velocity, 0x6077
  torque, 0x6078 current, 0x60E4:1 a second encoder), set-points (0x607A, 0x60FF,
  0x6071, offsets 0x60B1 / 0x60B2), 0x60C2 interpolation period;
* **PDOs**: the RPDO / TPDO communication objects present (0x1400.., 0x1800..) and
  which TPDO maps each feedback object now (read from 0x1A00..); whether an object may
  be mapped at all comes from the EDS given (the drive's own EDS for a third-party
  drive; ``hdservo.eds`` by default), ``None`` when the EDS does not list it;
* **SYNC**: 0x1005 SYNC COB-ID (the drive consumes SYNC), 0x1006 communication cycle;
* **hdservo vendor extensions**: 0x5000 capture, 0x5010 excitation generator, 0x5100
  tables, 0x5F00 process data, the drive parameters (0x2000.., layout hash 0x5101:5).
  The manufacturer range 0x2000-0x5FFF means something else on every vendor's drive,
  so these are probed **only** when 0x1018 names the hdservo firmware (vendor
  0x00000EDA, product 0x00484453); on any other drive they are absent without a single
  access (the generic profile of the virtual drive, product 0x0047454E, counts every
  such access and a test fails on it).

Use
---
>>> from hdservo.drive import Drive
>>> from hdservo import drive_caps
>>> with Drive.connect(interface="socketcand", host="127.0.0.1", port=29536, channel="can0") as d:
...     caps = drive_caps.probe(d.node.sdo)
...     print("\\n".join(caps.lines()))
...     caps.require("mode:CSP", "sync", "position_actual", command="identify")
...     caps.has("hdservo.capture"), caps.missing(["second_encoder"])

:func:`require` / :meth:`DriveCaps.require` raise :class:`CapabilityError` (a
:class:`~hdservo.errors.UserError`: the CLI prints one line, exit 2) naming every missing
capability and the object or bit that provides it.  :data:`NEEDS` describes each
capability name; :data:`COMMAND_NEEDS` lists what each drive command checks before it
starts (:func:`check`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, Optional, Protocol, Sequence

from . import od_gen
from .errors import UserError

#: SDO aborts that mean "this drive has no such object / sub-index"
ABSENT_ABORTS = (0x06020000, 0x06090011)
#: attempts of one probe upload answered by a stale SDO response (:func:`_upload`)
STALE_ATTEMPTS = 3
#: identity of the hdservo firmware (0x1018:1 / :2); its vendor objects are probed only then
HDSERVO_VENDOR_ID = od_gen.VENDOR_ID
HDSERVO_PRODUCT_CODE = od_gen.PRODUCT_CODE
#: CiA 402 0x6502 bits -> mode names
MODE_BITS = {0: "PP", 1: "VL", 2: "PV", 3: "TQ", 5: "HM", 6: "IP", 7: "CSP", 8: "CSV", 9: "CST"}
#: CiA 402 0x6060 values of the modes hdservo uses
MODE_VALUES = {"PP": 1, "PV": 3, "CSP": 8, "CSV": 9, "CST": 10}

#: standard objects probed: capability name -> (index, sub, what it is)
STANDARD_OBJECTS: dict[str, tuple[int, int, str]] = {
    "controlword": (0x6040, 0, "controlword"),
    "statusword": (0x6041, 0, "statusword"),
    "modes_of_operation": (0x6060, 0, "modes of operation"),
    "modes_display": (0x6061, 0, "modes of operation display"),
    "position_actual": (0x6064, 0, "position actual value"),
    "velocity_actual": (0x606C, 0, "velocity actual value"),
    "torque_actual": (0x6077, 0, "torque actual value"),
    "current_actual": (0x6078, 0, "current actual value"),
    "second_encoder": (0x60E4, 1, "additional position actual value (second encoder)"),
    "target_position": (0x607A, 0, "target position"),
    "target_velocity": (0x60FF, 0, "target velocity"),
    "target_torque": (0x6071, 0, "target torque"),
    "velocity_offset": (0x60B1, 0, "velocity offset"),
    "torque_offset": (0x60B2, 0, "torque offset"),
    "rated_torque": (0x6076, 0, "motor rated torque"),
    "rated_current": (0x6075, 0, "motor rated current"),
    "following_error": (0x60F4, 0, "following error actual value"),
    "interpolation_period": (0x60C2, 1, "interpolation time period"),
    "sync": (0x1005, 0, "SYNC COB-ID (SYNC consumer)"),
    "comm_cycle": (0x1006, 0, "communication cycle period"),
    "heartbeat": (0x1017, 0, "producer heartbeat time"),
}
#: the feedback objects (TPDO candidates), in report order
FEEDBACK = ("position_actual", "velocity_actual", "torque_actual", "current_actual", "second_encoder")
#: the cyclic set-points (RPDO candidates)
SETPOINTS = ("target_position", "target_velocity", "target_torque", "velocity_offset", "torque_offset")
#: hdservo vendor extensions: name -> (index, sub, what it is)
VENDOR_OBJECTS: dict[str, tuple[int, int, str]] = {
    "hdservo.capture": (0x5000, 2, "capture (0x5000)"),
    "hdservo.excitation": (0x5010, 2, "excitation generator (0x5010)"),
    "hdservo.tables": (0x5100, 0, "compensator tables (0x5100)"),
    "hdservo.process_data": (0x5F00, 1, "process data with the loop tick (0x5F00)"),
    "hdservo.parameters": (0x5101, 5, "drive parameters 0x2000.. (layout hash 0x5101:5)"),
}

#: every capability name :func:`require` knows -> the one phrase that says what provides it
NEEDS: dict[str, str] = {
    "cia402": "a CiA 402 drive (0x1000 device type profile 402)",
    **{f"mode:{m}": f"mode {m} (0x6502 bit {b})" for b, m in MODE_BITS.items()},
    **{k: f"0x{i:04X}:{s} {what}" for k, (i, s, what) in STANDARD_OBJECTS.items()},
    "tpdo": "a TPDO (0x1800 / 0x1A00)",
    "rpdo": "an RPDO (0x1400 / 0x1600)",
    **{k: f"hdservo vendor object: {what}" for k, (_, _, what) in VENDOR_OBJECTS.items()},
}

#: what each drive command checks before it starts (the hdservo-firmware path of each);
#: a capability missing is one error line naming it
COMMAND_NEEDS: dict[str, tuple[str, ...]] = {
    "identify": ("cia402", "mode:CSP", "mode:CST", "sync", "tpdo", "hdservo.parameters", "hdservo.process_data",
                 "hdservo.capture", "hdservo.excitation"),
    "download": ("cia402", "hdservo.parameters", "hdservo.tables"),
    "config": ("hdservo.parameters",),
    "record": ("cia402", "tpdo", "hdservo.parameters", "hdservo.process_data"),
    "test": ("cia402", "mode:CSP", "mode:CSV", "mode:CST", "mode:PP", "sync", "tpdo", "hdservo.parameters",
             "hdservo.process_data"),
    "compare": ("cia402", "mode:CSP", "mode:CSV", "mode:CST", "mode:PP", "sync", "tpdo", "hdservo.parameters",
                "hdservo.process_data"),
}


class CapabilityError(UserError):
    """The drive lacks a capability a command needs (one line, exit status 2)."""


class SdoLike(Protocol):
    """What :func:`probe` needs of python canopen's :class:`canopen.sdo.SdoClient`."""

    def upload(self, index: int, subindex: int) -> bytes: ...


@dataclass(frozen=True)
class ObjectInfo:
    """One probed object.

    Attributes
    ----------
    index, sub : int
        The object.
    present : bool
        The drive answered the SDO upload (or aborted it with another reason than "no object").
    raw : bytes or None
        The value read (little-endian), None when absent or not readable.
    mapped : str or None
        ``TPDOn`` / ``RPDOn`` that maps it now, None if none.
    mappable : bool or None
        PDO-mappable according to the EDS; None when the EDS does not list it.
    """

    index: int
    sub: int
    present: bool
    raw: Optional[bytes] = None
    mapped: Optional[str] = None
    mappable: Optional[bool] = None

    def value(self, signed: bool = False) -> Optional[int]:
        """The value as an integer (little-endian), None when absent."""
        if self.raw is None or not self.raw:
            return None
        return int.from_bytes(self.raw[:8], "little", signed=signed)


@dataclass(frozen=True)
class DriveCaps:
    """What a drive offers (see the module docstring); build it with :func:`probe`.

    Attributes
    ----------
    device_type : int or None
        0x1000 (None if the drive does not answer it: not a CANopen device).
    vendor_id, product_code, revision, serial : int or None
        0x1018:1..4.
    device_name : str or None
        0x1008.
    supported_modes : int or None
        0x6502 raw.
    objects : dict
        Capability name -> :class:`ObjectInfo` of every standard (and, on hdservo, vendor) object probed.
    tpdos, rpdos : tuple of int
        PDO numbers (1-based) whose communication object exists.
    tpdo_valid : tuple of int
        TPDOs whose COB-ID is valid (bit 31 clear).
    vendor_probed : bool
        True when the identity is the hdservo firmware's and its vendor objects were probed.
    """

    device_type: Optional[int]
    vendor_id: Optional[int]
    product_code: Optional[int]
    revision: Optional[int]
    serial: Optional[int]
    device_name: Optional[str]
    supported_modes: Optional[int]
    objects: Mapping[str, ObjectInfo] = field(default_factory=dict)
    tpdos: tuple[int, ...] = ()
    rpdos: tuple[int, ...] = ()
    tpdo_valid: tuple[int, ...] = ()
    vendor_probed: bool = False

    # ---- derived ---------------------------------------------------------------------
    @property
    def profile(self) -> Optional[int]:
        """Device profile number (low 16 bits of 0x1000): 402 for a drive."""
        return None if self.device_type is None else self.device_type & 0xFFFF

    @property
    def modes(self) -> tuple[str, ...]:
        """Standard modes of 0x6502 (``PP``, ``PV``, ``CSP``, ...)."""
        m = self.supported_modes or 0
        return tuple(name for bit, name in sorted(MODE_BITS.items()) if m >> bit & 1)

    @property
    def vendor_modes(self) -> tuple[int, ...]:
        """Manufacturer modes (0x6502 bits 16-31 -> mode -1, -2, ...)."""
        m = self.supported_modes or 0
        return tuple(-(bit - 15) for bit in range(16, 32) if m >> bit & 1)

    @property
    def is_hdservo(self) -> bool:
        """The identity is the hdservo firmware's and its vendor objects answer."""
        return self.vendor_probed and all(self.has(k) for k in VENDOR_OBJECTS)

    def has(self, need: str) -> bool:
        """True when the drive offers the capability ``need`` (a key of :data:`NEEDS`)."""
        if need not in NEEDS:
            raise KeyError(f"unknown capability '{need}' (expected one of {', '.join(NEEDS)})")
        if need == "cia402":
            return self.profile == 402
        if need.startswith("mode:"):
            return need[5:] in self.modes
        if need == "tpdo":
            return bool(self.tpdos)
        if need == "rpdo":
            return bool(self.rpdos)
        info = self.objects.get(need)
        return info is not None and info.present

    def missing(self, needs: Iterable[str]) -> list[str]:
        """The capabilities of ``needs`` the drive lacks, in the order given."""
        return [n for n in needs if not self.has(n)]

    def require(self, *needs: str, command: str = "this command") -> None:
        """Raise :class:`CapabilityError` naming every capability of ``needs`` the drive lacks.

        Raises
        ------
        CapabilityError
            One line: the command, what is missing (with the object / bit), and the drive's identity.
        """
        lack = self.missing(needs)
        if lack:
            raise CapabilityError(f"this drive ({self.identity()}) lacks what {command} needs: "
                                  + "; ".join(NEEDS[n] for n in lack)
                                  + " (hdservo drive info lists what it offers)")

    def identity(self) -> str:
        """One phrase: vendor / product / revision, or the device name."""
        if self.vendor_id is None:
            return "identity 0x1018 unreadable"
        s = f"vendor 0x{self.vendor_id:08X} product 0x{(self.product_code or 0):08X}"
        if self.vendor_id == HDSERVO_VENDOR_ID and self.product_code == HDSERVO_PRODUCT_CODE:
            s += " = hdservo firmware"
        return s

    # ---- output ------------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        """A JSON-able dict (``hdservo drive info --json``)."""
        def hx(v: Optional[int], w: int = 8) -> Optional[str]:
            return None if v is None else f"0x{v:0{w}X}"
        objs = {k: {"object": f"0x{o.index:04X}:{o.sub}", "present": o.present, "mapped": o.mapped,
                    "mappable": o.mappable} for k, o in self.objects.items()}
        return {
            "device_type": hx(self.device_type), "profile": self.profile,
            "identity": {"vendor_id": hx(self.vendor_id), "product_code": hx(self.product_code),
                         "revision": hx(self.revision), "serial": self.serial, "device_name": self.device_name},
            "hdservo_firmware": self.is_hdservo,
            "supported_modes": hx(self.supported_modes), "modes": list(self.modes),
            "vendor_modes": list(self.vendor_modes),
            "sync": self.has("sync"), "tpdos": list(self.tpdos), "rpdos": list(self.rpdos),
            "tpdo_valid": list(self.tpdo_valid),
            "feedback": {k: objs[k] for k in FEEDBACK if k in objs},
            "setpoints": {k: objs[k] for k in SETPOINTS if k in objs},
            "objects": objs,
            "vendor_extensions": ({k: self.has(k) for k in VENDOR_OBJECTS} if self.vendor_probed else None),
            "commands": {c: {"ok": not self.missing(n), "missing": self.missing(n)} for c, n in COMMAND_NEEDS.items()},
        }

    def lines(self) -> list[str]:
        """The human report of ``hdservo drive info``."""
        def yn(k: str) -> str:
            return "yes" if self.has(k) else "no"
        out = [f"device type: {'?' if self.device_type is None else f'0x{self.device_type:08X}'}"
               f" (profile {self.profile}{', CiA 402 drive' if self.profile == 402 else ', not a CiA 402 drive'})",
               f"identity: {self.identity()}, revision "
               f"{'?' if self.revision is None else f'0x{self.revision:08X}'}, serial {self.serial}"
               + (f", name '{self.device_name}'" if self.device_name else ""),
               f"modes (0x6502): {', '.join(self.modes) or 'none'}"
               + (f"; manufacturer modes {', '.join(str(m) for m in self.vendor_modes)}" if self.vendor_modes else "")]
        fb = []
        for k in FEEDBACK:
            o = self.objects.get(k)
            if o is None or not o.present:
                fb.append(f"{k} no")
                continue
            extra = [f"mapped in {o.mapped}" if o.mapped else "not mapped"]
            if o.mappable is not None:
                extra.append("mappable" if o.mappable else "not mappable")
            fb.append(f"{k} 0x{o.index:04X}:{o.sub} ({', '.join(extra)})")
        out.append("feedback: " + "; ".join(fb))
        out.append("set-points: " + ", ".join(f"{k} {yn(k)}" for k in SETPOINTS))
        period = self.objects.get("interpolation_period")
        out.append(f"SYNC (0x1005): {yn('sync')}; communication cycle 0x1006: {yn('comm_cycle')}; "
                   f"interpolation period 0x60C2: {'yes' if period is not None and period.present else 'no'}; "
                   f"TPDOs {list(self.tpdos)} (valid {list(self.tpdo_valid)}), RPDOs {list(self.rpdos)}")
        if self.vendor_probed:
            out.append("hdservo vendor extensions: " + ", ".join(f"{k[8:]} {yn(k)}" for k in VENDOR_OBJECTS))
        else:
            out.append("hdservo vendor extensions: none (not the hdservo firmware: 0x2000-0x5FFF not probed)")
        for c, n in COMMAND_NEEDS.items():
            lack = self.missing(n)
            out.append(f"{c}: " + ("ok" if not lack else "missing " + ", ".join(lack)))
        return out


def _stale(e: Exception) -> bool:
    """Whether an SDO error is a response that belongs to an earlier request (python canopen's wording)."""
    msg = str(e)
    return "instead" in msg or "Unexpected response" in msg


def _upload(sdo: SdoLike, index: int, sub: int) -> tuple[bool, Optional[bytes]]:
    """(present, value) of one object; absent on 0x06020000 / 0x06090011, present on other aborts.

    python canopen repeats a request after a response time-out, so on a loaded link the late
    answer to the first request and the answer to the repeat both arrive, and the second can be
    taken for the answer of the next upload ("Node returned a value for ... instead").  An upload
    is idempotent: after such a stale answer it waits one response time-out, so the stragglers
    land (python canopen drops them at the next request), and asks again, up to
    :data:`STALE_ATTEMPTS` times.
    """
    import time

    import canopen
    for attempt in range(STALE_ATTEMPTS):
        try:
            return True, bytes(sdo.upload(index, sub))
        except canopen.SdoAbortedError as e:
            if e.code in ABSENT_ABORTS:
                return False, None
            return True, None
        except canopen.SdoCommunicationError as e:
            if attempt + 1 >= STALE_ATTEMPTS or not _stale(e):
                raise
            time.sleep(float(getattr(sdo, "RESPONSE_TIMEOUT", 0.3)))
    raise AssertionError("unreachable")


def _eds_mappable(eds: Optional[Any], index: int, sub: int) -> Optional[bool]:
    """PDO-mappable according to the EDS object dictionary (None when it does not list it)."""
    if eds is None:
        return None
    try:
        obj = eds[index]
        var = obj[sub] if hasattr(obj, "subindices") else obj
        return bool(var.pdo_mappable)
    except (KeyError, TypeError, AttributeError):
        return None


def probe(sdo: SdoLike, eds: Optional[Path | str] = None, use_eds: bool = True) -> DriveCaps:
    """Ask a drive what it offers (a few dozen SDO uploads of standard objects; see the module docstring).

    Parameters
    ----------
    sdo
        The drive's SDO client (``Drive.node.sdo``, or any ``canopen`` node's ``.sdo``).
    eds : path, optional
        The drive's EDS, for "mappable"; default the hdservo EDS (whose standard objects are
        the CiA 402 ones).  ``use_eds=False``: no EDS, mappable is None.

    Returns
    -------
    DriveCaps

    Raises
    ------
    canopen.SdoCommunicationError
        The drive does not answer (no SDO response to 0x1000): the caller reports it.
    """
    import canopen
    od = None
    if use_eds:
        from .drive import EDS_PATH
        od = canopen.import_od(str(eds or EDS_PATH))

    def u32(index: int, sub: int) -> Optional[int]:
        ok, raw = _upload(sdo, index, sub)
        return int.from_bytes(raw[:4].ljust(4, b"\0"), "little") if ok and raw else None

    device_type = u32(0x1000, 0)
    ident = [u32(0x1018, s) for s in (1, 2, 3, 4)]
    ok, raw = _upload(sdo, 0x1008, 0)
    name = raw.decode("latin-1").rstrip("\0") if ok and raw else None
    modes = u32(0x6502, 0)
    # PDOs: communication objects present, and the current TPDO / RPDO mappings
    tpdos, rpdos, valid = [], [], []
    mapped: dict[tuple[int, int], str] = {}
    for i in range(512):
        cob = u32(0x1800 + i, 1)
        if cob is None:
            break
        tpdos.append(i + 1)
        if not cob >> 31 & 1:
            valid.append(i + 1)
        n = u32(0x1A00 + i, 0) or 0
        for k in range(1, min(n, 64) + 1):
            m = u32(0x1A00 + i, k) or 0
            mapped.setdefault((m >> 16, m >> 8 & 0xFF), f"TPDO{i + 1}")
    for i in range(512):
        if u32(0x1400 + i, 1) is None:
            break
        rpdos.append(i + 1)
        n = u32(0x1600 + i, 0) or 0
        for k in range(1, min(n, 64) + 1):
            m = u32(0x1600 + i, k) or 0
            mapped.setdefault((m >> 16, m >> 8 & 0xFF), f"RPDO{i + 1}")
    objects: dict[str, ObjectInfo] = {}
    for key, (index, sub, _) in STANDARD_OBJECTS.items():
        present, val = _upload(sdo, index, sub)
        objects[key] = ObjectInfo(index, sub, present, val, mapped.get((index, sub)) if present else None,
                                  _eds_mappable(od, index, sub) if present else None)
    vendor_probed = ident[0] == HDSERVO_VENDOR_ID and ident[1] == HDSERVO_PRODUCT_CODE
    if vendor_probed:
        for key, (index, sub, _) in VENDOR_OBJECTS.items():
            present, val = _upload(sdo, index, sub)
            objects[key] = ObjectInfo(index, sub, present, val, mapped.get((index, sub)) if present else None,
                                      _eds_mappable(od, index, sub) if present else None)
    return DriveCaps(device_type=device_type, vendor_id=ident[0], product_code=ident[1], revision=ident[2],
                     serial=ident[3], device_name=name, supported_modes=modes, objects=objects,
                     tpdos=tuple(tpdos), rpdos=tuple(rpdos), tpdo_valid=tuple(valid), vendor_probed=vendor_probed)


def require(caps: DriveCaps, *needs: str, command: str = "this command") -> None:
    """:meth:`DriveCaps.require` as a function (``require(caps, "mode:CSP", command="test")``)."""
    caps.require(*needs, command=command)


def check(drive: Any, command: str, needs: Optional[Sequence[str]] = None) -> DriveCaps:
    """Probe ``drive`` (a :class:`hdservo.drive.Drive`) and require what ``command`` needs.

    Parameters
    ----------
    drive
        A connected :class:`~hdservo.drive.Drive` (before :meth:`~hdservo.drive.Drive.start`).
    command
        Command name; its needs are ``COMMAND_NEEDS[command]`` unless ``needs`` is given.

    Returns
    -------
    DriveCaps
        What the drive offers (it has everything the command needs).

    Raises
    ------
    CapabilityError
        A capability is missing (one line).
    hdservo.drive.DriveError
        The drive does not answer.
    """
    import canopen
    from .drive import DriveError
    try:
        caps = probe(drive.node.sdo)
    except canopen.SdoCommunicationError as e:
        raise DriveError(f"capability probe: {e}") from None
    caps.require(*(COMMAND_NEEDS[command] if needs is None else needs), command=command)
    return caps


def preflight(choice: Any, node_id: int, command: str, needs: Optional[Sequence[str]] = None) -> DriveCaps:
    """Check a drive before a command starts: connect, :func:`check`, disconnect.

    For commands that open the drive later, once per step (``test``, ``compare``): they
    refuse here, before any output is written or any procedure starts.

    Parameters
    ----------
    choice
        A :class:`hdservo.drive.DriveChoice`; a simulated drive is started for the check
        (its ``profile`` honoured) and stopped again.
    node_id
        CANopen node id.
    command, needs
        See :func:`check`.

    Raises
    ------
    CapabilityError
        A capability is missing (one line).
    UserError
        The drive does not answer.
    """
    from .drive import DriveError
    from .ident.drive_runner import chosen_drive
    try:
        with chosen_drive(choice, node_id) as drive:
            return check(drive, command, needs)
    except DriveError as e:
        raise UserError(f"drive: {e}") from None
