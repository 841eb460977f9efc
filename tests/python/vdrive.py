"""A virtual drive (``hdservo-sim serve``) for the CAN tests, always stopped by its user.

``HDSERVO_SIM`` overrides the binary (default ``build/bin/hdservo-sim``).  The process
handling is the package's own :class:`hdservo.serve_proc.ServeProcess`.
"""
from __future__ import annotations

import os
from pathlib import Path

from hdservo.serve_proc import ServeProcess

ROOT = Path(__file__).resolve().parents[2]
SIM = Path(os.environ.get("HDSERVO_SIM", ROOT / "build" / "bin" / "hdservo-sim"))
NODE = 1


class Server(ServeProcess):
    """A running virtual drive on an ephemeral loopback port (socketcand), node :data:`NODE`."""

    def __init__(self, *extra: str) -> None:
        super().__init__(SIM, ["--node-id", str(NODE), *extra])
