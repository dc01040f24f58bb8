"""`write_all`: a write whose bytes went out never fails however late its thread runs (pyserial's own write
timeout failed the Kobuki link that way under load); a port that accepts nothing still times out; devices,
``socket://`` and descriptor-less ports."""

from __future__ import annotations

import os
import select
import socket
import time
import tty
from collections.abc import Iterator

import pytest
import serial

from robotexp_drivers.portio import write_all


@pytest.fixture
def pty_port() -> Iterator[tuple[int, serial.SerialBase]]:
    """A pseudo-terminal: its master (read by the test) and its slave opened as a pyserial port."""
    master, slave = os.openpty()
    tty.setraw(slave)
    port = serial.serial_for_url(os.ttyname(slave), timeout=0.01, write_timeout=1.0)
    try:
        yield master, port
    finally:
        port.close()
        os.close(slave)
        os.close(master)


def _read(fd: int, n: int, timeout: float = 10.0) -> bytes:
    """`n` bytes from the terminal's master `fd` (a terminal hands them over a moment after the write)."""
    got = b""
    deadline = time.monotonic() + timeout
    while len(got) < n and time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], 0.05)
        if ready:
            got += os.read(fd, n - len(got))
    return got


def test_a_write_that_went_out_is_no_timeout_however_late_the_thread_runs(pty_port, monkeypatch) -> None:
    master, port = pty_port
    clock = [0.0]
    monkeypatch.setattr(serial.serialutil.Timeout, "TIME", staticmethod(lambda: clock[0]))   # pyserial's clock
    real_write = os.write

    def late_write(fd: int, data: bytes) -> int:
        n = real_write(fd, data)
        clock[0] += 2.0         # the thread kept from the interpreter for 2 s right after its write
        return n

    monkeypatch.setattr(os, "write", late_write)
    with pytest.raises(serial.SerialTimeoutException):
        port.write(b"abc")      # pyserial: every byte went out, and still "Write timeout"
    write_all(port, b"def")
    monkeypatch.undo()
    assert _read(master, 6) == b"abcdef"


def test_a_port_that_accepts_nothing_times_out(pty_port) -> None:
    master, port = pty_port
    chunk = b"x" * 4096
    t0 = time.monotonic()
    with pytest.raises(serial.SerialTimeoutException, match="nothing accepted for 0.2 s"):
        for _ in range(1000):       # nobody reads the master: the terminal's buffers fill up
            write_all(port, chunk, timeout=0.2)
    assert time.monotonic() - t0 >= 0.2


def test_socket_and_loop_ports() -> None:
    with socket.create_server(("127.0.0.1", 0)) as server:
        port = serial.serial_for_url(f"socket://127.0.0.1:{server.getsockname()[1]}", timeout=0.01, write_timeout=1.0)
        conn, _ = server.accept()
        with conn:
            write_all(port, b"hello" * 1000)
            got = b""
            conn.settimeout(5.0)
            while len(got) < 5000:
                got += conn.recv(65536)
            assert got == b"hello" * 1000
        port.close()
    loop = serial.serial_for_url("loop://", timeout=0.01)      # no descriptor: pyserial's own write
    write_all(loop, b"abc")
    assert loop.read(3) == b"abc"
    loop.close()
