"""Progress reporting: tqdm bars on a terminal, log lines elsewhere, nothing when quiet.

Long runs (the procedures, ``hdservo compare``, ``hdservo demo``) report how far they
are through one of two objects:

* :class:`Bar`, a count of steps (rows x procedures, the demo's stages);
* :class:`Fraction`, a fraction 0..1 with a short text (one procedure).

On a terminal (stderr is a TTY) both draw a `tqdm <https://tqdm.github.io>`_ bar.
Elsewhere (a log file, CI, a pipe) a bar would be a stream of carriage returns, so
they write INFO lines through :mod:`logging` instead (logger ``hdservo.progress``),
at most one per 10 % for a fraction.  ``enabled=False`` (the commands pass
``not args.quiet``) prints nothing at all; so does a library caller that has not
configured logging, since INFO lines are below Python's default level.
"""
from __future__ import annotations

import logging
import sys
import threading
from typing import Any, Optional, TextIO

from tqdm import tqdm

LOG = logging.getLogger("hdservo.progress")

#: a fraction off a terminal logs a line only after this many percent since its last one
LOG_STEP_PCT = 10.0

#: serialises writes of several bars (worker threads of ``hdservo compare``)
_LOCK = threading.RLock()
tqdm.set_lock(_LOCK)


def _stream() -> TextIO:
    return sys.stderr


def on_terminal(stream: Optional[TextIO] = None) -> bool:
    """True when ``stream`` (default stderr) is a terminal, where bars are drawn."""
    s = stream if stream is not None else _stream()
    try:
        return bool(s.isatty())
    except (AttributeError, ValueError):       # closed or not a file
        return False


def echo(text: str, file: Optional[TextIO] = None) -> None:
    """Print a line without breaking the bars on the terminal (:func:`tqdm.write`)."""
    tqdm.write(text, file=file if file is not None else sys.stdout)


class Bar:
    """Progress over a known number of steps.

    Parameters
    ----------
    label : str
        Prefix, e.g. ``compare``.
    total : int
        Number of steps (at least 1).
    enabled : bool
        False: report nothing.
    stream : file, optional
        Where a terminal bar goes (default stderr); a stream that is not a TTY
        gives INFO log lines instead.
    """

    def __init__(self, label: str, total: int, enabled: bool = True, stream: Optional[TextIO] = None) -> None:
        self.label = label
        self._total = max(1, int(total))
        self.done = 0
        self.enabled = enabled
        self._bar: Optional[Any] = None
        if enabled and on_terminal(stream):
            self._bar = tqdm(total=self._total, desc=label, file=stream if stream is not None else _stream(),
                             unit="step", dynamic_ncols=True, leave=True)

    @property
    def total(self) -> int:
        """Number of steps; may be raised while running (the ablation learns its second stage late)."""
        return self._total

    @total.setter
    def total(self, n: int) -> None:
        self._total = max(1, int(n))
        if self._bar is not None:
            self._bar.total = self._total
            self._bar.refresh()

    def show(self, text: str) -> None:
        """Show ``text`` at the current step (no step done)."""
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.set_postfix_str(text)
        else:
            LOG.info("[%s] %d/%d %s", self.label, self.done, self._total, text)

    def step(self, text: str = "") -> None:
        """One step done."""
        self.done += 1
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.set_postfix_str(text, refresh=False)
            self._bar.update(1)
        else:
            LOG.info("[%s] %d/%d %s", self.label, self.done, self._total, text)

    def close(self) -> None:
        """End the bar (the terminal line stays)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None


class Fraction:
    """Progress as a fraction 0..1 with a short text; called as ``progress(frac, text)``.

    Parameters
    ----------
    name : str
        Prefix, e.g. the procedure ``min-rate``.
    enabled : bool
        False: report nothing.
    stream : file, optional
        As for :class:`Bar`.
    """

    def __init__(self, name: str, enabled: bool = True, stream: Optional[TextIO] = None) -> None:
        self.name = name
        self.enabled = enabled
        self._stream = stream
        self._bar: Optional[Any] = None
        self._last = -1.0

    def __call__(self, frac: float, text: str = "") -> None:
        if not self.enabled:
            return
        pct = max(0.0, min(1.0, float(frac))) * 100.0
        if self._bar is None and on_terminal(self._stream):
            self._bar = tqdm(total=100.0, desc=self.name, file=self._stream if self._stream is not None else _stream(),
                             bar_format="{desc}: {percentage:5.1f}%|{bar}| {elapsed}<{remaining}{postfix}",
                             dynamic_ncols=True, leave=True)
        if self._bar is not None:
            self._bar.set_postfix_str(text, refresh=False)
            self._bar.update(pct - self._bar.n)
            if pct >= 100.0:
                self.close()
            return
        if pct < 100.0 and pct - self._last < LOG_STEP_PCT:
            return
        self._last = pct
        LOG.info("[%s] %5.1f%% %s", self.name, pct, text)

    def close(self) -> None:
        """End the bar (the terminal line stays)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None


__all__ = ["Bar", "Fraction", "LOG", "echo", "on_terminal"]
