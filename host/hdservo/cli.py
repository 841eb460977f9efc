"""Command-line entry point ``hdservo``.

Subcommands live in :mod:`hdservo.commands`, one module each, and are
discovered at start-up so adding one needs no edit here.

Every subcommand shares one convention (docs/cli.md): ``--node-id N`` for the
drive's node id, ``-o FILE`` for a file it writes and ``--out-dir DIR`` for a
directory, ``--set NAME=VALUE`` (repeatable) for overrides, ``--json PATH`` for
the machine-readable result, ``-q`` / ``-v`` for less or more output (logging
levels) and ``--version``.  The common options are added here, after the
command's own ``register``.
"""
from __future__ import annotations

import argparse
import importlib
import logging
import pkgutil
import sys
from typing import Sequence, TextIO

from . import __version__, commands
from .errors import UserError  # noqa: F401  (re-exported: the one error type the CLI prints)

#: logging level of the ``hdservo`` loggers per verbosity (-q = -1, none = 0, -v = 1, -vv = 2)
LEVELS = {-1: logging.WARNING, 0: logging.INFO, 1: logging.DEBUG}


def add_common_arguments(p: argparse.ArgumentParser) -> None:
    """Add ``-q/--quiet``, ``-v/--verbose`` and ``--version`` to a (sub)command parser.

    ``-q`` sets the ``hdservo`` loggers to WARNING and turns progress bars off;
    ``-v`` sets them to DEBUG.  The defaults are suppressed so that an option given
    before the subcommand (``hdservo -v test ...``) is not reset by the subcommand's
    parser; :func:`main` fills in the missing ones.
    """
    g = p.add_argument_group("output")
    g.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                   help="warnings and errors only, no progress bars")
    g.add_argument("-v", "--verbose", action="count", default=argparse.SUPPRESS,
                   help="more detail (debug log lines)")
    g.add_argument("--version", action="version", version=f"hdservo {__version__}",
                   help="print the version and exit")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hdservo",
        description="Model, identify and compensate harmonic-drive servo axes.")
    add_common_arguments(parser)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        mod = importlib.import_module(f"{commands.__name__}.{info.name}")
        if not hasattr(mod, "register"):
            continue
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=mod.HELP)
        mod.register(p)
        add_common_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def verbosity(args: argparse.Namespace) -> int:
    """-1 quiet, 0 normal, 1 or more verbose (``-q`` wins over ``-v``)."""
    return -1 if getattr(args, "quiet", False) else min(int(getattr(args, "verbose", 0) or 0), 1)


class _StderrHandler(logging.StreamHandler):  # type: ignore[type-arg]
    """A stream handler on whatever ``sys.stderr`` is when a record is written (tests swap it)."""

    @property  # type: ignore[override]
    def stream(self) -> TextIO:
        return sys.stderr

    @stream.setter
    def stream(self, value: TextIO) -> None:
        pass


def setup_logging(level: int) -> None:
    """Messages of the ``hdservo`` loggers on stderr, bare (the library reports progress through them)."""
    log = logging.getLogger("hdservo")
    log.setLevel(level)
    if not any(isinstance(h, _StderrHandler) for h in log.handlers):
        h = _StderrHandler()
        h.setFormatter(logging.Formatter("%(message)s"))
        log.addHandler(h)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    v = verbosity(args)
    args.quiet = v < 0
    args.verbose = max(v, 0)
    setup_logging(LEVELS[v])
    try:
        return int(args._run(args) or 0)
    except UserError as e:
        print(f"hdservo {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    # `python -m hdservo.cli`: run the package module's main, so that the
    # UserError the commands import (hdservo.cli.UserError) is the one caught
    # here, not a second class of this __main__ copy (which would print a
    # traceback instead of the one-line error).
    from hdservo.cli import main as _main
    sys.exit(_main())
