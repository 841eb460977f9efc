#!/usr/bin/env python3
"""Write the committed seed corpora of the libFuzzer targets (tests/fuzz/corpus/).

Run from the repository root: ``python3 tests/fuzz/gen_seeds.py``.  The seeds
are small, hand-made inputs that reach each target's deep paths at once
(valid images, complete SDO transfers, parameter saves); libFuzzer mutates
from there.  Text seeds of the TOML reader are the repository's own scenario
and axis files plus a few edge cases.  Deterministic: re-running rewrites the
same files.
"""
from __future__ import annotations

import shutil
import struct
import zlib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "tests" / "fuzz" / "corpus"
NODE = 5


def write(target: str, name: str, data: bytes) -> None:
    d = OUT / target
    d.mkdir(parents=True, exist_ok=True)
    (d / name).write_bytes(data)


def tri(i: int) -> int:
    return i * (i + 1) // 2


def preisach_image(levels: int, sub: int, shift: int, u0: int) -> bytes:
    e = [0] * tri(levels)
    for i in range(levels):
        for j in range(i):
            e[tri(i) + j] = (i - j) * (i - j) * 37
    hdr = struct.pack("<9I", 0x54504448, 1, 3, levels, sub, shift, u0 & 0xFFFFFFFF, 0, len(e))
    body = struct.pack(f"<{len(e)}i", *e)
    crc = zlib.crc32(hdr + body) & 0xFFFFFFFF
    return hdr + struct.pack("<I", crc) + body


def seeds_toml() -> None:
    for src in sorted((ROOT / "sim" / "scenarios").glob("*.toml")) + sorted((ROOT / "sim" / "axes").glob("*.toml")):
        (OUT / "toml").mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, OUT / "toml" / src.name)
    write("toml", "edge_strings.toml",
          b'a = "x\\"y\\\\z\\n"\nb = \'lit\'\n"quoted key" = 1_000\n[s.t]\nc.d = -1.5e-3\n'
          b'arr = [1, 2.5,\n  -inf, ]\nsarr = ["a", "b"]\n[[fault]]\nt_s = 0.1\n[[fault]]\nt_s = 0.2\nflag = true\n')
    write("toml", "bad_nan.toml", b"x = nan\n")
    write("toml", "bad_inline.toml", b"x = { a = 1 }\n")
    write("toml", "bad_unterminated.toml", b'x = "abc\n')
    write("toml", "dup.toml", b"x = 1\nx = 2\n")


def seeds_preisach() -> None:
    img = preisach_image(8, 1, 12, -(1 << 15))
    moves = b"".join(bytes([op]) + struct.pack("<i", v)
                     for op, v in [(1, 0), (1, 20000), (1, -3000), (1, 9000), (0, 5), (2, 100), (5, 7), (9, -5)])
    write("preisach", "raw_valid_L8", b"\x00" + img + b"\x01" + moves)
    write("preisach", "raw_valid_L8_badcrc", b"\x00" + img[:36] + b"\0\0\0\0" + img[40:])
    write("preisach", "raw_valid_L3", b"\x00" + preisach_image(3, 0, 0, 0) + b"\x00" + moves)
    # structured + diagonal + seal: levels 16, sub 2, shift 8
    e16 = b"".join(struct.pack("<h", (k * 13) % 500) for k in range(tri(16)))
    write("preisach", "sealed_L16_i16",
          bytes([0x0F, 16, 2, 8]) + struct.pack("<i", -4096) + bytes([1, 0]) + b"\0\0\0\0" + e16 + b"\x02" + moves * 4)
    e64 = b"".join(struct.pack("<h", k % 97) for k in range(tri(64)))
    write("preisach", "sealed_L64_sub8", bytes([0x0F, 64, 8, 0]) + b"\0\0\0\0" + bytes([2, 2]) + b"\0\0\0\0" + e64 + b"\x00" + moves)


def seeds_pstore() -> None:
    write("pstore", "valid_both", b"\x00\x03")
    write("pstore", "flip_slot1_crc", b"\x00\x05" + struct.pack("<HB", 1024 + 20, 0x01))
    write("pstore", "flip_slot1_resealed", b"\x04\x05" + struct.pack("<HB", 1024 + 30, 0x80))
    write("pstore", "seq_wrap", b"\x10\x01" + struct.pack("<I", 0xFFFFFFFF))
    write("pstore", "seq_half", b"\x16\x07" + struct.pack("<I", 0x7FFFFFFF) + struct.pack("<HB", 8, 0x80) + struct.pack("<HB", 1024 + 8, 0x01))
    write("pstore", "read_fail", b"\x08\x00")
    write("pstore", "raw_blank", b"\x01" + b"\xff" * 64)
    # a record header of the record store (magic, format, sequence, words) and two payload words
    write("pstore", "raw_magic_only", b"\x01" + struct.pack("<6I", 0x53504448, 1, 1, 2, 1, 0))


def rec(op: int, arg: int, val: int) -> bytes:
    return bytes([op, arg]) + struct.pack("<i", val)


def seeds_params() -> None:
    write("params", "set_run_save",
          rec(0, 6, 100 << 16) + rec(1, 3, 0) + rec(5, 0, 1000) + rec(2, 15, 0x00101010) +
          rec(1, 0, 0) + rec(4, 0, 0) + rec(7, 9, 1) + rec(4, 0, 0))
    write("params", "limits_fault_reset",
          rec(7, 30, 0) + rec(7, 31, 0) + rec(1, 1, 0) + rec(5, 2, 0x7FFFFFFF) + rec(2, 15, 0x7FF) +
          rec(2, 0x85, 1) + rec(3, 0, 0) + rec(1, 2, 0) + rec(5, 1, -5000000) + rec(2, 15, -0x7FFFF))
    write("params", "bad_ids", rec(0, 41, 1) + rec(0, 42, 1) + rec(0, 0, -1) + rec(1, 9, 0))
    write("params", "ptp_rate", rec(1, 4, 0) + rec(6, 0, 1 << 20) + rec(2, 15, 0x100) + rec(1, 5, 0) +
          rec(6, 4, 1 << 24) + rec(2, 15, 0x100) + rec(1, 6, 0) + rec(2, 15, 3))


def frame(kind: int, cob: int, data: bytes, dlc: int | None = None) -> bytes:
    d = data.ljust(8, b"\0")
    return bytes([kind]) + struct.pack("<H", cob) + bytes([len(data) if dlc is None else dlc]) + d


def sdo(data: bytes) -> bytes:
    return frame(0, 0x600 + NODE, data, 8)


def seeds_canopen() -> None:
    up = sdo(bytes([0x40, 0x00, 0x10, 0]))                          # read 0x1000
    wr = sdo(bytes([0x2B, 0x17, 0x10, 0, 0xF4, 0x01]))             # 0x1017 = 500 ms
    par = sdo(bytes([0x23, 0x00, 0x20, 0x07, 0, 0, 0x64, 0]))      # a manufacturer parameter
    write("canopen", "expedited", up + wr + par + frame(3, 200, b"") + up)
    # settings, 0x1010 save, changed again, NMT reset communication (back to the saved ones),
    # 0x1011 restore
    save = sdo(bytes([0x23, 0x10, 0x10, 1, 0x73, 0x61, 0x76, 0x65]))
    load = sdo(bytes([0x23, 0x11, 0x10, 1, 0x6C, 0x6F, 0x61, 0x64]))
    write("canopen", "save_reset_restore", wr + sdo(bytes([0x23, 0x65, 0x60, 0, 0xE8, 0x03, 0, 0])) + save +
          sdo(bytes([0x2B, 0x17, 0x10, 0, 0x64, 0])) + frame(1, 0x000, bytes([0x82, NODE])) + frame(3, 5, b"") +
          up + load + frame(1, 0x000, bytes([0x81, 0])) + frame(3, 5, b""))
    nmt = frame(1, 0x000, bytes([0x01, NODE]))
    sync = frame(1, 0x080, b"")
    write("canopen", "nmt_sync_rpdo", nmt + sync + frame(1, 0x200 + NODE, bytes([0x06, 0]), 2) +
          frame(1, 0x200 + NODE, bytes([0x0F, 0]), 2) + sync + frame(3, 10, b"") + frame(1, 0x000, bytes([0x80, 0])))
    # segmented download of a Preisach table (0x5100:1), then segmented upload
    img = preisach_image(3, 0, 0, 0)
    seq = sdo(bytes([0x21, 0x00, 0x51, 1]) + struct.pack("<I", len(img)))
    t = 0
    for i in range(0, len(img), 7):
        chunk = img[i:i + 7]
        last = i + 7 >= len(img)
        cmd = (t << 4) | ((7 - len(chunk)) << 1) | (1 if last else 0)
        seq += sdo(bytes([cmd]) + chunk)
        t ^= 1
    seq += sdo(bytes([0x40, 0x00, 0x51, 1])) + sdo(bytes([0x60])) + sdo(bytes([0x70])) + sdo(bytes([0x60]))
    write("canopen", "segmented_table", seq)
    # block download with CRC, then block upload
    blk = sdo(bytes([0xC6, 0x00, 0x51, 1]) + struct.pack("<I", len(img)))
    n = 0
    for i in range(0, len(img), 7):
        n += 1
        chunk = img[i:i + 7].ljust(7, b"\0")
        last = i + 7 >= len(img)
        blk += sdo(bytes([(0x80 if last else 0) | n]) + chunk)
    pad = (7 - len(img) % 7) % 7
    crc = zlib.crc32(b"")  # placeholder: the server CRC is CRC-16, a wrong one exercises the abort
    blk += sdo(bytes([0xC1 | (pad << 2)]) + struct.pack("<H", crc & 0xFFFF))
    blk += sdo(bytes([0xA4, 0x00, 0x51, 1, 16, 0])) + sdo(bytes([0xA3])) + sdo(bytes([0xA2, 16, 16])) + sdo(bytes([0xA1]))
    write("canopen", "block_table", blk)
    # CiA 402 enable sequence through SDO on 0x6040, with ticks
    cw = b"".join(sdo(bytes([0x2B, 0x40, 0x60, 0, v, 0])) + frame(3, 2, b"") for v in (0x06, 0x07, 0x0F, 0x80))
    write("canopen", "cia402", sdo(bytes([0x2F, 0x60, 0x60, 0, 8])) + cw)
    write("canopen", "bad_dlc", frame(0, 0x600 + NODE, bytes([0x40, 0, 0x10, 0]), 3) + frame(1, 0x000, b"\x01", 15))


def seeds_tstore() -> None:
    # table region of fuzz_tstore: slot 0 at 0, slot 1 at 9 KiB (1 KiB pages)
    write("tstore", "valid_both", b"\x00\x0e\x1e")
    write("tstore", "valid_then_none", b"\x10\x3e\x00")
    write("tstore", "flip_slot1_image", b"\x00\x0e\x1e" + struct.pack("<HB", 9216 + 60, 0x01))
    write("tstore", "flip_slot1_resealed", b"\x04\x0e\x1e" + struct.pack("<HB", 9216 + 16 + 4 * 12, 0x04))
    write("tstore", "flip_count_resealed", b"\x02\x0e\x1e" + struct.pack("<HB", 12, 0x02))
    write("tstore", "read_fail", b"\x08\x05\x05")
    write("tstore", "raw_blank", b"\x01" + b"\xff" * 64)
    write("tstore", "raw_header_only", b"\x01" + struct.pack("<4I", 0x53544448, 1, 1, 10))


def plant_param_names() -> list[str]:
    """Parameter names in the plant table's order (fuzz_plant reads one selector byte each),
    from build/lib/libhdsim.so; empty when it is not built."""
    import ctypes
    lib_path = ROOT / "build" / "lib" / "libhdsim.so"
    if not lib_path.exists():
        return []
    lib = ctypes.CDLL(str(lib_path))
    lib.hd_simlib_param_name.restype = ctypes.c_char_p
    lib.hd_simlib_param_name.argtypes = [ctypes.c_int32]
    return [lib.hd_simlib_param_name(i).decode() for i in range(lib.hd_simlib_param_count())]


def seeds_plant() -> None:
    # layout of fuzz_plant: defaults (0 reference, 1 minimal), mode (0 position, 1 velocity,
    # 2 torque, 3 off, 4 stabilise), periods - 20, amplitude (int8, 2^-k), then one selector
    # byte per plant parameter (15 = keep; for numbers 0 min, 1 max, 2 zero, 3 tiny, 5 1e9 ...;
    # for bools 96 = off, 97 = on), then the seed byte and the open-loop inputs
    names = plant_param_names()
    if not names:
        print("plant: build/lib/libhdsim.so not built, seeds skipped (make sim)")
        return
    keep = [15] * len(names)
    inputs = bytes([7, 40]) + b"\x00\x10\x00\x00\x05\x00" * 40

    def sel(**over: int) -> bytes:
        b = list(keep)
        for k, v in over.items():
            b[names.index(k.replace("__", "."))] = v
        return bytes(b)

    head = bytes([0, 0, 100, 10, 12])
    write("plant", "reference_step", head + sel() + bytes([1]) + inputs)
    write("plant", "minimal_velocity", bytes([1, 1, 80, 20, 8]) + sel() + bytes([2]) + inputs)
    for m, name in enumerate(["position", "velocity", "torque", "off", "stabilise"]):
        write("plant", f"mode_{name}", bytes([0, m, 60, 0x7F, 2]) + sel() + bytes([3]) + inputs)
    stiff = {k: 5 for k in ("stiffness__k1_Nm_per_rad", "stiffness__k2_Nm_per_rad", "stiffness__k3_Nm_per_rad",
                            "stiffness_cubic__k1_Nm_per_rad", "stiffness_cubic__k3_Nm_per_rad3")}
    write("plant", "diverge_stiff_1e9_preisach", head + sel(**stiff) + bytes([1]) + inputs)
    bools = [i for i, n in enumerate(names) if n.endswith("enabled")]
    on, off = list(keep), list(keep)
    for i in bools:
        on[i], off[i] = 97, 96
    write("plant", "every_effect_on", head + bytes(on) + bytes([1]) + inputs)
    write("plant", "every_effect_off", head + bytes(off) + bytes([1]) + inputs)
    write("plant", "all_min", head + bytes([0] * len(names)) + bytes([1]) + inputs)
    write("plant", "all_max", head + bytes([1] * len(names)) + bytes([1]) + inputs)
    write("plant", "all_zero_tiny", head + bytes([2, 3] * len(names))[:len(names)] + bytes([1]) + inputs)


def chunks(data: bytes, size: int, limit: int) -> bytes:
    """The chunk framing of fuzz_socketcand: a length byte (len - 1) before each chunk."""
    out = b""
    for i in range(0, len(data), size):
        c = data[i:i + size]
        assert len(c) <= limit
        out += bytes([len(c) - 1]) + c
    return out


def seeds_socketcand() -> None:
    # fuzz_socketcand: selector (even = socketcand server, odd = rig channel); server: the
    # handshake stage (0 after "< hi >", 1 after open, 2 streaming), then chunks (length
    # byte < 240 + bytes) and drive frames (byte >= 240 + id u32, dlc, 8 data, dt u32)
    hs = b"< open can0 >< rawmode >"
    sends = (b"< send 601 8 40 0 10 0 0 0 0 0 >< send 0 2 1 5 >< send 80 0 >"
             b"< send 1FFFFFFF 8 FF FF FF FF FF FF FF FF >< echo >")
    write("socketcand", "handshake_and_sends", b"\x00\x00" + chunks(hs + sends, 13, 96))
    write("socketcand", "bytewise", b"\x00\x00" + chunks(hs + sends[:60], 1, 96))
    write("socketcand", "streaming_bad",
          b"\x00\x02" + chunks(b"< send 800 1 0 >< send 1 9 0 >< send 123456789 0 >< send 1 1 100 >"
                               b"<<< > garbage >> < send   1   1   AB   >< send 1 1 0 0 >", 40, 96))
    frame = bytes([0xF1]) + struct.pack("<I", 0x181) + bytes([8]) + bytes(range(8)) + struct.pack("<I", 100)
    write("socketcand", "frames_out", b"\x00\x02" + frame * 3 + chunks(b"< send 181 1 1 >", 16, 96))
    write("socketcand", "overlong", b"\x00\x02" + chunks(b"<" + b"x" * 300 + b">< send " + b"F" * 40 + b" 1 1 >", 90, 96))
    rig = (b"brake 1\nbrake 0\ntorque 1.5 10\nthen -2 5\nthen 0 1\nstatus\n"
           b"record /dev/null 10\nrecord stop\ncan drop 0.5 7\ncan errors 10 3\ncan busoff\ncan status\n"
           b"torque nan\nthen 1 0\ncan drop 2\nbogus\n\n   \t\r\n")
    write("socketcand", "rig_commands", b"\x01" + chunks(rig, 17, 128))
    write("socketcand", "rig_too_long", b"\x01" + chunks(b"torque " + b"9" * 1100 + b"\nstatus\n", 100, 128))


# ---- fuzz_appco: operation records (see the header of tests/fuzz/fuzz_appco.c) ----------
def a_nmt(i: int) -> bytes:        # 0 start, 1 stop, 2 pre-op, 3 reset node, 4 reset comm
    return bytes([8, i])


def a_walk(mode: int, rpdo: bool = False, per: int = 1) -> bytes:  # mode 0 PP, 1 CSP, 2 CSV, 3 CST, 4 STAB
    return bytes([10, mode | ((per - 1) << 3) | (0x80 if rpdo else 0)])


def a_periods(n: int, how: int = 0) -> bytes:  # how 0 follows the reference, 1 at rest
    return bytes([9 | (how << 4), (n - 1) % 32])


def a_misc(kind: int, arg: int = 0) -> bytes:  # 0 save, 1 restore, 2 capture arm, 3 trigger, 4/5 excitation, 7 options
    return bytes([13, kind]) + struct.pack("<I", arg & 0xFFFFFFFF)


def a_table(kind: int, arg: int, bad: int = 0, block: bool = False) -> bytes:  # kind 0 Preisach, 1 friction, 2 TE
    return bytes([4 if block else 2, kind]) + struct.pack("<I", arg) + bytes([bad])


def a_segments(n: int = 16) -> bytes:
    return bytes([3, n - 1])


def a_upload(sub: int, block: bool = False, segs: int = 256) -> bytes:  # sub 0 capture data, 1..3 tables
    return bytes([5, sub | (4 if block else 0) | (((segs - 8) // 8) << 3)])


def capture_arg() -> int:
    # signals 5 (output velocity), 11 (torque command) and a third from byte 2; length,
    # decimation and pre-trigger come from the same word (op_misc in fuzz_appco.c)
    for x in list(range(17)) + [0xFF]:
        a = 0xFF000000 | (x << 16) | 0x0B05
        length = (a >> 4) % 700
        pre = (a >> 16) % 300
        if length >= 100 and pre < length // 2:
            return a
    raise SystemExit("no capture argument")


def od_entry(index: int, sub: int) -> int:
    """Position of (index, sub) in the generated object dictionary table hd_co_od[]."""
    rows = [ln for ln in (ROOT / "firmware" / "canopen" / "hd_co_od.c").read_text().splitlines()
            if ln.startswith("    {0x")]
    key = f"{{0x{index:04X}u, {sub}u,"
    return next(i for i, ln in enumerate(rows) if ln.startswith("    " + key))


def a_write(index: int, sub: int, value: int) -> bytes:
    return bytes([0]) + struct.pack("<HIB", od_entry(index, sub), value & 0xFFFFFFFF, 0)


def pmut(how: int, pid: int, raw: int = 0) -> bytes:
    """One change of a crafted parameter record (how: 0 min-1, 1 max+1, 2 min, 3 max, 4 any word)."""
    return bytes([how, pid]) + struct.pack("<I", raw)


def omut(how: int, a: int, raw: int = 0) -> bytes:
    """One change of a crafted object record (how: 0 RPDO mapping -> object raw = index << 8 | sub,
    1 a bare COB-ID, 2 one bit flipped, 3 any value)."""
    return bytes([how]) + struct.pack("<HI", a, raw)


def seeds_appco() -> None:
    start = a_nmt(0)
    write("appco", "walk_op_enabled", start + a_walk(1) + a_periods(20) + a_walk(0, rpdo=True) + a_periods(30) +
          a_walk(2, per=2) + a_periods(10))
    for i, name in ((1, "stop"), (2, "preop"), (4, "reset_comm"), (3, "reset_node")):
        write("appco", f"nmt_{name}_while_enabled", start + a_walk(1) + a_periods(5) + a_nmt(i) + a_periods(5))
    write("appco", "nmt_stop_quick_stop_option", a_misc(7, 3 | (2 << 8)) + start + a_walk(2) + a_periods(5) +
          a_nmt(1) + a_periods(30))
    write("appco", "busoff_while_enabled", start + a_walk(1) + a_periods(5) + bytes([14, 1, 0]) + a_periods(31))
    write("appco", "staging_commit", a_table(0, 2) + a_segments() + a_segments() + a_table(1, 5) + a_segments() +
          a_segments() + a_table(2, 9 | (3 << 24), block=True) + a_upload(1) + a_upload(2, block=True) +
          a_upload(3) + a_misc(0) + bytes([11]) + a_upload(1))
    write("appco", "staging_bad", a_table(0, 3, bad=1) + a_segments() + a_segments() + a_table(1, 5, bad=4, block=True) +
          a_table(2, 1, bad=2) + a_segments() + a_segments() + a_table(0, 4, bad=0x40, block=True))
    write("appco", "commit_while_enabled", a_table(0, 2) + a_segments(4) + start + a_walk(1, rpdo=True) +
          a_periods(3) + a_segments() + a_segments() + a_periods(2))
    cap = capture_arg()
    write("appco", "capture_read", start + a_walk(1) + a_misc(2, cap) + a_periods(10) + a_misc(3) + a_periods(32) +
          a_periods(32) + a_periods(32) + a_upload(0, segs=256) + a_upload(0, block=True, segs=64))
    write("appco", "excitation", start + a_walk(1) + a_misc(2, cap) + a_misc(4, 2 | (1 << 3) | (0x400 << 8) | (1000 << 20)) +
          a_periods(32) + a_periods(32) + a_misc(5) + a_periods(4) + a_upload(0, segs=64))
    write("appco", "crafted_params", bytes([12, 0 | (1 << 1)]) + pmut(2, 6) + pmut(3, 9) + a_periods(2) +
          bytes([12, 0]) + pmut(0, 7) + bytes([12, 0]) + pmut(4, 0, 0x0100 * 7 + 3))
    write("appco", "crafted_objects", bytes([12, 1]) + omut(0, 0, 0x604100) + a_periods(2) + bytes([12, 1]) +
          omut(1, 3, 0x0) + bytes([12, 1 | (2 << 1)]) + omut(2, 5, 7) + omut(3, 9, 0x12345678) + omut(2, 1, 31))
    write("appco", "save_restore_reboot", a_misc(7, 2) + a_table(1, 77) + a_segments() + a_segments() + a_misc(0) +
          bytes([11]) + a_misc(6, 4) + a_misc(1) + a_misc(0) + bytes([11]) + a_misc(6, 1))
    write("appco", "shutdown_while_enabled", start + a_walk(1) + a_periods(5) + a_write(0x6040, 0, 0x06) +
          a_periods(3) + a_write(0x6040, 0, 0x0F) + a_periods(3) + a_write(0x6040, 0, 0x02) + a_periods(31))
    # TPDO 1 moved to a restricted COB-ID (0x581: SDO replies of node 1), then OPERATIONAL
    write("appco", "tpdo_restricted_cobid", a_write(0x1800, 1, 0x80000185) + a_write(0x1800, 1, 0x581) + start +
          a_periods(3))


def main() -> None:
    seeds_toml()
    seeds_preisach()
    seeds_pstore()
    seeds_tstore()
    seeds_params()
    seeds_canopen()
    seeds_plant()
    seeds_socketcand()
    seeds_appco()
    for d in sorted(OUT.iterdir()):
        print(f"{d.name}: {len(list(d.iterdir()))} seeds")


if __name__ == "__main__":
    main()
