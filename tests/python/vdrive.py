"""A virtual drive (``hdservo-sim serve``) for the CAN tests, always stopped by its user.

``HDSERVO_SIM`` overrides the binary (default ``build/bin/hdservo-sim``).
"""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SIM = Path(os.environ.get("HDSERVO_SIM", ROOT / "build" / "bin" / "hdservo-sim"))
NODE = 1


class Server:
    """A running virtual drive on an ephemeral loopback port (socketcand)."""

    def __init__(self, *extra: str) -> None:
        self.p = subprocess.Popen([str(SIM), "serve", "--port", "0", "--node-id", str(NODE), *extra],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        line = self.p.stdout.readline() if self.p.stdout else ""
        if not line.startswith("listening on 127.0.0.1:"):
            self.stop()
            raise RuntimeError(f"hdservo-sim serve did not start: {line!r}")
        self.port = int(line.strip().rsplit(":", 1)[1])

    def stop(self) -> str:
        """Terminate (then kill) the process; returns its stderr."""
        if self.p.poll() is None:
            self.p.terminate()
            try:
                self.p.wait(10)
            except subprocess.TimeoutExpired:
                self.p.kill()
                self.p.wait()
        return self.p.stderr.read() if self.p.stderr else ""
