"""CAN benchmark of the virtual drive over socketcand -> build/bench/can.json.

Measures (never fails on time): SDO expedited round-trip latency, block
transfer throughput (64 KiB domain down and up, CRC on), and the highest
loss-free streaming sample rate (one TPDO: loop tick + one value) over the raw
socketcand link and with the 1 Mbit/s bus model on, plus the full-sample rate
(three TPDOs: output angle, motor angle, motor torque, each with the tick).
"""
from __future__ import annotations

import json
import logging
import queue
import statistics
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

import can
import canopen

ROOT = Path(__file__).resolve().parents[2]
SIM = ROOT / "build" / "bin" / "hdservo-sim"
EDS = ROOT / "host" / "hdservo" / "data" / "hdservo.eds"
OUT = ROOT / "build" / "bench" / "can.json"
logging.getLogger("can.interfaces.socketcand").setLevel(logging.ERROR)


def serve(*extra: str) -> tuple[subprocess.Popen, int]:
    p = subprocess.Popen([str(SIM), "serve", "--port", "0", *extra], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    line = p.stdout.readline() if p.stdout else ""
    return p, int(line.strip().rsplit(":", 1)[1])


def stop(p: subprocess.Popen) -> dict:
    p.terminate()
    try:
        p.wait(10)
    except subprocess.TimeoutExpired:
        p.kill()
    err = p.stderr.read() if p.stderr else ""
    for line in err.splitlines():
        if line.startswith("{"):
            return json.loads(line)
    return {}


def connect(port: int) -> tuple[canopen.Network, canopen.RemoteNode]:
    net = canopen.Network()
    net.connect(interface="socketcand", host="127.0.0.1", port=port, channel="can0")
    node = canopen.RemoteNode(1, str(EDS))
    net.add_node(node)
    return net, node


def sdo_and_block() -> dict:
    p, port = serve("--pacing", "realtime")
    net, node = connect(port)
    try:
        lat = []
        for _ in range(300):
            t0 = time.perf_counter()
            node.sdo.upload(0x5F00, 1)
            lat.append(time.perf_counter() - t0)
        body = bytes(i & 0xFF for i in range(65532))
        blob = body + struct.pack("<I", zlib.crc32(body))
        dom = node.sdo[0x5F20][11]
        t0 = time.perf_counter()
        with dom.open("wb", size=len(blob), block_transfer=True) as f:
            f.write(blob)
        t_dl = time.perf_counter() - t0
        t0 = time.perf_counter()
        with dom.open("rb", block_transfer=True) as f:
            ok = f.read() == blob
        t_ul = time.perf_counter() - t0
        t0 = time.perf_counter()
        with dom.open("rb") as f:
            f.read()
        t_seg = time.perf_counter() - t0
    finally:
        net.disconnect()
        stop(p)
    return {"sdo_rtt_median_us": statistics.median(lat) * 1e6, "sdo_rtt_p95_us": sorted(lat)[int(0.95 * len(lat))] * 1e6,
            "block_download_kib_s": 64 / t_dl, "block_upload_kib_s": 64 / t_ul, "segmented_upload_kib_s": 64 / t_seg,
            "block_upload_verified": ok}


def stream_trial(period: int, n_pdo: int, bitrate: int, n_frames: int = 3000) -> tuple[bool, dict]:
    extra = ["--pacing", "fast"] + (["--bitrate", str(bitrate)] if bitrate else [])
    p, port = serve(*extra)
    net, node = connect(port)
    q: "queue.Queue[can.Message]" = queue.Queue()

    class L(can.Listener):
        def on_message_received(self, msg: can.Message) -> None:
            q.put(msg)

    ok = True
    try:
        node.sdo[0x1800][2].raw = 255
        node.sdo[0x1800][5].raw = 0
        for n in (2, 3, 4):
            node.sdo["tpdo_stream_period"][f"tpdo_stream_period_{n}"].raw = period if n - 1 <= n_pdo else 0
        net.notifier.add_listener(L())
        node.nmt.send_command(0x01)
        ids = {0x280 + 1 + 0x100 * k for k in range(n_pdo)}
        last: dict[int, int] = {}
        count = 0
        end = time.monotonic() + 60
        while count < n_frames * n_pdo and time.monotonic() < end:
            try:
                m = q.get(timeout=1.0)
            except queue.Empty:
                ok = False
                break
            if m.arbitration_id in ids:
                t = struct.unpack_from("<I", m.data, 0)[0]
                if m.arbitration_id in last and t - last[m.arbitration_id] != period:
                    ok = False
                last[m.arbitration_id] = t
                count += 1
        ok = ok and count >= n_frames * n_pdo
    finally:
        net.disconnect()
        stats = stop(p)
    return ok, stats


def max_rate(n_pdo: int, bitrate: int) -> dict:
    best = None
    tried = []
    for period in (1, 2, 3, 4, 5, 8, 10, 20):
        ok, st = stream_trial(period, n_pdo, bitrate)
        tried.append({"rate_hz": 10000 / period, "loss_free": ok, "bus_load": st.get("bus_load"),
                      "bus_dropped": st.get("bus_dropped")})
        if ok:
            best = 10000 / period
            break
    return {"max_loss_free_rate_hz": best, "tpdos": n_pdo, "bitrate": bitrate or None, "trials": tried}


def main() -> int:
    if not SIM.exists():
        print("40_can: build/bin/hdservo-sim not built (make sim)", file=sys.stderr)
        return 1
    res = {"transport": "socketcand (TCP loopback)"}
    res.update(sdo_and_block())
    res["stream_socketcand_1pdo"] = max_rate(1, 0)
    res["stream_socketcand_3pdo"] = max_rate(3, 0)
    res["stream_bus_1mbit_1pdo"] = max_rate(1, 1000000)
    res["stream_bus_1mbit_3pdo"] = max_rate(3, 1000000)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(res, indent=2) + "\n")
    print(f"SDO round trip {res['sdo_rtt_median_us']:.0f} us median; block download "
          f"{res['block_download_kib_s']:.0f} KiB/s, upload {res['block_upload_kib_s']:.0f} KiB/s; "
          f"loss-free stream: socketcand {res['stream_socketcand_1pdo']['max_loss_free_rate_hz']} Hz (1 TPDO), "
          f"{res['stream_socketcand_3pdo']['max_loss_free_rate_hz']} Hz (3 TPDOs); 1 Mbit/s bus "
          f"{res['stream_bus_1mbit_1pdo']['max_loss_free_rate_hz']} Hz (1), "
          f"{res['stream_bus_1mbit_3pdo']['max_loss_free_rate_hz']} Hz (3) -> {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
