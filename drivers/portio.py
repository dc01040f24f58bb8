"""The drivers' byte streams: the pyserial URL of an address (`stream_url`), and writing to a port whose write
timeout is judged by the kernel, not by the wall clock (`write_all`).

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
import re
import select

import serial

from robotexp import ConfigError

__all__ = ["WRITE_TIMEOUT", "stream_url", "write_all"]

_HOST = re.compile(r"^[A-Za-z0-9][A-Za-z0-9.-]*$")
_HOST_PORT = re.compile(r"^([A-Za-z0-9][A-Za-z0-9.-]*|\[[0-9A-Fa-f:]+\]):(\d{1,5})$")
_WINDOWS_PORT = re.compile(r"^COM\d+$", re.IGNORECASE)

WRITE_TIMEOUT = 1.0     # [s] a port that accepts no byte for this long counts as gone


def stream_url(who: str, address: str, forms: str, default_port: int | None = None) -> str:
    """The `serial.serial_for_url` URL of a device's `address`: "host:port" and "tcp://host:port" become
    ``socket://host:port``, a bare host ``socket://host:default_port`` when the device has a default port; a
    device path (/dev/ttyUSB0, COM3) or another URL (socket://, loop://, rfc2217://) passes as is.

    Raises:
        ConfigError: an empty address or a port outside 1..65535 ("`who`: ...", `forms` the accepted forms).
    """
    address = address.strip()
    if address.lower().startswith("tcp://"):
        address = address[len("tcp://"):].rstrip("/")
        if not _HOST_PORT.match(address):
            raise ConfigError(f"{who}: address 'tcp://{address}': give host:port; {forms}")
    if not address:
        raise ConfigError(f"{who}: empty address; {forms}")
    if "://" in address or address.startswith("/") or _WINDOWS_PORT.match(address):
        return address
    m = _HOST_PORT.match(address)
    if m:
        port = int(m.group(2))
        if not 1 <= port <= 65535:
            raise ConfigError(f"{who}: address {address!r}: TCP port must be 1..65535, got {port}")
        return f"socket://{m.group(1)}:{port}"
    if default_port is not None and _HOST.match(address):
        return f"socket://{address}:{default_port}"
    return address


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
