"""Command-line entry point ``hdservo``.

Subcommands live in :mod:`hdservo.commands`, one module each, and are
discovered at start-up so adding one needs no edit here.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from typing import Sequence

from . import __version__, commands
from .errors import UserError  # noqa: F401  (re-exported: the one error type the CLI prints)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="hdservo",
        description="Model, identify and compensate harmonic-drive servo axes.")
    parser.add_argument("--version", action="version", version=f"hdservo {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        mod = importlib.import_module(f"{commands.__name__}.{info.name}")
        if not hasattr(mod, "register"):
            continue
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=mod.HELP)
        mod.register(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
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
