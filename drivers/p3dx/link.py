"""Byte link to a Pioneer (ARCOS) or MobileSim: `serial.serial_for_url` with read timeouts.

Any address `serial_for_url` accepts works (`/dev/ttyUSB0`, `socket://host:8101`, `rfc2217://...`,
`loop://`); `address_to_url` also turns the MobileSim forms "host" and "host:port" into a TCP URL.
Every failure of the other side (EOF, `OSError`, `SerialException`) becomes `ConnectionLost`.
"""

from __future__ import annotations

import threading
import time

import serial

from robotexp import ConnectionLost
from robotexp_drivers.backend import read_waiting
from robotexp_drivers.portio import WRITE_TIMEOUT, stream_url, write_all

from . import constants as c

__all__ = ["SerialLink", "address_to_url"]


def address_to_url(address: str) -> str:
    """The `serial_for_url` URL of a robot address.

    Args:
        address: "host", "host:port" or "tcp://host:port" (MobileSim over TCP, port 8101 by default), or
            anything `serial_for_url` accepts as is (a device path, `socket://`, `rfc2217://`, `loop://`).

    Returns:
        The URL.

    Raises:
        ConfigError: an empty address or a port outside 1..65535.
    """
    return stream_url("p3dx", address, "give a serial device (/dev/ttyUSB0), host, host:port (MobileSim, port "
                      "8101) or a pyserial URL (socket://host:8101)", c.SIM_TCP_PORT)


class SerialLink:
    """A byte stream to the robot, safe to write from two threads.

    Args:
        address: see `address_to_url`.
        baudrate: serial speed [baud] (ignored by TCP links); 9600 is ARCOS's default.
        timeout: longest wait of one `read` [s].

    Raises:
        ConnectionLost: the port or socket cannot be opened.
    """

    def __init__(self, address: str, *, baudrate: int = c.SERIAL_BAUD, timeout: float = 0.05) -> None:
        self.address = address
        self.url = address_to_url(address)
        self.timeout = timeout
        self._write_lock = threading.Lock()
        try:
            self._port = serial.serial_for_url(self.url, baudrate=baudrate, timeout=timeout,
                                               write_timeout=WRITE_TIMEOUT)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise ConnectionLost(f"p3dx: cannot open {self.url!r}: {exc}; check the address, that the "
                                 "robot or emulator is running and that the port is not in use") from exc
        self.closed = False

    def read(self) -> bytes:
        """Bytes received so far, waiting at most `timeout` for the first one (b"" on timeout).

        Raises:
            ConnectionLost: the other side closed the link or the port failed.
        """
        try:
            return read_waiting(self._port, self.timeout)
        except (serial.SerialException, OSError) as exc:
            raise ConnectionLost(f"p3dx: link {self.url!r} lost while reading: {exc}") from exc
        except (TypeError, AttributeError) as exc:    # pyserial after close() from another thread
            raise ConnectionLost(f"p3dx: link {self.url!r} closed while reading") from exc

    def write(self, data: bytes) -> None:
        """Send `data` completely.

        Raises:
            ConnectionLost: the link is closed or the write failed.
        """
        with self._write_lock:
            if self.closed:
                raise ConnectionLost(f"p3dx: link {self.url!r} is closed")
            try:
                write_all(self._port, data)
                self._port.flush()
            except (serial.SerialException, OSError) as exc:
                raise ConnectionLost(f"p3dx: link {self.url!r} lost while writing: {exc}") from exc

    def drain(self, seconds: float) -> None:
        """Read and drop what arrives for up to `seconds` [s], or until the other side closes.

        Closing a TCP socket with unread input makes Linux reset the connection, and the peer then
        loses the last commands we sent (the final stop and CLOSE: seen with AMRISim). ARIA waits
        one second after CLOSE for the same reason.
        """
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            try:
                self.read()
            except ConnectionLost:
                return

    def reset_input(self) -> None:
        """Drop bytes received and not read yet (ARIA flushes before SYNC0)."""
        try:
            self._port.reset_input_buffer()
        except (serial.SerialException, OSError) as exc:
            raise ConnectionLost(f"p3dx: link {self.url!r} lost: {exc}") from exc

    def close(self) -> None:
        """Close the port. Safe to call twice."""
        with self._write_lock:
            if self.closed:
                return
            self.closed = True
        # pyserial's socket:// close() skips closing the socket when shutdown() fails (the peer
        # is gone already), which leaks it: close it ourselves afterwards
        sock = getattr(self._port, "_socket", None)
        try:
            self._port.close()
        except (serial.SerialException, OSError):
            pass        # closing a link whose other side is gone: nothing left to release
        if sock is not None:
            sock.close()
