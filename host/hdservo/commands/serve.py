"""``hdservo serve``: start the virtual drive (``hdservo-sim serve``).

The simulated axis is served as a CANopen node over a socketcand-protocol TCP
server on loopback (python-can ``interface="socketcand"``) or SocketCAN.
Every option is passed through to ``hdservo-sim serve`` (found by :mod:`hdservo.resources`).
"""
from __future__ import annotations

import argparse
import signal
import subprocess
import threading
from pathlib import Path

from ..errors import UserError
from .. import resources
from ..serve_proc import find_sim

NAME = "serve"
HELP = "serve the simulated axis as a CANopen drive (virtual drive)"


def register(p: argparse.ArgumentParser) -> None:
    """Options of the virtual drive."""
    p.add_argument("--axis", default="reference",
                   help="axis TOML file, 'reference' or 'minimal' (built in), or the name of a shipped axis file")
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
    """Run the virtual drive in the foreground until Ctrl-C or SIGTERM (both stop the program).

    Returns
    -------
    int
        The program's exit status; 128 + N when it ended on signal N.
    """
    cmd = [str(find_sim()), "serve", "--axis", resources.axis_arg(args.axis), "--node-id", str(args.node_id),
           "--transport", args.transport, "--port", str(args.port), "--channel", args.channel,
           "--pacing", args.pacing, "--sync-periods", str(args.sync_periods), "--bitrate", str(args.bitrate),
           "--profile", args.profile]
    if args.duration is not None:
        cmd += ["--duration", str(args.duration)]
    try:
        proc = subprocess.Popen(cmd)
    except OSError as e:
        raise UserError(f"{cmd[0]}: cannot start the virtual drive: {e.strerror or e}") from None
    # SIGTERM (a service manager, `kill`) must stop the program too, not leave it serving
    # without its parent; Ctrl-C reaches both through the terminal's process group.
    main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, lambda signum, _frame: proc.send_signal(signum)) if main else None
    try:
        rc = proc.wait()
    except KeyboardInterrupt:
        rc = -signal.SIGINT
    finally:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        if main:
            signal.signal(signal.SIGTERM, previous)
    return 128 - rc if rc < 0 else rc
