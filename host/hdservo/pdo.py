"""The drive's PDOs through the EDS's PDO maps (python ``canopen``): TPDOs decoded, RPDOs encoded.

The drive's default transmit PDOs are defined once, in ``firmware/params/canopen.toml``,
from which the EDS (``hdservo/data/hdservo.eds``) and the DBC are generated.  This
module reads the EDS's PDO communication and mapping objects with canopen's
:meth:`canopen.pdo.PdoMap.read` (``from_od=True``) and decodes frames with the
map's variables (and encodes the set-point RPDOs the same way), so no COB-ID, byte
offset or data type is written here.  A byte-aligned map (all of the drive's) is compiled
once into a :class:`struct.Struct` from the offsets of canopen's map and the EDS data
types (about 4 us a frame against 17 us through canopen's variables on the development
machine; the stream's three TPDOs come at up to 3 x 10 kHz); a map with bit fields is
decoded by canopen itself.  With the shipped EDS:

=====  ==============  ===================================================================
PDO    COB-ID          mapped objects (names as in the EDS)
=====  ==============  ===================================================================
TPDO1  0x180 + node    statusword, modes_of_operation_display, error_register, loop_tick
TPDO2  0x280 + node    loop_tick, load_phase
TPDO3  0x380 + node    loop_tick, motor_phase
TPDO4  0x480 + node    loop_tick, motor_torque
RPDO1  0x200 + node    controlword, modes_of_operation
RPDO2  0x300 + node    target_position, velocity_offset
RPDO3  0x400 + node    target_velocity, target_torque, torque_offset
=====  ==============  ===================================================================

Example
-------
>>> dec = PdoDecoder(node_id=1)
>>> dec.cob_id(2)
641
>>> dec.decode(0x281, bytes.fromhex("0a00000000000080"))
Frame(pdo=2, values={'loop_tick': 10, 'load_phase': 2147483648})
"""
from __future__ import annotations

import struct
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import canopen

from . import resources

#: the streaming TPDOs of ``hdservo record`` and the identification (tick + one signal each)
STREAM_PDOS = (2, 3, 4)
#: the TPDO that answers SYNC in lock-step (statusword, mode, error register, tick)
STATUS_PDO = 1


@dataclass(frozen=True)
class Frame:
    """One decoded TPDO.

    Attributes
    ----------
    pdo : int
        TPDO number (1..4).
    values : dict of str to int
        Raw value of every mapped object by its EDS name (the sub-object's name for a
        record member, e.g. ``loop_tick`` in 100 us ticks, ``load_phase`` in 2^-32 turn).
    """

    pdo: int
    values: dict[str, int]

    @property
    def tick(self) -> int:
        """The drive's 32-bit loop tick of the frame (0x5F00:1; every default TPDO carries it)."""
        return int(self.values["loop_tick"])


def _short(name: str) -> str:
    """``drive_status.loop_tick`` -> ``loop_tick`` (the member's name)."""
    return name.rsplit(".", 1)[-1]


def _compile(m: "canopen.pdo.PdoMap") -> Optional[tuple[list[str], struct.Struct]]:
    """One :class:`struct.Struct` for a byte-aligned map (offsets and types from canopen's map
    and the EDS data types); None for a map with bit fields (decoded by canopen itself)."""
    fmt, pos, names = "<", 0, []
    for v in m:
        st = v.od.STRUCT_TYPES.get(v.od.data_type)
        if st is None or v.offset % 8 or v.length % 8 or v.offset < pos or st.size * 8 != v.length:
            return None
        if v.offset > pos:
            fmt += f"{(v.offset - pos) // 8}x"
        fmt += st.format.lstrip("<")
        pos = v.offset + v.length
        names.append(_short(v.name))
    return names, struct.Struct(fmt)


class PdoDecoder:
    """The drive's transmit PDO maps as the EDS defines them, for one node id.

    Parameters
    ----------
    node_id : int
        CANopen node id of the drive (the EDS's ``$NODEID`` COB-IDs follow it).
    eds : path or canopen.ObjectDictionary, optional
        EDS file, or the dictionary already read from it (default: the package's ``hdservo.eds``).

    Notes
    -----
    The maps live on a private, unconnected :class:`canopen.Network`: decoding sends
    nothing and is independent of the network the drive is on.  :meth:`decode` is
    thread-safe (a CAN notifier thread and the caller may share one decoder).
    """

    def __init__(self, node_id: int, eds: "Path | str | canopen.ObjectDictionary | None" = None) -> None:
        self.node_id = int(node_id)
        od = eds if isinstance(eds, canopen.ObjectDictionary) else str(eds if eds is not None else resources.eds_path())
        self._node = canopen.RemoteNode(self.node_id, od)
        canopen.Network().add_node(self._node)          # a network to subscribe to, never connected
        self._node.tpdo.read(from_od=True)
        self._node.rpdo.read(from_od=True)
        self._by_cob = {m.cob_id: (n, m) for n, m in self._node.tpdo.map.items() if m.enabled and len(m)}
        self._lock = threading.Lock()
        self._fast = {cob: _compile(m) for cob, (_, m) in self._by_cob.items()}
        self._rx = {n: (m.cob_id, _compile(m)) for n, m in self._node.rpdo.map.items() if m.enabled and len(m)}

    def cob_id(self, pdo: int) -> int:
        """The COB-ID of TPDO ``pdo`` (1-based).

        Raises
        ------
        KeyError
            The EDS has no enabled TPDO of that number.
        """
        for cob, (n, _) in self._by_cob.items():
            if n == pdo:
                return int(cob)
        raise KeyError(f"TPDO{pdo}: not enabled in the EDS")

    def names(self, pdo: int) -> list[str]:
        """The mapped objects of TPDO ``pdo``, in frame order (names as in :class:`Frame`)."""
        return [_short(v.name) for v in self._node.tpdo[pdo]]

    def pdo_of(self, cob_id: int) -> Optional[int]:
        """The TPDO number of a COB-ID, None for any other frame."""
        hit = self._by_cob.get(cob_id)
        return None if hit is None else hit[0]

    def decode(self, cob_id: int, data: bytes) -> Optional[Frame]:
        """Decode one frame; None when it is not one of the TPDOs or shorter than its map."""
        hit = self._by_cob.get(cob_id)
        if hit is None:
            return None
        n, m = hit
        if len(data) < m.length // 8:
            return None
        fast = self._fast[cob_id]
        if fast is not None:
            names, st = fast
            return Frame(n, dict(zip(names, st.unpack_from(data))))
        with self._lock:                               # canopen decodes through the map's one buffer
            m.data = bytearray(data)
            values = {_short(v.name): int(v.raw) for v in m}
        return Frame(n, values)

    def encode(self, pdo: int, **values: int) -> tuple[int, bytes]:
        """COB-ID and data of RPDO ``pdo`` with raw ``values`` by object name (an object left out is 0).

        Raises
        ------
        KeyError
            No enabled RPDO of that number, or a name it does not map.
        """
        if pdo not in self._rx:
            raise KeyError(f"RPDO{pdo}: not enabled in the EDS")
        cob, fast = self._rx[pdo]
        if fast is None:
            raise KeyError(f"RPDO{pdo}: bit-field mappings are not supported")
        names, st = fast
        unknown = sorted(set(values) - set(names))
        if unknown:
            raise KeyError(f"RPDO{pdo} maps {', '.join(names)}, not {', '.join(unknown)}")
        return int(cob), st.pack(*(int(values.get(n, 0)) for n in names))

    def rpdo_names(self, pdo: int) -> list[str]:
        """The mapped objects of RPDO ``pdo``, in frame order."""
        return [_short(v.name) for v in self._node.rpdo[pdo]]


#: the same object under the name of what it also does
PdoCodec = PdoDecoder

__all__ = ["Frame", "PdoCodec", "PdoDecoder", "STATUS_PDO", "STREAM_PDOS"]
