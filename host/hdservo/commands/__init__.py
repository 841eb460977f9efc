"""CLI subcommands.  Each module defines ``NAME``, ``HELP`` and
``register(parser)`` / ``run(args) -> int``; cli.py discovers them and adds the
common options (``-q``, ``-v``, ``--version``)."""
from __future__ import annotations

import logging
from typing import Callable


def progress_lines(command: str) -> Callable[[str], None]:
    """A ``progress(msg)`` callback that logs ``[command] msg`` at INFO (``logger hdservo.COMMAND``).

    The CLI shows INFO on stderr; ``-q`` raises the level to WARNING, which hides these lines.
    """
    log = logging.getLogger(f"hdservo.{command}")

    def progress(msg: str) -> None:
        log.info("[%s] %s", command, msg)
    return progress
