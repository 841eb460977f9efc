"""CANopen client for an hdservo drive (real or the virtual drive ``hdservo-sim serve``).

Built on python ``canopen``: a :class:`canopen.BaseNode402` with the generated
EDS (``hdservo/data/hdservo.eds``).  Bus settings are the usual python-can
ones (interface, channel, bitrate) and fall back to python-can's config file
and ``CAN_*`` environment variables when not given.

Example
-------
>>> with Drive.connect(interface="socketcand", channel="can0", host="127.0.0.1", port=29536) as d:
...     d.start()
...     d.enable("CYCLIC SYNCHRONOUS POSITION")
...     d.set_param("pos_kp", 40.0)
"""
from __future__ import annotations

import argparse
import logging
import struct
import time
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator, Optional, TypeVar

import can
import canopen

from . import od_gen, resources
from .errors import UserError
from .params_gen import BY_NAME as PARAMS
from .pdo import STREAM_PDOS, Frame, PdoDecoder
from .phase import unwrap_phase, unwrap_tick  # the stream decoding of docs/sim.md; one home: hdservo.phase

T = TypeVar("T")

# python-can's socketcand client logs every partial TCP read at WARNING level
logging.getLogger("can.interfaces.socketcand").setLevel(logging.ERROR)
# canopen's SDO client logs each time-out / client abort besides raising it; the raised
# error becomes the one DriveError line, so its log lines would only duplicate it
logging.getLogger("canopen.sdo.client").setLevel(logging.CRITICAL)

EDS_PATH = resources.eds_path()
from .fw_const import LOOP_HZ, SIGNALS  # noqa: E402  (generated from the C headers)
from .units import TURN  # noqa: E402

#: 0x5101:1, the parameters at boot (hd_pstore_status_t); all but "loaded" mean the defaults.
PARAM_STORE_STATUS = {0: "loaded", 1: "blank", 2: "corrupt", 3: "other table version", 4: "nvm error"}
#: 0x5101:2, the Preisach table at boot (hd_tstore_status_t); all but "loaded" mean no table.
TABLE_STORE_STATUS = {0: "loaded", 1: "blank", 2: "corrupt", 3: "saved as none", 4: "nvm error"}
#: 0x5101:4, the stored communication / CiA 402 objects at boot; all but "loaded" mean the defaults.
OBJECT_STORE_STATUS = {0: "loaded", 1: "blank", 2: "corrupt", 3: "other dictionary", 4: "nvm error",
                       5: "refused by the SDO checks"}

#: attempts per SDO request/response exchange (python canopen's MAX_RETRIES; its default 1
#: means no retry): a frame lost on the bus costs one response time-out (0.3 s), not the transfer
SDO_ATTEMPTS = 3
#: attempts of a whole domain block transfer broken at the protocol level (below)
DOMAIN_ATTEMPTS = 3
#: SDO aborts of the protocol, not of the content, after which a domain transfer is repeated:
#: time-out (0x05040000), unknown command specifier (0x05040001: a stale frame), block
#: sequence / CRC errors (0x05040003 / 0x05040004); no response at all is repeated too
PROTOCOL_ABORTS = (0x05040000, 0x05040001, 0x05040003, 0x05040004)


def _patch_block_upload_abort() -> None:
    """Give python canopen's block-upload stream the ``abort`` its end-of-upload path calls.

    ``BlockUploadStream._end_upload`` answers a response time-out with ``self.abort(...)``, a
    method the stream does not have (its other paths call ``self.sdo_client.abort``), so a
    late answer at the end of a capture upload surfaced as ``AttributeError`` instead of the
    SDO time-out it is.  The added method sends the same abort through the client.
    """
    from canopen.sdo.client import BlockUploadStream
    if not hasattr(BlockUploadStream, "abort"):
        def abort(self: Any, code: int) -> None:
            self.sdo_client.abort(code)
        BlockUploadStream.abort = abort  # type: ignore[attr-defined]


_patch_block_upload_abort()


def _patch_refused_download_close() -> None:
    """Leave a segmented download the drive refused at its start closed, with nothing to send.

    python canopen's ``WritableStream`` sends its initiate request in ``__init__``; when the
    drive aborts it, the half-made stream is left open, and the garbage collector later calls
    its ``close()``, which sends an end segment.  If the collector runs while this thread holds
    the network's send lock (inside another ``send_message``), that second send waits for the
    lock forever: the host hangs.  The wrapped ``__init__`` marks such a stream done and closed
    before the error propagates, so nothing is sent when it is collected.
    """
    import io
    from canopen.sdo.client import WritableStream
    if getattr(WritableStream.__init__, "_hd_closes_on_refusal", False):
        return
    orig = WritableStream.__init__

    def init(self: Any, *args: Any, **kwargs: Any) -> None:
        try:
            orig(self, *args, **kwargs)
        except BaseException:
            self._done = True
            io.RawIOBase.close(self)
            raise

    init._hd_closes_on_refusal = True  # type: ignore[attr-defined]
    WritableStream.__init__ = init  # type: ignore[method-assign]


_patch_refused_download_close()
#: the drive's SDO server time-out (firmware/canopen/hd_co.h HD_CO_SDO_TIMEOUT_MS): a transfer
#: silent this long is discarded, so a repeat after it starts clean even if the client's abort
#: frame was lost
DRIVE_SDO_TIMEOUT_S = 1.0

MODES = {
    "PROFILED POSITION": 1,
    "CYCLIC SYNCHRONOUS POSITION": 8,
    "CYCLIC SYNCHRONOUS VELOCITY": 9,
    "CYCLIC SYNCHRONOUS TORQUE": 10,
}


class DriveError(Exception):
    """A drive-side failure reported in one line (SDO abort, time-out, refused transition)."""


class DriveProtocolError(DriveError):
    """A transfer that broke at the protocol level (time-out, stale frame) on every repeat.

    The drive did not refuse the content; the same transfer on a fresh connection may succeed.
    """


def _sdo_error(e: Exception) -> type[DriveError]:
    """The error class of a failed expedited SDO exchange: an abort is the drive's answer (DriveError);
    no (valid) response is the transport's failure (DriveProtocolError), e.g. a loaded host's time-out."""
    import canopen
    return DriveProtocolError if isinstance(e, canopen.SdoCommunicationError) else DriveError


#: python-can-like interface name of the simulated drive (``-i virtual-drive``, ``CAN_INTERFACE``, config file)
SIM_INTERFACE = "virtual-drive"
#: built-in axes of the simulated drive (else an axis TOML file)
SIM_AXES = ("reference", "minimal")
#: object profiles of the simulated drive (``hdservo-sim serve --profile``): ``--sim generic:AXIS``
#: (or ``--sim generic``, the reference axis) picks the generic CiA 402 one
SIM_PROFILES = ("hdservo", "generic")
#: python-can's configuration files, in its order (``can.util.CONFIG_FILES``)
CAN_CONFIG_FILES = "~/can.conf, /etc/can.conf, ~/.can, ~/.canrc"


def add_bus_arguments(p: "argparse.ArgumentParser | argparse._ArgumentGroup", sim: bool = True) -> None:
    """Add the python-can bus options ``-i/-c/-b``, socketcand ``--host/--port``, ``--node-id`` and ``--sim [AXIS]``.

    Without ``-i/-c/-b/--host/--port`` the bus comes from python-can's configuration (its
    config file, ``CAN_INTERFACE`` / ``CAN_CHANNEL`` / ``CAN_BITRATE``); a simulated drive
    only with ``--sim [AXIS]`` or the interface name ``virtual-drive`` (:func:`choose_drive`).
    """
    p.add_argument("-i", "--interface",
                   help=f"python-can interface, or '{SIM_INTERFACE}' for the simulator "
                        "(default: python-can config file / CAN_INTERFACE)")
    p.add_argument("-c", "--channel", help="channel, e.g. can0 (default: python-can config file / CAN_CHANNEL)")
    p.add_argument("-b", "--bitrate", type=int, help="bitrate in bit/s (default: python-can config / CAN_BITRATE)")
    p.add_argument("--host", default=None, help="socketcand server host (interface socketcand)")
    p.add_argument("--port", type=int, default=None, help="socketcand server port (interface socketcand)")
    p.add_argument("--node-id", type=int, default=1, help="CANopen node id of the drive (default 1)")
    p.add_argument("--node", dest="node_id", type=int, help=argparse.SUPPRESS)   # older spelling of --node-id
    if sim:
        p.add_argument("--sim", nargs="?", const="reference", default=None, metavar="AXIS",
                       help="talk to a simulated drive instead (a virtual drive started for this command, over "
                            "CAN): axis 'reference' (default), 'minimal', a shipped axis (e.g. csf17_50) or an axis TOML "
                            "file; 'generic:AXIS' (or 'generic') the same axis as a generic CiA 402 drive (standard "
                            f"objects only); the same as -i {SIM_INTERFACE}. Put it last or write --sim=AXIS")


def bus_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """python-can keyword arguments given on the command line (:func:`add_bus_arguments` options only)."""
    kw: dict[str, Any] = {}
    if args.interface:
        kw["interface"] = args.interface
    if args.channel:
        kw["channel"] = args.channel
    if args.bitrate:
        kw["bitrate"] = args.bitrate
    if args.host:
        kw["host"] = args.host
    if args.port is not None:
        kw["port"] = args.port
    if kw.get("interface") == "socketcand":
        kw.setdefault("channel", "can0")
        kw.setdefault("host", "127.0.0.1")
    return kw


@dataclass(frozen=True)
class DriveChoice:
    """The drive a command talks to: a bus from python-can's settings, or a simulated drive.

    Attributes
    ----------
    bus : dict or None
        python-can keyword arguments of the real bus; None for a simulated drive.
    axis : str or None
        Simulated drive only: ``reference``, ``minimal`` or an absolute axis TOML path.
    origin : str
        Where the choice comes from (``--sim``, ``-i``, ``CAN_INTERFACE``, ``python-can config file``).
    profile : str
        Simulated drive only: its object profile, ``hdservo`` (every object) or ``generic``
        (CiA 301/402 standard objects only, ``hdservo-sim serve --profile generic``).
    """

    bus: Optional[dict[str, Any]]
    axis: Optional[str]
    origin: str
    profile: str = "hdservo"

    @property
    def virtual(self) -> bool:
        """True for a simulated drive."""
        return self.bus is None

    def describe(self) -> str:
        """One phrase for logs and reports."""
        if self.bus is None:
            return f"simulated drive (virtual drive{self._profile_note}, axis {self.axis_name})"
        shown = {k: v for k, v in self.bus.items() if k in ("interface", "channel", "bitrate", "host", "port")}
        return f"drive {shown} ({self.origin})"

    @property
    def _profile_note(self) -> str:
        return ", generic CiA 402 profile" if self.profile == "generic" else ""

    @property
    def axis_name(self) -> str:
        """The simulated axis as the user gave it (a file by its name)."""
        return self.axis if self.axis in SIM_AXES or self.axis is None else Path(self.axis).name

    def announce(self, command: str) -> None:
        """Say on stderr, in one line, that a simulated drive is started (nothing for a real one)."""
        if self.bus is None:
            import sys
            print(f"hdservo {command}: using a simulated drive (virtual drive{self._profile_note}, "
                  f"axis {self.axis_name}); "
                  "your real drive is not touched", file=sys.stderr, flush=True)


def _configured_interface(given: dict[str, Any]) -> tuple[Optional[str], str]:
    """The interface name python-can would use (options, ``can.rc``, ``CAN_INTERFACE``/``CAN_CONFIG``,
    config files, in python-can's order) and where it comes from; (None, "") without one."""
    from can.util import load_environment_config, load_file_config
    if given.get("interface"):
        return str(given["interface"]), "-i"
    sources: list[tuple[str, Callable[[], dict[str, Any]]]] = [
        ("can.rc", lambda: dict(can.rc)),
        ("CAN_INTERFACE", lambda: dict(load_environment_config())),
        (f"python-can config file ({CAN_CONFIG_FILES})", lambda: dict(load_file_config())),
    ]
    for origin, load in sources:
        try:
            cfg = load()
        except ValueError as e:        # CAN_CONFIG is not JSON; a config file does not parse
            raise UserError(f"python-can configuration ({origin}): {e}") from None
        name = cfg.get("interface") or cfg.get("bustype")
        if name:
            return str(name), origin
    return None, ""


def choose_drive(args: argparse.Namespace, sim_only: tuple[str, ...] = ()) -> DriveChoice:
    """The drive a command talks to, python-can's way; a simulated drive only when asked for.

    Bus options on the command line first, then python-can's configuration
    (:func:`can.util.load_config`: ``can.rc``, ``CAN_INTERFACE`` / ``CAN_CHANNEL`` /
    ``CAN_BITRATE`` / ``CAN_CONFIG``, then ``~/can.conf``, ``/etc/can.conf``, ``~/.can``,
    ``~/.canrc``).  ``--sim [AXIS]`` or the interface name ``virtual-drive`` (from any of
    those) chooses the simulated drive.  Without any of them there is no drive: an error,
    never a silent simulation.

    Parameters
    ----------
    args
        Parsed :func:`add_bus_arguments` options.
    sim_only
        Names of options that only mean something for the simulated drive (e.g. ``seed``):
        refused, when set (not None / False), with a real drive.

    Raises
    ------
    UserError
        No drive configured, conflicting options, an unknown axis or a bad python-can configuration.
    """
    given = {k: getattr(args, k) for k in ("interface", "channel", "bitrate", "host", "port")
             if getattr(args, k, None) not in (None, "")}
    sim_axis = getattr(args, "sim", None)
    name, origin = _configured_interface(given)
    if sim_axis is not None or name == SIM_INTERFACE:
        origin = "--sim" if sim_axis is not None else origin
        clash = [f"--{k}" for k in given if not (k == "interface" and given[k] == SIM_INTERFACE)]
        if clash:
            raise UserError(f"{', '.join(clash)}: bus options do not go with a simulated drive ({origin}); "
                             "give either the bus or --sim")
        axis = sim_axis or "reference"
        profile = "hdservo"
        if axis == "generic" or axis.startswith("generic:"):
            profile, axis = "generic", axis[len("generic:"):] or "reference"
        axis = resources.axis_arg(axis)      # a shipped axis by name, too
        if axis not in SIM_AXES:
            if not Path(axis).is_file():
                raise UserError(f"--sim {sim_axis}: no such axis file (expected {', '.join(SIM_AXES)}, "
                                 f"a shipped axis ({', '.join(resources.axis_names())}), an axis TOML file, "
                                 "or generic:AXIS)")
            axis = str(Path(axis).resolve())
        return DriveChoice(bus=None, axis=axis, origin=origin, profile=profile)
    for opt in sim_only:
        if getattr(args, opt, None) not in (None, False):
            raise UserError(f"--{opt.replace('_', '-')} is an option of the simulated drive: it goes with --sim")
    if name is None:
        raise UserError("no CAN interface chosen: no -i option and no python-can configuration "
                         f"(CAN_INTERFACE / CAN_CHANNEL, or a [default] section in {CAN_CONFIG_FILES}); "
                         "choose the drive with -i/-c, a python-can config, or --sim for the simulator")
    try:
        cfg = dict(can.util.load_config(config=dict(given)))
    except (can.CanInterfaceNotImplementedError, ValueError, TypeError) as e:
        raise UserError(f"python-can configuration ({origin}): {e}") from None
    bus = {k: v for k, v in cfg.items() if v is not None}
    if bus.get("interface") == "socketcand":
        bus.setdefault("channel", "can0")
        bus.setdefault("host", "127.0.0.1")
    return DriveChoice(bus=bus, axis=None, origin=origin if origin == "-i" else f"python-can configuration: {origin}")


@dataclass
class Sample:
    """One decoded streaming sample (SI units)."""

    tick: int
    values: dict[str, float]


class Drive:
    """One drive on a CANopen network.

    Parameters
    ----------
    network
        A connected :class:`canopen.Network`.
    node_id
        Node id of the drive.
    """

    def __init__(self, network: canopen.Network, node_id: int = 1) -> None:
        self.network = network
        self.node = canopen.BaseNode402(node_id, str(EDS_PATH))
        self.node.sdo.MAX_RETRIES = SDO_ATTEMPTS
        #: (index, sub) of the domain transfer running (:meth:`_domain_transfer`), None between transfers
        self._transfer: Optional[tuple[int, int]] = None
        self._sdo_on_response = self.node.sdo.on_response
        self.node.sdo.on_response = self._on_sdo_response    # before add_node subscribes it
        network.add_node(self.node)
        self.node_id = node_id
        #: the PDOs as the EDS maps them (decoding TPDOs, encoding set-point RPDOs)
        self.pdo = PdoDecoder(node_id, self.node.object_dictionary)
        self._own_network = False

    def _on_sdo_response(self, can_id: int, data: bytes, timestamp: float) -> None:
        """The SDO client's receive callback, without the stale aborts of a domain transfer.

        When the drive discards a block transfer (its SDO time-out, drive time: ~50 ms wall with
        fast pacing, which a loaded host can miss between two segments), the rest of the
        sub-block reaches an idle SDO server.  It reads each segment as a new request (the
        sequence number as a command specifier, table bytes as index and sub-index) and aborts
        each one: 0x05040001, and 0x06020000 "Object does not exist" for an "index" it does
        not have.  Those aborts can arrive while the repeat of the transfer runs and end it as
        a refusal.  An abort answers the transfer it names (CiA 301: the abort frame carries
        the multiplexer), so during a domain transfer an abort of another object is dropped.
        """
        t = self._transfer
        if t is not None and len(data) >= 4 and data[0] == 0x80:
            index, sub = struct.unpack_from("<HB", bytes(data), 1)
            if (index, sub) != t:
                return
        self._sdo_on_response(can_id, data, timestamp)

    # ---- connection ----------------------------------------------------------
    @classmethod
    def connect(cls, node_id: int = 1, **bus: Any) -> "Drive":
        """Open the bus with python-can settings and attach to the drive."""
        net = canopen.Network()
        try:
            net.connect(**bus)
        except (can.CanError, OSError, ValueError) as e:
            raise DriveError(f"cannot open the CAN bus {bus or '(python-can defaults)'}: {e}") from None
        d = cls(net, node_id)
        d._own_network = True
        return d

    def close(self) -> None:
        """Disconnect the bus if this object opened it."""
        if self._own_network:
            self.network.disconnect()
            self._own_network = False

    def __enter__(self) -> "Drive":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- SDO -----------------------------------------------------------------
    def _var(self, index: int, sub: int = 0) -> Any:
        obj = self.node.sdo[index]
        return obj[sub] if isinstance(obj, (canopen.sdo.base.SdoRecord, canopen.sdo.base.SdoArray)) else obj

    def _stale_retry(self, e: Exception, attempt: int) -> bool:
        """True (after letting stragglers arrive) when ``e`` is a stale SDO response worth one more try.

        python canopen retries a request after a response time-out (``MAX_RETRIES``), so on a
        slow link both the late answer to the first request and the answer to the repeat
        arrive; the second one can then be taken for the answer of the *next* request
        ("Node returned a value for ... instead" / "Unexpected response").  Expedited reads
        and writes are idempotent, so the exchange is repeated once the queue is quiet.
        """
        msg = str(e)
        if attempt + 1 >= SDO_ATTEMPTS or not isinstance(e, canopen.SdoCommunicationError):
            return False
        if "instead" not in msg and "Unexpected response" not in msg:
            return False
        time.sleep(self.node.sdo.RESPONSE_TIMEOUT)   # late answers land; request_response drops them
        return True

    def read(self, index: int, sub: int = 0) -> Any:
        """Raw value of (index, sub) by SDO (a stale response is retried, see :meth:`_stale_retry`)."""
        for attempt in range(SDO_ATTEMPTS):
            try:
                return self._var(index, sub).raw
            except (canopen.SdoAbortedError, canopen.SdoCommunicationError) as e:
                if self._stale_retry(e, attempt):
                    continue
                raise _sdo_error(e)(f"read 0x{index:04X}:{sub}: {e}") from None
        raise AssertionError("unreachable")

    def write(self, index: int, sub: int, value: Any) -> None:
        """Write a raw value by SDO (a stale response is retried, see :meth:`_stale_retry`)."""
        for attempt in range(SDO_ATTEMPTS):
            try:
                self._var(index, sub).raw = value
                return
            except (canopen.SdoAbortedError, canopen.SdoCommunicationError) as e:
                if self._stale_retry(e, attempt):
                    continue
                raise _sdo_error(e)(f"write 0x{index:04X}:{sub} = {value!r}: {e}") from None

    # ---- parameters by name ----------------------------------------------------
    def get_param(self, name: str) -> float:
        """A drive parameter (params.toml) in SI units."""
        p = PARAMS.get(name)
        if p is None:
            raise DriveError(f"unknown parameter '{name}'")
        return self.read(p.index, p.sub) / 2.0 ** p.frac

    def set_param(self, name: str, value: float) -> None:
        """Set a drive parameter in SI units (range-checked here and by the drive)."""
        p = PARAMS.get(name)
        if p is None:
            raise DriveError(f"unknown parameter '{name}'")
        if not p.min <= value <= p.max:
            raise DriveError(f"{name} = {value} outside [{p.min}, {p.max}] {p.unit}")
        from .driveconfig import raw_of
        self.write(p.index, p.sub, raw_of(p, value))

    def save(self) -> None:
        """Store the drive parameters, the Preisach table in force and the communication / CiA 402
        settings (PDO configuration, heartbeat, 0x6065-0x6068, ...) in the drive's NVM (0x1010:1 = 'save').

        Refused (0x08000022) with the power stage on.
        """
        self.write(0x1010, 1, 0x65766173)

    def store_status(self) -> dict[str, Any]:
        """What the drive's last boot loaded from NVM, and whether the table in force is saved (0x5101).

        Returns
        -------
        dict
            ``params``, ``table`` and ``objects``: the load status by name
            (:data:`PARAM_STORE_STATUS`, :data:`TABLE_STORE_STATUS`, :data:`OBJECT_STORE_STATUS`);
            ``table_saved``: True when the NVM holds the Preisach table in force (or "no
            table" with none in force), False after a download or a restore of the
            defaults until :meth:`save`.
        """
        p, t, o = int(self.read(0x5101, 1)), int(self.read(0x5101, 2)), int(self.read(0x5101, 4))
        return {"params": PARAM_STORE_STATUS.get(p, f"unknown ({p})"),
                "table": TABLE_STORE_STATUS.get(t, f"unknown ({t})"),
                "objects": OBJECT_STORE_STATUS.get(o, f"unknown ({o})"),
                "table_saved": bool(self.read(0x5101, 3))}

    # ---- NMT and CiA 402 --------------------------------------------------------
    def start(self, wait_tpdo: bool = True) -> None:
        """Load the PDO configuration from the drive, then NMT start (OPERATIONAL).

        ``wait_tpdo``: wait (2 s) for the first TPDO1 as a sign of life.  A virtual drive in
        lock-step (``--pacing sync``) sends none until it gets SYNCs: pass False there.
        """
        try:
            self.node.tpdo.read()
            self.node.rpdo.read()
            self.node.setup_402_state_machine(read_pdos=False)
        except (canopen.SdoAbortedError, canopen.SdoCommunicationError) as e:
            raise DriveError(f"start: reading the PDO configuration: {e}") from None
        self.node.nmt.state = "OPERATIONAL"
        if wait_tpdo:
            self.node.tpdo[1].wait_for_reception(2.0)

    def reconfigure(self, writes: Callable[[], T]) -> T:
        """Run ``writes`` (SDO writes that may change PDO settings) in PRE-OPERATIONAL, then
        reload the PDO configuration and go back to OPERATIONAL.

        No PDO is exchanged while a PDO is remapped (CiA 301), and the host decodes the
        frames that follow with the new mapping.
        """
        self.node.nmt.state = "PRE-OPERATIONAL"
        try:
            out = writes()
        finally:
            try:
                self.node.tpdo.read()
                self.node.rpdo.read()
            except (canopen.SdoAbortedError, canopen.SdoCommunicationError) as e:
                raise DriveError(f"reloading the PDO configuration: {e}") from None
            finally:
                self.node.nmt.state = "OPERATIONAL"
        return out

    def enable(self, mode: str = "CYCLIC SYNCHRONOUS POSITION", settle: Optional[Callable[[], None]] = None,
               timeout: float = 1.0) -> None:
        """Select a mode and walk the 402 state machine to OPERATION ENABLED (:meth:`walk`).

        The power stage is switched on afresh (through READY TO SWITCH ON, also from
        OPERATION ENABLED), so the drive's targets start at the actual values (bumpless).
        ``settle`` and ``timeout`` as for :meth:`walk`.
        """
        if mode not in MODES:
            raise DriveError(f"mode must be one of {sorted(MODES)}")
        self.write(0x6060, 0, MODES[mode])
        self.walk("OPERATION ENABLED", settle=settle, timeout=timeout)

    def disable(self, settle: Optional[Callable[[], None]] = None) -> None:
        """Back to SWITCH ON DISABLED (power stage off; :meth:`walk`)."""
        self.walk("SWITCH ON DISABLED", settle=settle)

    # ---- any CiA 402 drive: python canopen's profile ------------------------------------
    def capabilities(self) -> Any:
        """What this drive offers (:func:`hdservo.drive_caps.probe`: identity, modes, objects, PDOs, SYNC).

        Raises
        ------
        DriveError
            The drive does not answer.
        """
        from . import drive_caps
        try:
            return drive_caps.probe(self.node.sdo)
        except canopen.SdoCommunicationError as e:
            raise DriveError(f"capability probe: {e}") from None

    def enable_402(self, mode: str = "CYCLIC SYNCHRONOUS POSITION") -> None:
        """Select a mode and reach OPERATION ENABLED through python canopen's CiA 402 profile.

        The path for any CiA 402 drive (the generic one): :class:`canopen.BaseNode402`
        checks the mode against 0x6502, writes 0x6060 (by RPDO when mapped), and walks the
        CiA 402 graph from whatever state the drive is in (fault reset included), reading
        the statusword from its TPDO when mapped, else by SDO.  Needs :meth:`start` first
        (it loads the PDO configuration the profile reads) and a drive whose time runs
        (realtime or fast pacing; in lock-step the periods come only with SYNCs).  With
        0x6040/0x6060 mapped in an RPDO the profile sends that RPDO with its own copy of
        the controlword: do not mix it with controlword writes by SDO (:meth:`halt`,
        ``write(0x6040, ...)``, :meth:`enable`), which leave that copy stale.

        Raises
        ------
        DriveError
            The mode is not supported, not taken (0x6061 differs), or the state is not reached.
        """
        if mode not in MODES:
            raise DriveError(f"mode must be one of {sorted(MODES)}")
        node = self.node
        try:
            if not node.is_op_mode_supported(mode):
                raise DriveError(f"mode {mode}: not among this drive's supported modes (0x6502)")
            # python canopen logs a failed mode change instead of raising: 0x6061 is checked below
            node.op_mode = mode
            node.state = "OPERATION ENABLED"
        except (RuntimeError, ValueError) as e:
            raise DriveError(f"CiA 402 enable ({mode}): {e} (state {self.state()})") from None
        except (canopen.SdoAbortedError, canopen.SdoCommunicationError) as e:
            raise DriveError(f"CiA 402 enable ({mode}): {e}") from None
        shown = int(self.read(0x6061))
        if shown != MODES[mode]:
            raise DriveError(f"CiA 402 enable: mode display 0x6061 = {shown}, expected {MODES[mode]} ({mode})")

    def disable_402(self) -> None:
        """SWITCH ON DISABLED (power stage off) through python canopen's CiA 402 profile."""
        try:
            self.node.state = "SWITCH ON DISABLED"
        except (RuntimeError, ValueError) as e:
            raise DriveError(f"CiA 402 disable: {e} (state {self.state()})") from None
        except (canopen.SdoAbortedError, canopen.SdoCommunicationError) as e:
            raise DriveError(f"CiA 402 disable: {e}") from None

    def fault_reset(self) -> None:
        """Rising edge of controlword bit 7, then wait for SWITCH ON DISABLED."""
        self.write(0x6040, 0, 0x00)
        self.write(0x6040, 0, 0x80)
        self._wait_state("SWITCH ON DISABLED", 1.0)

    def state(self) -> str:
        """402 state from the statusword (read by SDO, always fresh)."""
        sw = self.read(0x6041)
        for name, (mask, val) in canopen.profiles.p402.State402.SW_MASK.items():
            if sw & mask == val:
                return name
        return f"UNKNOWN (0x{sw:04X})"

    def _wait_state(self, target: str, timeout: float) -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if self.state() == target:
                return
            time.sleep(0.002)
        raise DriveError(f"drive did not reach {target} (state {self.state()})")

    def walk(self, target: str, settle: Optional[Callable[[], None]] = None, timeout: float = 1.0) -> None:
        """Take the drive to the CiA 402 state ``target`` along python canopen's 402 state machine.

        The controlwords are planned by :func:`plan_402` from the state read once (by SDO), written
        by SDO one after the other, and the statusword is then polled (by SDO) until ``target``
        is reached.  The controlword is written by SDO, never by RPDO, so it does not mix with
        :class:`canopen.BaseNode402`'s own RPDO copy (:meth:`enable_402`) or :meth:`halt`.

        Parameters
        ----------
        target
            ``OPERATION ENABLED`` (through READY TO SWITCH ON, see :meth:`enable`),
            ``SWITCH ON DISABLED`` or another state canopen's graph reaches.
        settle
            Called after each controlword and between two polls, e.g. a SYNC that lets a
            lock-step drive run its loop; None for a drive whose time runs by itself.
        timeout
            Seconds of polling (without ``settle``); with ``settle``: ``timeout`` x 50 polls.

        Raises
        ------
        DriveError
            The drive is in FAULT (:meth:`fault_reset` first), or does not reach ``target``.
        """
        now = self.state()
        if now in ("FAULT", "FAULT REACTION ACTIVE"):
            raise DriveError("drive is in FAULT: fault_reset() first")
        for cw in plan_402(now, target):
            self.write(0x6040, 0, cw)
            if settle is not None:
                settle()
        if settle is None:
            self._wait_state(target, timeout)
            return
        for _ in range(int(round(50 * timeout))):
            if self.state() == target:
                return
            settle()
        raise DriveError(f"drive did not reach {target} (state {self.state()})")

    # ---- setpoints (SI, output side) ----------------------------------------------
    def set_position(self, rad: float) -> None:
        """CSP/PP target position, rad at the output."""
        self.write(0x607A, 0, int(round(rad / TURN * 2 ** 24)))

    def set_velocity(self, rad_s: float) -> None:
        """CSV target velocity, rad/s at the output."""
        self.write(0x60FF, 0, int(round(rad_s / TURN * 2 ** 32)))

    def set_torque(self, nm: float) -> None:
        """CST target torque, N.m at the output (1/1000 of the rated torque 0x6076)."""
        rated = self.read(0x6076) / 1000.0
        self.write(0x6071, 0, int(round(nm / rated * 1000.0)))

    def halt(self, on: bool) -> None:
        """Set (``on``) or clear controlword bit 8, halt; the other controlword bits are kept.

        Profile position: setting it ramps the running move to rest at the drive's
        ``traj_amax`` (statusword bit 10 once at rest); clearing it leaves the axis at rest
        until the next set-point (the move is not resumed).  Cyclic synchronous velocity: the
        velocity command ramps to 0 while it is set.  CSP / CST: no effect (docs/can.md).
        A controlword written afterwards without bit 8 (e.g. a new set-point handshake with
        0x0F / 0x1F) clears it.

        Parameters
        ----------
        on
            True: halt; False: release.
        """
        cw = int(self.read(0x6040))
        self.write(0x6040, 0, (cw | 0x0100) if on else (cw & ~0x0100 & 0xFFFF))

    # ---- tables and capture --------------------------------------------------------
    def download_table(self, sub: int, payload: bytes) -> None:
        """Download a table domain (0x5100:sub) with its CRC-32 trailer and verify by read-back."""
        blob = payload + struct.pack("<I", zlib.crc32(payload))
        self.write_domain(0x5100, sub, blob)
        back = self.read_domain(0x5100, sub)
        if back != blob:
            raise DriveError(f"table 0x5100:{sub}: read-back differs from what was written")

    def _domain_transfer(self, what: str, fn: Callable[[], Any], index: int, sub: int) -> Any:
        """Run one block transfer ``fn``, repeated whole when it broke at the protocol level.

        A response time-out or a protocol abort (:data:`PROTOCOL_ABORTS`) repeats the transfer,
        up to :data:`DOMAIN_ATTEMPTS`, after the drive's own SDO time-out has discarded the part
        it received: the drive installs a domain only when the complete transfer and its CRC
        check out, so a repeat cannot leave a mix.  With fast pacing that time-out is drive time
        (~50 ms wall), which a loaded host can miss between two blocks (a stale frame then ends
        the transfer with 0x05040001: seen in `make demo` at load average 13).  A refusal of the
        content (any other abort) is final.  While it runs, an abort frame that names another
        object than ``index``:``sub`` is not this transfer's answer (:meth:`_on_sdo_response`).
        """
        self._transfer = (index, sub)
        try:
            for attempt in range(DOMAIN_ATTEMPTS):
                try:
                    return fn()
                except (canopen.SdoAbortedError, canopen.SdoCommunicationError) as e:
                    protocol = not isinstance(e, canopen.SdoAbortedError) or e.code in PROTOCOL_ABORTS
                    if protocol and attempt + 1 < DOMAIN_ATTEMPTS:
                        time.sleep(DRIVE_SDO_TIMEOUT_S + self.node.sdo.RESPONSE_TIMEOUT)
                        continue
                    raise (DriveProtocolError if protocol else DriveError)(f"{what}: {e}") from None
            raise AssertionError("unreachable")
        finally:
            self._transfer = None

    def write_domain(self, index: int, sub: int, blob: bytes) -> None:
        """Block download of a domain (CRC-checked; see :meth:`_domain_transfer` for repeats)."""
        def go() -> None:
            with self._var(index, sub).open("wb", size=len(blob), block_transfer=True) as f:
                f.write(blob)
        self._domain_transfer(f"download 0x{index:04X}:{sub}", go, index, sub)

    def read_domain(self, index: int, sub: int) -> bytes:
        """Block upload of a domain (CRC-checked; see :meth:`_domain_transfer` for repeats)."""
        def go() -> bytes:
            with self._var(index, sub).open("rb", block_transfer=True) as f:
                return bytes(f.read())
        out: bytes = self._domain_transfer(f"upload 0x{index:04X}:{sub}", go, index, sub)
        return out

    def download_group(self, sub: int, raw: dict[str, int], version: int = 1) -> None:
        """Download a parameter-group table (0x5100:2 friction, 0x5100:3 TE): every parameter of
        :data:`TABLE_GROUPS` ``[sub]`` as a raw value, applied by the drive all at once or not at all."""
        self.download_table(sub, group_payload(sub, raw, version))

    def arm_capture(self, signals: list[int], samples: int, decimation: int = 1, pretrigger: int = 0) -> None:
        """Arm the capture buffer (0x5000) without triggering it: the command trigger
        (0x5000:1 = 2) or the start of the drive's excitation (0x5010:1 = 1) triggers it."""
        if not 1 <= len(signals) <= 4:
            raise DriveError("capture takes 1 to 4 signals")
        packed = 0
        for k in range(4):
            packed |= (signals[k] if k < len(signals) else 0xFF) << (8 * k)
        self.write(0x5000, 3, packed)
        self.write(0x5000, 4, samples)
        self.write(0x5000, 5, decimation)
        self.write(0x5000, 6, pretrigger)
        self.write(0x5000, 1, 1)

    def read_capture(self, n_signals: int) -> list[list[int]]:
        """Upload the capture buffer (0x5000:7): one list of int32 per frame, oldest first."""
        raw = self.read_domain(0x5000, 7)
        words = struct.unpack(f"<{len(raw) // 4}i", raw)
        return [list(words[i:i + n_signals]) for i in range(0, len(words) - n_signals + 1, n_signals)]

    # ---- excitation generator (0x5010, firmware/core/hd_excitation.h) ------------------
    def has_excitation(self) -> bool:
        """True when the drive answers 0x5010 (the drive-side excitation generator)."""
        try:
            self.node.sdo.upload(0x5010, 0)
            return True
        except (canopen.SdoAbortedError, canopen.SdoCommunicationError, KeyError):
            return False

    def excite(self, kind: str, amplitude: float, injection: str = "torque_ff", offset: float = 0.0,
               f0_Hz: float = 1.0, f1_Hz: float = 100.0, duration_s: float = 0.0, lines: Optional[int] = None,
               period_s: Optional[float] = None, order: Optional[int] = None, bit_periods: int = 1,
               decades: Optional[int] = None, steps_per_decade: int = 1, hold_s: Optional[float] = None,
               cycles: Optional[int] = None, reversals: Optional[int] = None, rate_per_s: Optional[float] = None,
               seed: int = 1, start: bool = True) -> dict[str, int]:
        """Configure (and by default start) the drive's own excitation generator (0x5010).

        ``kind``: one of :data:`EXC_TYPES`; ``injection``: one of :data:`EXC_INJECTION`;
        ``amplitude``, ``offset`` (and ``rate_per_s``, per second) in SI at the injection point:
        N.m (torque, torque_ff), rad/s (velocity), rad (position).  Multisine: ``lines``
        harmonics of 1/``period_s`` (line k at k / period_s Hz, amplitude per line, Schroeder
        phases); chirp: ``f0_Hz`` -> ``f1_Hz`` over ``duration_s``; PRBS: LFSR ``order`` and
        ``bit_periods`` loop periods per bit; steps: ``decades`` x ``steps_per_decade`` levels
        held ``hold_s``; ramp: ``cycles``; FORC: ``reversals``.  Start is accepted in OPERATION
        ENABLED only; an armed capture is triggered in the same loop period.  Returns the raw
        values written (by 0x5010 sub name)."""
        if kind not in EXC_TYPES:
            raise DriveError(f"excitation kind must be one of {sorted(EXC_TYPES)}")
        if injection not in EXC_INJECTION:
            raise DriveError(f"injection must be one of {sorted(EXC_INJECTION)}")
        sc = EXC_SCALE[injection]
        per = lambda t: int(round(t * LOOP_HZ))       # noqa: E731
        count = {"steps": decades, "torque_ramp": cycles, "reversal": reversals, "chirp": 0,
                 "multisine": lines, "prbs": order}[kind]
        if count is None:
            raise DriveError(f"excitation '{kind}' needs "
                             f"{ {'steps': 'decades', 'torque_ramp': 'cycles', 'reversal': 'reversals', 'multisine': 'lines', 'prbs': 'order'}[kind] }")
        if kind == "multisine" and period_s is None:
            raise DriveError("multisine needs period_s")
        raw = {
            "type": EXC_TYPES[kind], "injection": EXC_INJECTION[injection],
            "amplitude": int(round(amplitude * sc)), "offset": int(round(offset * sc)),
            "f0": int(round(f0_Hz * 65536)), "f1": int(round(f1_Hz * 65536)), "duration": per(duration_s),
            "count": int(count), "hold": per(hold_s) if hold_s is not None else int(bit_periods),
            "period": per(period_s) if period_s is not None else 1000, "steps_per_decade": int(steps_per_decade),
            "rate": int(round((rate_per_s or 0.0) * sc / LOOP_HZ)), "seed": int(seed),
        }
        for name, value in raw.items():
            self.write(0x5010, EXC_SUB[name], value)
        if start:
            self.write(0x5010, 1, 1)
        return raw

    def stop_excitation(self) -> None:
        """Stop the excitation: the drive returns to its CiA 402 mode (targets = actual values)."""
        self.write(0x5010, 1, 0)

    def excitation_state(self) -> str:
        """'idle', 'running' or 'done' (0x5010:2)."""
        return {0: "idle", 1: "running", 2: "done"}.get(int(self.read(0x5010, 2)), "unknown")

    def capture(self, signals: list[int], samples: int, decimation: int = 1, timeout: float = 30.0,
                pretrigger: int = 0) -> list[list[int]]:
        """Arm the capture buffer, trigger it, wait until done and upload it (int32 per signal,
        one list per frame, oldest first; ``pretrigger`` frames precede the trigger)."""
        self.arm_capture(signals, samples, decimation, pretrigger)
        self.write(0x5000, 1, 2)
        end = time.monotonic() + timeout
        while self.read(0x5000, 2) != 3:
            if time.monotonic() > end:
                raise DriveError("capture did not finish")
            time.sleep(0.01)
        return self.read_capture(len(signals))

    # ---- streaming ----------------------------------------------------------------
    def configure_stream(self, period_ticks: int) -> None:
        """Default stream: TPDO2..4 = tick + load phase / motor phase / motor torque every period_ticks."""
        for n in STREAM_PDOS:
            self.write(0x1800 + n - 1, 2, 254)
            self.write(0x5F10, n, period_ticks)

    def stream(self, duration_s: float) -> Iterator[Frame]:
        """Yield every streamed TPDO (:data:`hdservo.pdo.STREAM_PDOS`), decoded by the EDS's PDO maps
        (:class:`hdservo.pdo.Frame`: raw values by object name), for duration_s of wall-clock time."""
        q: list[can.Message] = []
        listener = _Collector(q)
        self.network.notifier.add_listener(listener)
        try:
            end = time.monotonic() + duration_s
            while time.monotonic() < end:
                time.sleep(0.01)
                while q:
                    m = q.pop(0)
                    fr = self.pdo.decode(m.arbitration_id, bytes(m.data))
                    if fr is not None and fr.pdo in STREAM_PDOS:
                        yield fr
        finally:
            self.network.notifier.remove_listener(listener)


# ---- CiA 402 state machine (python canopen's profile) -----------------------------------
def plan_402(state: str, target: str) -> list[int]:
    """The controlwords that take a drive from ``state`` to ``target`` along canopen's CiA 402 graph.

    Each step is the transition python canopen's :class:`canopen.BaseNode402` takes
    (:class:`canopen.profiles.p402.State402`: a direct transition when the table has one,
    else the next state towards OPERATION ENABLED).  OPERATION ENABLED is reached through
    READY TO SWITCH ON (shutdown, then switch on, then enable operation) from every state,
    so an enable always switches the power stage on afresh.

    Raises
    ------
    DriveError
        ``target`` cannot be commanded (FAULT, NOT READY TO SWITCH ON) or is not reached.
    """
    from canopen.profiles.p402 import State402
    if target not in State402.SW_MASK or target in ("FAULT", "FAULT REACTION ACTIVE", "NOT READY TO SWITCH ON"):
        raise DriveError(f"CiA 402 state {target!r} cannot be commanded")
    if target == "OPERATION ENABLED":
        return _path_402(state, "READY TO SWITCH ON") + _path_402("READY TO SWITCH ON", target)
    return _path_402(state, target)


def _path_402(state: str, target: str) -> list[int]:
    """Controlwords from ``state`` to ``target``, each step as :class:`canopen.BaseNode402` takes it."""
    from canopen.profiles.p402 import State402
    out: list[int] = []
    seen = {state}
    while state != target:
        nxt = target if (state, target) in State402.TRANSITIONTABLE else State402.next_state_indirect(state)
        if nxt is None or (state, nxt) not in State402.TRANSITIONTABLE or nxt in seen:
            raise DriveError(f"CiA 402: no way from {state} to {target}")
        out.append(State402.TRANSITIONTABLE[(state, nxt)])
        seen.add(nxt)
        state = nxt
    return out


# ---- table domains 0x5100 (firmware/canopen/hd_app_co.h) --------------------------------
#: capture signal ids: SIGNALS (hd_sig_t), from fw_const

#: excitation kinds (0x5010:3, hd_exc_kind_t) and injection points (0x5010:4, hd_inj_t)
EXC_TYPES = {"steps": 1, "torque_ramp": 2, "reversal": 3, "chirp": 4, "multisine": 5, "prbs": 6}
EXC_INJECTION = {"torque": 0, "velocity": 1, "position": 2, "torque_ff": 3}
#: SI -> raw at the injection point: N.m -> 2^-16 N.m, rad/s -> 2^-32 turn/s, rad -> 2^-32 turn
EXC_SCALE = {"torque": 2.0 ** 16, "torque_ff": 2.0 ** 16, "velocity": 2.0 ** 32 / TURN, "position": 2.0 ** 32 / TURN}
#: 0x5010 sub-indices of the configuration
EXC_SUB = {"type": 3, "injection": 4, "amplitude": 5, "offset": 6, "f0": 7, "f1": 8, "duration": 9, "count": 10,
           "hold": 11, "period": 12, "steps_per_decade": 13, "rate": 14, "seed": 15}

#: parameter groups of 0x5100:2 (friction) and 0x5100:3 (TE), in the drive's order
TABLE_GROUPS = {
    2: (0x52464448, ["str_fc_pos", "str_fs_pos", "str_vs_pos", "str_fv_pos", "str_fc_neg", "str_fs_neg",
                     "str_vs_neg", "str_fv_neg", "str_delta", "str_eps_v", "str_w_ref", "str_tau_max",
                     "lug_fc", "lug_fs", "lug_vs", "lug_delta", "lug_sigma0", "lug_sigma1", "lug_sigma2",
                     "lug_k_obs", "lug_tau_max", "lug_v_src"]),
    3: (0x45544448, ["te_n", "te_k1", "te_tau_max", "te_order1", "te_amp1", "te_phase1", "te_order2",
                     "te_amp2", "te_phase2", "te_order3", "te_amp3", "te_phase3", "te_order4", "te_amp4",
                     "te_phase4"]),
}


def group_payload(sub: int, raw: dict[str, int], version: int = 1) -> bytes:
    """Payload of a parameter-group table: magic, format 1, version (1..2^31-1), count, raw int32 values."""
    if sub not in TABLE_GROUPS:
        raise DriveError(f"0x5100:{sub} is not a parameter-group table")
    if not 0 < version <= 0x7FFFFFFF:
        raise DriveError(f"0x5100:{sub}: version {version} outside 1..2147483647")
    magic, names = TABLE_GROUPS[sub]
    missing = [n for n in names if n not in raw]
    if missing:
        raise DriveError(f"0x5100:{sub}: missing {', '.join(missing)}")
    return struct.pack(f"<4I{len(names)}i", magic, 1, version, len(names), *(int(raw[n]) for n in names))


class _Collector(can.Listener):
    def __init__(self, q: list[can.Message]) -> None:
        self.q = q

    def on_message_received(self, msg: can.Message) -> None:
        self.q.append(msg)


# ---- decoding of the default stream into the log columns (docs/sim.md) ------------
def align_motor_turns(motor_turns: float, load_turns: float, ratio: float) -> float:
    """The motor's multi-turn angle (turns) that matches the load angle through the gear.

    The TPDOs carry each encoder's single-turn phase, so the motor's whole turns since
    power-on are unknown: a recording that starts them at zero puts k whole motor turns,
    k 2 pi / N at the output, into the twist theta_m / N - theta_l (0.063 rad on N = 100,
    five orders of magnitude above a real twist).  The twist of a gear is far below half a
    motor turn at the output (pi / N), so the whole turns are the k that bring
    ``motor_turns / ratio`` nearest ``load_turns``.
    """
    return motor_turns + round(ratio * load_turns - motor_turns)


__all__ = ["Drive", "DriveError", "DriveProtocolError", "DriveChoice", "add_bus_arguments", "bus_kwargs", "choose_drive",
           "SIM_INTERFACE", "SIM_AXES", "unwrap_phase", "unwrap_tick", "align_motor_turns",
           "EDS_PATH", "MODES", "plan_402", "SIGNALS", "TABLE_GROUPS", "EXC_TYPES", "EXC_INJECTION", "EXC_SCALE", "group_payload", "od_gen"]
