"""One ``hdservo-sim serve`` process on an ephemeral loopback port: start, rig channel, stop.

Every user of a virtual drive (the procedures' bench, the identification runner, the
CAN fault table, the tests) starts the same program the same way: ``--port 0``, read the
``listening on 127.0.0.1:PORT`` line, talk socketcand to that port, optionally send test-rig
commands on stdin (``--rig``, one ``ok key=value ...`` answer line each), and end it with
SIGTERM then SIGKILL.  This module is that one piece; the callers only choose the arguments.
"""
from __future__ import annotations

import contextlib
import select
import signal
import subprocess
import threading
from pathlib import Path
from typing import Any, Iterator, Optional, Protocol, Sequence, TypeVar

from . import resources
from .errors import UserError

LISTENING = "listening on 127.0.0.1:"


def find_sim() -> Path:
    """The hdservo-sim program (see :func:`hdservo.resources.sim_program`)."""
    return resources.sim_program()


class ServeError(UserError):
    """The virtual drive did not start, has exited, or refused a rig command."""


class ServeProcess:
    """A running ``hdservo-sim serve``; :meth:`stop` always ends it.

    Parameters
    ----------
    sim : Path
        The ``hdservo-sim`` program.
    args : sequence of str
        Arguments after ``serve`` (``--port 0`` is added first).
    start_timeout_s : float
        Wall time allowed for the ``listening on`` line, s.
    error : type
        Exception class raised on failure (a :class:`~hdservo.errors.UserError` subclass, so the
        CLI prints one line).

    Attributes
    ----------
    port : int
        The socketcand TCP port on 127.0.0.1.
    """

    def __init__(self, sim: Path, args: Sequence[str], start_timeout_s: float = 20.0,
                 error: type[UserError] = ServeError) -> None:
        self.error = error
        self.lock = threading.Lock()
        self.p: Optional[subprocess.Popen[str]] = subprocess.Popen(
            [str(sim), "serve", "--port", "0", *args], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True, bufsize=1)
        line = self.readline(start_timeout_s)
        if not line.startswith(LISTENING):
            err = self.stop()
            msg = (err.strip().splitlines() or [line.strip() or "no output"])[-1]
            raise error(f"the virtual drive did not start: {msg}")
        self.port = int(line.strip().rsplit(":", 1)[1])

    def readline(self, timeout_s: float) -> str:
        """One line of the program's stdout, or "" after ``timeout_s`` seconds of silence."""
        assert self.p is not None and self.p.stdout is not None
        r, _, _ = select.select([self.p.stdout], [], [], timeout_s)
        return self.p.stdout.readline() if r else ""

    def rig_many(self, lines: Sequence[str], timeout_s: float = 30.0) -> list[dict[str, str]]:
        """Send rig commands in one write (the drive reads them within one loop period).

        Returns
        -------
        list of dict
            The ``key=value`` fields of each ``ok`` answer, in order.
        """
        with self.lock:
            if self.p is None or self.p.poll() is not None or self.p.stdin is None:
                raise self.error("the virtual drive has exited")
            self.p.stdin.write("".join(line + "\n" for line in lines))
            self.p.stdin.flush()
            # the answers arrive together: after the first, the rest may already sit in the
            # reader's buffer, where select() on the descriptor would not see them
            assert self.p.stdout is not None
            answers = [self.readline(timeout_s).strip()] + [self.p.stdout.readline().strip() for _ in lines[1:]]
        out = []
        for line, ans in zip(lines, answers):
            if not ans.startswith("ok"):
                raise self.error(f"virtual rig: '{line}': {ans or 'no answer'}")
            out.append(dict(kv.split("=", 1) for kv in ans.split()[1:] if "=" in kv))
        return out

    def rig(self, line: str, timeout_s: float = 30.0) -> dict[str, str]:
        """One rig command; the fields of its ``ok`` answer."""
        return self.rig_many([line], timeout_s)[0]

    def power_loss(self) -> None:
        """SIGKILL: no exit handler, no flush, like pulling the supply."""
        if self.p is not None and self.p.poll() is None:
            self.p.send_signal(signal.SIGKILL)
            self.p.wait()

    def stop(self) -> str:
        """Terminate (SIGTERM, then SIGKILL after 10 s); returns the program's stderr."""
        p = self.p
        if p is None:
            return ""
        if p.poll() is None:
            try:
                if p.stdin:
                    p.stdin.close()
            except OSError:
                pass
            p.terminate()
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        try:
            return p.stderr.read() if p.stderr else ""
        except (OSError, ValueError):
            return ""
        finally:
            for f in (p.stdout, p.stderr):     # the pipes are ours to close (no ResourceWarning)
                if f:
                    f.close()


class _Stoppable(Protocol):
    port: int

    def stop(self) -> str: ...


P = TypeVar("P", bound=_Stoppable)


@contextlib.contextmanager
def connected(proc: P, node_id: int) -> Iterator[tuple[P, Any]]:
    """Connect the CAN client (:class:`hdservo.drive.Drive`, socketcand) to a started virtual drive.

    Yields ``(proc, drive)``; at the end the client is closed and the drive process stopped,
    also when the connection fails.
    """
    from .drive import Drive
    d = None
    try:
        d = Drive.connect(node_id, interface="socketcand", host="127.0.0.1", port=proc.port, channel="can0")
        yield proc, d
    finally:
        if d is not None:
            d.close()
        proc.stop()
