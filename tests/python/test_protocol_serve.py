"""`hdservo-sim serve` over its socketcand transport at the protocol level (a raw TCP
client, no python-can): a client that stops reading cannot keep the server from
stopping on SIGTERM, is given up after --client-timeout, and a diverging axis ends
the server with the one-line error."""
from __future__ import annotations

import json
import select
import signal
import socket
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

#: The checkout these tests run in.
REPO_ROOT = Path(__file__).resolve().parents[2]

EXE = REPO_ROOT / "build" / "bin" / "hdservo-sim"


@pytest.fixture(scope="module", autouse=True)
def _built() -> None:
    subprocess.run(["make", "--no-print-directory", "build/bin/hdservo-sim"], cwd=REPO_ROOT, check=True,
                   stdout=subprocess.DEVNULL)


def _start(*args: str) -> tuple[subprocess.Popen[str], int]:
    """Start the server; return it and its TCP port (from "listening on 127.0.0.1:PORT")."""
    p = subprocess.Popen([str(EXE), "serve", "--port", "0", *args], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    assert p.stdout is not None
    line = p.stdout.readline()
    assert line.startswith("listening on 127.0.0.1:"), line
    return p, int(line.rsplit(":", 1)[1])


@pytest.fixture()
def server_procs() -> Iterator[list[subprocess.Popen[str]]]:
    procs: list[subprocess.Popen[str]] = []
    yield procs
    for p in procs:
        if p.poll() is None:
            p.kill()
            p.wait()


def _expect(sock: socket.socket, want: bytes, timeout_s: float = 5.0) -> None:
    sock.settimeout(timeout_s)
    got = b""
    while len(got) < len(want):
        chunk = sock.recv(len(want) - len(got))
        assert chunk, f"connection closed, expected {want!r}, got {got!r}"
        got += chunk
    assert got == want


def _send_frame(sock: socket.socket, cob: int, data: bytes) -> None:
    sock.sendall(f"< send {cob:X} {len(data)} {' '.join(f'{b:X}' for b in data)} >".encode())


def _open_and_stream(port: int) -> socket.socket:
    """Connect with a small receive buffer, finish the handshake, make the drive stream
    TPDO2-4 every loop period (0x5F10:2..4 = 1 by SDO) and start it (NMT start)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", port))
    _expect(sock, b"< hi >")
    sock.sendall(b"< open can0 >")
    _expect(sock, b"< ok >")
    sock.sendall(b"< rawmode >")
    _expect(sock, b"< ok >")
    for sub in (2, 3, 4):
        _send_frame(sock, 0x601, bytes([0x2B, 0x10, 0x5F, sub, 1, 0, 0, 0]))
    _send_frame(sock, 0x000, bytes([0x01, 0x01]))
    # the stream is on: frames arrive
    sock.settimeout(5.0)
    seen = b""
    t_end = time.monotonic() + 5.0
    while seen.count(b"< frame 28") < 3 and time.monotonic() < t_end:
        seen += sock.recv(65536)
    assert seen.count(b"< frame 28") >= 3, seen[-300:]
    return sock


def _wait_stalled(sock: socket.socket, proc: subprocess.Popen[str]) -> None:
    """Stop reading; wait until this end's receive queue stops growing (the server's
    send buffer is full and its send loop waits)."""
    import fcntl
    import termios
    last, stable_since = -1, time.monotonic()
    t_end = time.monotonic() + 10.0
    while time.monotonic() < t_end:
        assert proc.poll() is None
        q = int.from_bytes(fcntl.ioctl(sock.fileno(), termios.FIONREAD, b"\0\0\0\0"), "little")
        if q != last:
            last, stable_since = q, time.monotonic()
        elif q > 0 and time.monotonic() - stable_since > 1.0:
            return
        time.sleep(0.05)
    pytest.fail("the server's output never backed up")


def _stats(stderr: str) -> dict[str, float]:
    lines = [ln for ln in stderr.splitlines() if ln.startswith("{")]
    assert len(lines) == 1, stderr
    return json.loads(lines[0])


def test_sigterm_stops_serve_while_the_client_stalls(server_procs: list[subprocess.Popen[str]]) -> None:
    proc, port = _start("--pacing", "fast", "-q")
    server_procs.append(proc)
    sock = _open_and_stream(port)
    try:
        _wait_stalled(sock, proc)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        try:
            _, err = proc.communicate(timeout=3.0)
        except subprocess.TimeoutExpired:
            pytest.fail("hdservo-sim serve ignored SIGTERM while its client stalled")
        assert time.monotonic() - t0 < 3.0
        assert proc.returncode == 0, err
        st = _stats(err)
        # the drive streamed, then waited for its client: fast pacing bounds its lead to about
        # 500 frames (docs/can.md) beyond what the client took before it stopped reading
        assert st["periods"] > 100 and 300 < st["frames_to_bus"] <= 4000, st
        assert st["client_timeouts"] == 0
    finally:
        sock.close()


def test_a_stalled_client_is_given_up_after_the_timeout(server_procs: list[subprocess.Popen[str]]) -> None:
    proc, port = _start("--pacing", "fast", "--client-timeout", "1.5", "-q")
    server_procs.append(proc)
    sock = _open_and_stream(port)
    try:
        _wait_stalled(sock, proc)
        time.sleep(1.5 + 1.0)           # still not reading, past the time-out
        # the server closed the connection: reading everything that is queued ends in EOF
        t_end = time.monotonic() + 10.0
        closed = False
        while time.monotonic() < t_end:
            r, _, _ = select.select([sock], [], [], 0.5)
            if r:
                try:
                    chunk = sock.recv(1 << 20)
                except ConnectionResetError:
                    chunk = b""
                if not chunk:
                    closed = True
                    break
        assert closed, "the stalled client was never dropped"
    finally:
        sock.close()
    # the server keeps serving: a new client gets the greeting
    with socket.create_connection(("127.0.0.1", port), timeout=5.0) as s2:
        _expect(s2, b"< hi >")
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=5.0)
    assert proc.returncode == 0
    assert _stats(err)["client_timeouts"] == 1


def test_bad_client_timeout_is_one_error_line() -> None:
    p = subprocess.run([str(EXE), "serve", "--client-timeout", "0"], capture_output=True, text=True, timeout=10)
    assert p.returncode == 2 and p.stderr.count("\n") == 1
    assert "--client-timeout must be 0.1..3600 seconds" in p.stderr


def test_diverging_axis_ends_serve_with_one_error_line(server_procs: list[subprocess.Popen[str]]) -> None:
    sets = [a for k in ("stiffness.k1_Nm_per_rad", "stiffness.k2_Nm_per_rad", "stiffness.k3_Nm_per_rad",
                        "stiffness_cubic.k1_Nm_per_rad", "stiffness_cubic.k3_Nm_per_rad3")
            for a in ("--set", f"{k}=1e9")]
    proc, port = _start("--pacing", "fast", "-q", *sets)
    server_procs.append(proc)
    with socket.create_connection(("127.0.0.1", port), timeout=5.0) as sock:
        _expect(sock, b"< hi >")
        sock.sendall(b"< open can0 >")
        _expect(sock, b"< ok >")
        sock.sendall(b"< rawmode >")
        _expect(sock, b"< ok >")
        sock.settimeout(0.2)
        t_end = time.monotonic() + 20.0
        while proc.poll() is None and time.monotonic() < t_end:   # keep reading: no back-pressure
            try:
                sock.recv(1 << 20)
            except (TimeoutError, socket.timeout, ConnectionResetError):
                pass
    _, err = proc.communicate(timeout=10.0)
    assert proc.returncode == 2, (proc.returncode, err[-500:])
    errs = [ln for ln in err.splitlines() if not ln.startswith("{")]
    assert len(errs) == 1, err
    assert errs[0].startswith("hdservo-sim serve: error: --axis reference: the simulation diverged at t = ")
