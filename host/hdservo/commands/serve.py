"""``hdservo serve``: start the virtual drive (``hdservo-sim serve``).

The simulated axis is served as a CANopen node over a socketcand-protocol TCP
server on loopback (python-can ``interface="socketcand"``) or SocketCAN.
Every option is passed through to ``build/bin/hdservo-sim serve``.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
from pathlib import Path

from ..cli import UserError

NAME = "serve"
HELP = "serve the simulated axis as a CANopen drive (virtual drive)"


def find_sim() -> Path:
    """Locate the hdservo-sim program: $HDSERVO_SIM, the build tree, then PATH."""
    env = os.environ.get("HDSERVO_SIM")
    if env:
        return Path(env)
    here = Path(__file__).resolve().parents[3] / "build" / "bin" / "hdservo-sim"
    if here.exists():
        return here
    w = shutil.which("hdservo-sim")
    if w:
        return Path(w)
    raise UserError("hdservo-sim not found (run `make sim` or set HDSERVO_SIM)")


def register(p: argparse.ArgumentParser) -> None:
    """Options of the virtual drive."""
    p.add_argument("--axis", default="reference", help="axis TOML file, 'reference' or 'minimal'")
    p.add_argument("--node-id", type=int, default=1)
    p.add_argument("--transport", choices=("socketcand", "socketcan"), default="socketcand")
    p.add_argument("--port", type=int, default=29536, help="socketcand TCP port (0 = ephemeral)")
    p.add_argument("--channel", default="can0", help="SocketCAN interface")
    p.add_argument("--pacing", choices=("realtime", "fast", "sync"), default="realtime")
    p.add_argument("--sync-periods", type=int, default=10, help="loop periods per SYNC (pacing sync)")
    p.add_argument("--bitrate", type=int, default=0, help="bus model bitrate (0 = off)")
    p.add_argument("--duration", type=float, default=None, help="stop after this simulated time, s")
    p.add_argument("--profile", choices=("hdservo", "generic"), default="hdservo",
                   help="object profile: hdservo (every object) or generic (CiA 301/402 standard objects "
                        "only; manufacturer objects refused and logged, no test rig)")


def run(args: argparse.Namespace) -> int:
    """Run the virtual drive in the foreground until Ctrl-C."""
    cmd = [str(find_sim()), "serve", "--axis", args.axis, "--node-id", str(args.node_id),
           "--transport", args.transport, "--port", str(args.port), "--channel", args.channel,
           "--pacing", args.pacing, "--sync-periods", str(args.sync_periods), "--bitrate", str(args.bitrate),
           "--profile", args.profile]
    if args.duration is not None:
        cmd += ["--duration", str(args.duration)]
    try:
        return subprocess.call(cmd)
    except KeyboardInterrupt:
        return 130
