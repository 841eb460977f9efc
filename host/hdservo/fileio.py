"""Writing result files: atomic (no half-written file), the user's umask, one JSON encoder.

Every file the package writes goes through a temporary file in the target's
directory and a rename, so a reader never sees half a file and a failed write
leaves the old file in place.  :func:`tempfile.mkstemp` creates its file with
mode 0600; the result gets ``0666 & ~umask`` instead, as ``open()`` would give.

JSON is written by one encoder (:func:`json_ready` + :func:`dumps_json`):
numpy scalars and arrays become Python numbers and lists, and NaN and
infinities become ``null``, so every file is strict JSON.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from pathlib import Path
from contextlib import contextmanager
from typing import Any, Callable, Iterator

import numpy as np


def _umask() -> int:
    """The process umask (read from /proc where it exists: setting it briefly is not thread-safe)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def file_mode() -> int:
    """Mode of a new result file: ``0666 & ~umask``."""
    return 0o666 & ~_umask()


@contextmanager
def _atomic(path: "str | os.PathLike[str]", suffix: str = ".tmp") -> Iterator[str]:
    """The name of an empty temporary file next to ``path`` with the user's mode; renamed onto
    ``path`` when the block ends, removed when it raises."""
    p = Path(path)
    d = p.parent if str(p.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=suffix, dir=d)
    try:
        try:
            os.fchmod(fd, file_mode())
        finally:
            os.close(fd)
        yield tmp
        os.replace(tmp, p)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


@contextmanager
def files_into(directory: "str | os.PathLike[str]") -> Iterator[Path]:
    """A temporary directory beside ``directory`` whose files move into it when the block ends.

    For a result made of several files (a report and its plots): nothing appears in
    ``directory`` until all of them are written, and a block that raises leaves
    ``directory`` as it was.  ``directory`` is created if missing; files of the same name
    in it are replaced one by one (each by a rename), others are kept.

    Parameters
    ----------
    directory : path-like
        The target directory; its parent is created if missing.

    Yields
    ------
    pathlib.Path
        The temporary directory to write into (removed afterwards).
    """
    target = Path(directory)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    try:
        yield tmp
        target.mkdir(exist_ok=True)
        mode = file_mode()
        for p in sorted(tmp.iterdir()):
            if p.is_file():
                os.chmod(p, mode)
            os.replace(p, target / p.name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def write_bytes_atomic(path: "str | os.PathLike[str]", data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically with the user's umask; returns the path."""
    with _atomic(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
    return Path(path)


def write_text_atomic(path: "str | os.PathLike[str]", text: str, newline: str = "\n") -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically with the user's umask; returns the path.

    Parameters
    ----------
    path : path-like
        Target file; its directory must exist.
    text : str
        The whole content.
    newline : str
        Line ending written for ``"\\n"`` (``""``: as in ``text``).
    """
    with _atomic(path) as tmp:
        with open(tmp, "w", encoding="utf-8", newline=newline) as f:
            f.write(text)
    return Path(path)


def _json_key(k: Any) -> str:
    """A dict key as JSON writes it (``1`` -> ``"1"``, ``True`` -> ``"true"``, ``None`` -> ``"null"``)."""
    if isinstance(k, str):
        return k
    if isinstance(k, np.generic):
        k = k.item()
    return json.dumps(k) if isinstance(k, (bool, int, float)) or k is None else str(k)


def json_ready(x: Any, drop_suffix: "str | None" = None) -> Any:
    """``x`` as JSON reads it back: numpy scalars/arrays as Python numbers/lists, tuples as
    lists, dict keys as strings and non-finite floats as ``None`` (recursively through dicts
    and lists).

    Parameters
    ----------
    x : Any
        The object.
    drop_suffix : str, optional
        Dict entries whose key ends with it are left out at every depth (e.g. ``"_trace"``
        for time series that belong in plots, not in a summary document).
    """
    if isinstance(x, dict):
        return {_json_key(k): json_ready(v, drop_suffix) for k, v in x.items()
                if drop_suffix is None or not _json_key(k).endswith(drop_suffix)}
    if isinstance(x, (list, tuple)):
        return [json_ready(v, drop_suffix) for v in x]
    if isinstance(x, np.ndarray):
        return json_ready(x.tolist())
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def dumps_json(obj: Any, indent: "int | None" = 2, default: "Callable[[Any], Any] | None" = None) -> str:
    """Strict JSON text of ``obj`` (:func:`json_ready`), with a final newline.

    Parameters
    ----------
    obj : Any
        Dicts, lists, numbers (numpy too), strings, booleans, None.
    indent : int or None
        Indentation (None: one line).
    default : callable, optional
        Called for any other object (as in :func:`json.dumps`); its result is
        encoded the same way.  Without it such an object raises TypeError.
    """
    hook = None if default is None else (lambda o: json_ready(default(o)))
    return json.dumps(json_ready(obj), indent=indent, allow_nan=False, default=hook) + "\n"


def write_json_atomic(path: "str | os.PathLike[str]", obj: Any, indent: "int | None" = 2,
                      default: "Callable[[Any], Any] | None" = None) -> Path:
    """Write ``obj`` as strict JSON (:func:`dumps_json`) atomically with the user's umask.

    The text is built before the file is opened: an object that cannot be
    encoded raises and leaves any old file untouched.
    """
    return write_text_atomic(path, dumps_json(obj, indent=indent, default=default))


def save_figure_atomic(fig: Any, path: "str | os.PathLike[str]", **savefig: Any) -> Path:
    """Save a matplotlib figure atomically with the user's umask (format from the suffix
    unless ``format`` is given).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure (left open: the caller closes it).
    path : path-like
        Target file, e.g. ``plot.png`` or ``plot.pdf``.
    **savefig
        Passed to ``fig.savefig`` (``dpi``, ``format`` ...).
    """
    p = Path(path)
    fmt = savefig.pop("format", None) or p.suffix.lstrip(".") or "png"
    with _atomic(p, suffix=f".{fmt}") as tmp:
        fig.savefig(tmp, format=fmt, **savefig)
    return p


__all__ = ["dumps_json", "file_mode", "files_into", "json_ready", "save_figure_atomic", "write_bytes_atomic",
           "write_json_atomic", "write_text_atomic"]
