"""The byte link to a Kobuki: pyserial's `serial_for_url` with short read timeouts and clear errors.

Any address `serial.serial_for_url` accepts works: a device path (``/dev/kobuki``,
``/dev/ttyUSB0``, a pseudo-terminal of the emulator), ``socket://127.0.0.1:PORT`` (the emulator on
TCP; ``host:port`` and ``tcp://host:port`` mean the same, `stream_url`), ``rfc2217://host:port`` or
``loop://``. Every pyserial or OS failure, and an end of file,
becomes a `ConnectionLost` naming the address (chained to the original error).
"""

from __future__ import annotations

import logging
import threading

import serial

from robotexp import ConnectionLost
from robotexp_drivers.kobuki import constants as K
from robotexp_drivers.portio import WRITE_TIMEOUT, stream_url, write_all

__all__ = ["KobukiLink", "READ_CHUNK", "POLL_TIMEOUT"]

log = logging.getLogger(__name__)

READ_CHUNK = 4096      # [bytes] most bytes returned by one `read_some`
POLL_TIMEOUT = 0.002   # [s] port read timeout: bounds how long a partial chunk waits (see read_some)


class KobukiLink:
    """An open byte stream to a Kobuki (115200 8N1, no flow control).

    Args:
        address: anything `serial.serial_for_url` accepts.
        baudrate: line speed [bit/s] (ignored by TCP URLs).
        poll: read timeout of the port [s]: `read_some` returns what arrived within it.

    Raises:
        ConnectionLost: the port cannot be opened (no such device, refused connection, busy port).
        ConfigError: an empty address or a TCP port outside 1..65535.
    """

    def __init__(self, address: str, *, baudrate: int = K.BAUD_RATE, poll: float = POLL_TIMEOUT) -> None:
        self.address = address
        url = stream_url("kobuki", address, "give a device (/dev/kobuki, /dev/ttyUSB0) or host:port")
        self._write_lock = threading.Lock()
        try:
            self._port = serial.serial_for_url(url, baudrate=baudrate, bytesize=serial.EIGHTBITS,
                                               parity=serial.PARITY_NONE, stopbits=serial.STOPBITS_ONE,
                                               timeout=poll, write_timeout=WRITE_TIMEOUT)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise ConnectionLost(f"kobuki: cannot open {address!r}: {exc}; check the device path or "
                                 "that the robot (or `robotexp emulate kobuki`) is running") from exc
        try:
            # the robot streams from power-on: frames queued before we opened are stale
            self._port.reset_input_buffer()
        except (serial.SerialException, OSError) as exc:
            self._port.close()
            raise ConnectionLost(f"kobuki: {address!r} failed right after opening: {exc}") from exc
        self.bytes_in = 0
        self.bytes_out = 0

    def read_some(self) -> bytes:
        """Return the bytes that arrived within the poll timeout (b"" when none), at most READ_CHUNK.

        A TCP peer's data comes in whole segments, so a chunk returns as soon as the poll timeout
        runs out after the first byte; on a serial line at 115200 baud that is ~23 bytes per 2 ms.
        Bytes that arrive in the same read as an end of file are lost with it (pyserial drops them).

        Raises:
            ConnectionLost: the other side closed the link (EOF) or the port failed.
        """
        try:
            data = self._port.read(READ_CHUNK)
        except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
            # TypeError/AttributeError: pyserial's socket handler after a concurrent close()
            raise ConnectionLost(f"kobuki: the link to {self.address!r} is gone ({exc}); "
                                 "check the cable or restart the robot/emulator") from exc
        self.bytes_in += len(data)
        return data

    def write(self, data: bytes) -> None:
        """Send `data` whole (thread-safe).

        Raises:
            ConnectionLost: the other side closed the link or the port failed.
        """
        with self._write_lock:
            try:
                write_all(self._port, data)
            except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
                raise ConnectionLost(f"kobuki: cannot write to {self.address!r} ({exc}); "
                                     "the robot or emulator went away") from exc
        self.bytes_out += len(data)

    @property
    def is_open(self) -> bool:
        """True until `close()`."""
        return bool(self._port.is_open)

    def close(self) -> None:
        """Release the port. Safe to call twice; errors while closing are logged, not raised."""
        with self._write_lock:
            # pyserial's socket:// close() skips closing the socket when shutdown() fails (a peer that
            # already left): keep a handle and close it ourselves (closing twice is harmless)
            sock = getattr(self._port, "_socket", None)
            try:
                self._port.close()
            except (serial.SerialException, OSError) as exc:
                log.debug("kobuki: closing %s: %s", self.address, exc)
            finally:
                if sock is not None:
                    sock.close()
