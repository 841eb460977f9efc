"""TOML text the host generates (scenarios, models, configuration files), and reading a TOML data file.

Every string the host pastes into a TOML document -- file paths above all, which
may hold quotes, backslashes (``C:\\axes\\x.toml``) or other odd characters --
goes through :func:`basic_string`, so the document parses back to the same
string both in Python (``tomllib``) and in the simulator's C reader
(``sim/harness/toml_lite.c``, which knows the escapes ``\\" \\\\ \\n \\t \\r``).
"""
from __future__ import annotations

import os
from typing import Any

try:
    import tomllib
except ModuleNotFoundError:      # Python < 3.11
    import tomli as tomllib  # type: ignore[no-redef]

from .errors import UserError

#: Escapes both readers understand.
_ESCAPES = {"\\": "\\\\", '"': '\\"', "\n": "\\n", "\t": "\\t", "\r": "\\r"}


def basic_string(s: str) -> str:
    """A TOML basic string (with the quotes) whose value is ``s``.

    Parameters
    ----------
    s : str
        Any text; a path is passed as ``str(path)``.

    Returns
    -------
    str
        ``"..."`` with backslash, quote, newline, tab and carriage return escaped.

    Raises
    ------
    ValueError
        ``s`` holds another control character (U+0000-U+001F, U+007F), which the
        simulator's TOML reader cannot take.
    """
    out = []
    for c in str(s):
        e = _ESCAPES.get(c)
        if e is not None:
            out.append(e)
        elif ord(c) < 0x20 or ord(c) == 0x7F:
            raise ValueError(f"{s!r}: control character U+{ord(c):04X} cannot go into a TOML string")
        else:
            out.append(c)
    return '"' + "".join(out) + '"'


def read_toml_file(path: "str | os.PathLike[str]", error: type[UserError] = UserError) -> dict[str, Any]:
    """The document of a TOML file; an unreadable or invalid file raises ``error`` with one line.

    Parameters
    ----------
    path : path-like
        The file.
    error : type
        The :class:`~hdservo.errors.UserError` subclass raised (``"PATH: cannot read: ..."`` or
        ``"PATH: not valid TOML: ..."``, with the parser's line and column; ``"PATH:LINE: expected
        UTF-8 TOML text ..."`` for bytes that are not UTF-8).
    """
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except OSError as e:
        raise error(f"{path}: cannot read: {e.strerror}") from None
    try:
        return tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as e:
        line = raw[: e.start].count(b"\n") + 1
        raise error(f"{path}:{line}: expected UTF-8 TOML text, found byte 0x{raw[e.start]:02x}") from None
    except tomllib.TOMLDecodeError as e:
        raise error(f"{path}: not valid TOML: {e}") from None


__all__ = ["basic_string", "read_toml_file"]
