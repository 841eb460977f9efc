"""CLI subcommands.  Each module defines ``NAME``, ``HELP`` and
``register(parser)`` / ``run(args) -> int``; cli.py discovers them."""
