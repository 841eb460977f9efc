"""Errors that the library raises and the command line prints as one line.

Every module of the library raises :class:`UserError` (or a subclass) for a
problem with the user's input or environment: a bad file, a missing drive, a
value out of range.  The command line (:mod:`hdservo.cli`) prints its message
as one line and exits with status 2; nothing in the library prints it.
"""
from __future__ import annotations


class UserError(Exception):
    """A problem with the user's input: printed as one line, exit status 2."""
