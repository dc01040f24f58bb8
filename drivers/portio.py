"""Writing to a pyserial port whose write timeout is judged by the kernel, not by the wall clock.

pyserial's `write` (POSIX serial ports and ``socket://``) starts its timeout, writes, then raises
`SerialTimeoutException` when the timeout has passed, even after a write that sent every byte. A thread kept
from the interpreter's lock for longer than that (the main thread compiling numba kernels on a loaded machine,
measured: 1.3 s) then fails a healthy link: the Kobuki driver's reader lost an emulated robot that way
("cannot write ... (Write timeout)") at the start of a run on a fresh install. `write_all` fails only when
the port stayed unwritable for the whole timeout, as `select()` measures it; ports without a file descriptor
(``loop://``, ``rfc2217://``) keep pyserial's own write.
"""

from __future__ import annotations

import os
import select

import serial

__all__ = ["WRITE_TIMEOUT", "write_all"]

WRITE_TIMEOUT = 1.0     # [s] a port that accepts no byte for this long counts as gone


def _fd(port: serial.SerialBase) -> int | None:
    """The file descriptor `port` writes to (a device or a ``socket://`` socket), None when it has none."""
    fd = getattr(port, "fd", None)
    if isinstance(fd, int) and fd >= 0:
        return fd
    sock = getattr(port, "_socket", None)         # pyserial's socket:// handler keeps its socket there
    if sock is not None:
        try:
            return int(sock.fileno())
        except OSError:
            return None
    return None


def write_all(port: serial.SerialBase, data: bytes, timeout: float = WRITE_TIMEOUT) -> None:
    """Write `data` whole to the open `port` (its descriptor is non-blocking, as pyserial opens them).

    Args:
        port: an open pyserial port.
        data: the bytes to send.
        timeout: [s] how long the port may stay unwritable before the write fails.

    Raises:
        serial.SerialTimeoutException: the port accepted nothing for `timeout` s.
        serial.SerialException, OSError: the port failed (closed, unplugged, the peer left).
    """
    fd = _fd(port)
    if fd is None:
        port.write(data)
        return
    view = memoryview(data)
    while view:
        try:
            view = view[os.write(fd, view):]
        except BlockingIOError:
            pass
        if view:
            _, ready, _ = select.select([], [fd], [], timeout)
            if not ready:
                raise serial.SerialTimeoutException(f"Write timeout: nothing accepted for {timeout:g} s")
