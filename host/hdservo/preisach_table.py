"""Everett table for the discrete Preisach model: quantisation, CRC and version.

The firmware image of a quantised Everett grid; the grid itself (density
integration, interpolation, the operator) comes from :mod:`hdservo.preisach`.

The image is shared with the firmware (``firmware/core/hd_preisach.h``):

=====  ============  =====================================================
word   field         meaning
=====  ============  =====================================================
0      magic         ``0x54504448`` ("HDPT" little-endian)
1      format        1
2      version       table version (identification run), host-assigned
3      levels        L, 2..64 grid levels
4      sub_bits      lattice steps per grid cell = 2**sub_bits (0..8)
5      in_shift      input LSB per lattice step = 2**in_shift (0..30)
6      u0            input (int32, firmware input format) at lattice 0
7      unit          0 generic, 1 torque->twist, 2 position->position
8      n_entries     L(L+1)/2
9      crc           CRC-32 (zlib) of the LE bytes of words 0..8 + entries
10..   entries       int32 E[i][j], 0 <= j <= i < L, at index i(i+1)/2 + j
=====  ============  =====================================================

``E[i][i]`` must be 0.  All words are little-endian.  The firmware refuses an
image that fails any check and keeps the previous table in force.
"""
from __future__ import annotations

import os
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path
import numpy as np

from .errors import UserError

MAGIC = 0x54504448
FORMAT = 1
L_MIN, L_MAX = 2, 64
SUB_MAX = 8
SHIFT_MAX = 30
HDR_WORDS = 9
UNIT_GENERIC, UNIT_TORQUE_TWIST, UNIT_POS_POS = 0, 1, 2


def tri_index(i: int, j: int) -> int:
    """Entry index of ``E[i][j]`` (``0 <= j <= i``)."""
    return i * (i + 1) // 2 + j


class PreisachError(UserError, ValueError):
    """A Preisach image fails a check (size, magic, format, CRC, diagonal); one line."""


@dataclass
class PreisachTable:
    """A quantised Everett table plus its lattice description.

    Attributes
    ----------
    levels : int
        Number of grid levels L (2..64).
    entries : numpy.ndarray
        int64 array of L(L+1)/2 entries (int32 range), output units (LSB of the
        firmware output format).
    sub_bits, in_shift, u0, unit, version : int
        See the module docstring.
    """

    levels: int
    entries: np.ndarray
    sub_bits: int = 0
    in_shift: int = 0
    u0: int = 0
    unit: int = UNIT_GENERIC
    version: int = 1
    magic: int = MAGIC
    fmt: int = FORMAT
    crc: int | None = field(default=None)

    @property
    def p_top(self) -> int:
        """Lattice size P = (L - 1) * 2**sub_bits."""
        return (self.levels - 1) << self.sub_bits

    def header_words(self) -> list[int]:
        """Words 0..8 (unsigned 32-bit)."""
        return [self.magic, self.fmt, self.version, self.levels, self.sub_bits,
                self.in_shift, self.u0 & 0xFFFFFFFF, self.unit, len(self.entries)]

    def compute_crc(self) -> int:
        """CRC-32 (zlib) over the header words 0..8 and the entries."""
        body = struct.pack("<9I", *self.header_words())
        body += np.asarray(self.entries, dtype="<i4").tobytes()
        return zlib.crc32(body) & 0xFFFFFFFF

    def seal(self) -> "PreisachTable":
        """Set the CRC from the content; returns self."""
        self.crc = self.compute_crc()
        return self

    def words(self) -> np.ndarray:
        """The whole image as uint32 words (header, crc, entries)."""
        if self.crc is None:
            self.seal()
        hdr = np.array(self.header_words() + [self.crc], dtype=np.uint64)
        ent = np.asarray(self.entries, dtype=np.int64) & 0xFFFFFFFF
        return np.concatenate([hdr, ent.astype(np.uint64)]).astype(np.uint32)

    def to_bytes(self) -> bytes:
        """Little-endian image (what is downloaded to the drive)."""
        return self.words().astype("<u4").tobytes()

    @classmethod
    def from_bytes(cls, data: bytes) -> "PreisachTable":
        """Parse and validate an image; raises :class:`PreisachError` (a ValueError) naming the failed check."""
        if len(data) < 40 or len(data) % 4:
            raise PreisachError(f"Preisach image: {len(data)} bytes, expected 40 + 4*n")
        w = struct.unpack(f"<{len(data) // 4}I", data)
        magic, fmt, version, levels, sub_bits, in_shift, u0, unit, n, crc = w[:10]
        if magic != MAGIC:
            raise PreisachError(f"Preisach image: magic 0x{magic:08x}, expected 0x{MAGIC:08x}")
        if fmt != FORMAT:
            raise PreisachError(f"Preisach image: format {fmt}, expected {FORMAT}")
        if not (L_MIN <= levels <= L_MAX) or sub_bits > SUB_MAX or in_shift > SHIFT_MAX \
                or n != levels * (levels + 1) // 2 or len(w) != 10 + n:
            raise PreisachError("Preisach image: inconsistent sizes")
        ent = np.array(w[10:], dtype=np.int64)
        ent = np.where(ent >= 2**31, ent - 2**32, ent)
        u0s = u0 - 2**32 if u0 >= 2**31 else u0
        t = cls(levels=levels, entries=ent, sub_bits=sub_bits, in_shift=in_shift, u0=u0s,
                unit=unit, version=version, crc=crc)
        if t.compute_crc() != crc:
            raise PreisachError("Preisach image: CRC mismatch")
        if any(ent[tri_index(i, i)] != 0 for i in range(levels)):
            raise PreisachError("Preisach image: non-zero diagonal entry")
        return t

    @classmethod
    def read(cls, path: "str | os.PathLike[str]") -> "PreisachTable":
        """:meth:`from_bytes` of a file; PreisachError (one line, naming the file) when unreadable or bad."""
        p = Path(path)
        try:
            data = p.read_bytes()
        except OSError as e:
            raise PreisachError(f"{p}: cannot read: {e.strerror or e}") from None
        try:
            return cls.from_bytes(data)
        except PreisachError as e:
            raise PreisachError(f"{p}: {e}") from None

    def grid(self) -> np.ndarray:
        """Full L x L array with E[i][j] (zeros above the diagonal), int64."""
        g = np.zeros((self.levels, self.levels), dtype=np.int64)
        for i in range(self.levels):
            for j in range(i + 1):
                g[i, j] = self.entries[tri_index(i, j)]
        return g


def quantise_everett(everett: np.ndarray, scale: float, **kw: int) -> PreisachTable:
    """Quantise a double Everett grid to a sealed table.

    Parameters
    ----------
    everett : numpy.ndarray
        L x L array, ``everett[i, j] = E(alpha_i, beta_j)`` for ``j <= i`` in output
        units (e.g. rad of twist); the upper triangle is ignored.
    scale : float
        Output LSB per output unit (e.g. ``2**32 / (2*pi)`` for rad -> 2^-32 turn).
    **kw
        ``sub_bits``, ``in_shift``, ``u0``, ``unit``, ``version``.

    Returns
    -------
    PreisachTable
        Entries rounded to nearest (half away from zero), diagonal forced to 0,
        saturated to int32, CRC set.
    """
    e = np.asarray(everett, dtype=float)
    levels = e.shape[0]
    if not (L_MIN <= levels <= L_MAX) or e.shape != (levels, levels):
        raise ValueError(f"Everett grid must be L x L with {L_MIN} <= L <= {L_MAX}")
    ent = np.zeros(levels * (levels + 1) // 2, dtype=np.int64)
    for i in range(levels):
        for j in range(i):
            x = e[i, j] * scale
            r = np.sign(x) * np.floor(abs(x) + 0.5)
            ent[tri_index(i, j)] = int(np.clip(r, -2**31, 2**31 - 1))
    return PreisachTable(levels=levels, entries=ent, **kw).seal()
