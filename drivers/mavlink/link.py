"""Byte links to a MAVLink vehicle, addressed the way pymavlink's `mavlink_connection` is.

| address                                   | link                                                  |
| ----------------------------------------- | ----------------------------------------------------- |
| ``udp:HOST:PORT``, ``udpin:HOST:PORT``,   | `UdpLink` bound to HOST:PORT; the backend locks it to |
| ``HOST:PORT``                             | the address of the vehicle's first HEARTBEAT          |
| ``udpout:HOST:PORT``                      | `UdpLink` sending to HOST:PORT from an ephemeral port |
| ``tcp:HOST:PORT``                         | `SerialLink` on pyserial ``socket://HOST:PORT``       |
| ``/dev/ttyACM0``, ``/dev/ttyUSB0,57600``, | `SerialLink` on the device (baud after a comma),      |
| ``COM3``, any pyserial URL                | or any `serial.serial_for_url` URL as is              |

UDP is not a pyserial URL, hence `UdpLink` with the same `read_some` / `write` / `close` interface.
A listening `UdpLink` sends nothing until `lock(address)` names its one peer; from then on datagrams
from any other address are dropped unread (counted in `refused`, the first one logged), so a second
sender can neither receive our commands nor feed us data.
Every OS or pyserial failure, and a TCP end of file, becomes a `ConnectionLost` naming the address.
"""

from __future__ import annotations

import logging
import os
import select
import socket
import threading
from typing import Protocol

import serial

from robotexp import ConfigError, ConnectionLost
from robotexp_drivers.mavlink import constants as C
from robotexp_drivers.portio import WRITE_TIMEOUT, write_all

__all__ = ["Link", "SerialLink", "UdpLink", "open_link", "parse_address", "POLL_TIMEOUT"]

log = logging.getLogger(__name__)

READ_CHUNK = 65536     # [bytes] most bytes returned by one read_some (one UDP datagram at most)
POLL_TIMEOUT = 0.005   # [s] how long read_some waits for data


class Link(Protocol):
    """A byte stream to the vehicle."""

    address: str

    def read_some(self) -> bytes:
        """Bytes that arrived within the poll timeout (b"" when none)."""
        ...

    def write(self, data: bytes) -> None:
        """Send `data` whole."""
        ...

    def close(self) -> None:
        """Release the link (safe twice)."""
        ...


def _host_port(rest: str, address: str) -> tuple[str, int]:
    host, sep, port = rest.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ConfigError(f"mavlink: address {address!r}: expected HOST:PORT after the prefix, e.g. "
                          f"udp:127.0.0.1:{C.DEFAULT_UDP_PORT} or tcp:127.0.0.1:{C.DEFAULT_TCP_PORT}")
    return host, int(port)


def parse_address(address: str, baudrate: int = C.DEFAULT_BAUD) -> tuple[str, str | tuple[str, int], int]:
    """Map a MAVLink-style address to (kind, target, baudrate); kind is udpin, udpout or serial.

    For serial the target is a `serial_for_url` URL (``tcp:`` becomes ``socket://``).

    Raises:
        ConfigError: a malformed address or one this driver does not open (``tcpin:``, ``udpbcast:``).
    """
    prefix, sep, rest = address.partition(":")
    if sep and prefix in ("udp", "udpin"):
        return "udpin", _host_port(rest, address), baudrate
    if sep and prefix == "udpout":
        return "udpout", _host_port(rest, address), baudrate
    if sep and prefix == "tcp":
        host, port = _host_port(rest, address)
        return "serial", f"socket://{host}:{port}", baudrate
    if sep and prefix in ("tcpin", "udpbcast"):
        raise ConfigError(f"mavlink: {prefix}: addresses are not supported ({address!r}); the vehicle "
                          "must listen (tcp:HOST:PORT) or send to us (udp:HOST:PORT)")
    if "://" in address:
        return "serial", address, baudrate
    device, comma, baud = address.rpartition(",")
    if comma and baud.isdigit() and not os.path.exists(address):
        return "serial", device, int(baud)
    udp_host, colon, udp_port = address.rpartition(":")
    if colon and udp_port.isdigit() and udp_host and "/" not in address and not os.path.exists(address):
        return "udpin", (udp_host, int(udp_port)), baudrate
    return "serial", address, baudrate


def open_link(address: str, *, baudrate: int = C.DEFAULT_BAUD, poll: float = POLL_TIMEOUT) -> Link:
    """Open the link an address names (see the module table).

    Raises:
        ConfigError: a malformed address.
        ConnectionLost: the port or socket cannot be opened.
    """
    kind, target, baud = parse_address(address, baudrate)
    if kind == "serial":
        assert isinstance(target, str)
        return SerialLink(address, target, baudrate=baud, poll=poll)
    assert isinstance(target, tuple)
    return UdpLink(address, target, listen=kind == "udpin", poll=poll)


class SerialLink:
    """A pyserial port (`serial_for_url`): a device, ``socket://`` (TCP), ``rfc2217://``, ``loop://``.

    Raises:
        ConnectionLost: the port cannot be opened.
    """

    def __init__(self, address: str, url: str, *, baudrate: int = C.DEFAULT_BAUD, poll: float = POLL_TIMEOUT) -> None:
        self.address = address
        self._lock = threading.Lock()
        try:
            self._port = serial.serial_for_url(url, baudrate=baudrate, timeout=poll, write_timeout=WRITE_TIMEOUT)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise ConnectionLost(f"mavlink: cannot open {address!r} ({url}): {exc}; check the device or that "
                                 "the vehicle (or `robotexp emulate mavlink`) is running") from exc
        self.bytes_in = self.bytes_out = 0

    def read_some(self) -> bytes:
        """Bytes that arrived within the poll timeout (b"" when none).

        Raises:
            ConnectionLost: end of file or a port failure.
        """
        try:
            data = self._port.read(READ_CHUNK)
        except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
            # TypeError/AttributeError: pyserial's socket handler after a concurrent close()
            raise ConnectionLost(f"mavlink: the link to {self.address!r} is gone ({exc}); "
                                 "check the cable or restart the vehicle/emulator") from exc
        self.bytes_in += len(data)
        return bytes(data)

    def write(self, data: bytes) -> None:
        """Send `data` whole (thread-safe).

        Raises:
            ConnectionLost: the port failed or the peer left.
        """
        with self._lock:
            try:
                write_all(self._port, data)
            except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
                raise ConnectionLost(f"mavlink: cannot write to {self.address!r} ({exc})") from exc
        self.bytes_out += len(data)

    def close(self) -> None:
        """Release the port; errors are logged, not raised."""
        with self._lock:
            sock = getattr(self._port, "_socket", None)   # pyserial skips closing it when shutdown() fails
            try:
                self._port.close()
            except (serial.SerialException, OSError) as exc:
                log.debug("mavlink: closing %s: %s", self.address, exc)
            finally:
                if sock is not None:
                    sock.close()


class UdpLink:
    """MAVLink over UDP, one datagram per write.

    Args:
        address: the address as given (for messages).
        endpoint: (host, port) to bind (`listen`) or to send to.
        listen: bind `endpoint`; the address of each datagram read is `source`, and nothing is sent
            until `lock` fixes the one peer (whose datagrams alone are read from then on); else send
            to `endpoint` from an ephemeral port (``udpout``: the kernel delivers only its datagrams),
            which then reports an ICMP "port unreachable" as a `ConnectionLost`.
        poll: read timeout [s].

    Raises:
        ConnectionLost: the socket cannot be bound.
    """

    def __init__(self, address: str, endpoint: tuple[str, int], *, listen: bool, poll: float = POLL_TIMEOUT) -> None:
        self.address = address
        self.poll = poll
        self.peer: tuple[str, int] | None = None if listen else endpoint
        self.source: tuple[str, int] | None = None   # where the datagram last read came from
        self._lock = threading.Lock()
        self.bytes_in = self.bytes_out = self.unsent = 0
        self.refused = 0                              # datagrams from other addresses than the locked peer
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            if listen:
                self._sock.bind(endpoint)
            else:
                self._sock.connect(endpoint)
        except OSError as exc:
            self._sock.close()
            raise ConnectionLost(f"mavlink: cannot {'bind' if listen else 'reach'} {address!r}: {exc}") from exc
        self._listen = listen

    def lock(self, peer: tuple[str, int]) -> None:
        """Talk to `peer` only from now on (a listening link; the first lock holds)."""
        if self._listen and self.peer is None:
            self.peer = peer
            log.info("mavlink: %s: the vehicle is at %s:%d; other senders are ignored", self.address, *peer)

    @property
    def local_port(self) -> int:
        """The UDP port we receive on."""
        return int(self._sock.getsockname()[1])

    def read_some(self) -> bytes:
        """One datagram, or b"" when none arrived within the poll timeout.

        Raises:
            ConnectionLost: the socket failed (or, for udpout, the peer's port is closed).
        """
        try:
            ready, _, _ = select.select([self._sock], [], [], self.poll)
            if not ready:
                return b""
            data, peer = self._sock.recvfrom(READ_CHUNK)
        except (OSError, ValueError) as exc:
            raise ConnectionLost(f"mavlink: the UDP link {self.address!r} failed ({exc}); "
                                 "is the vehicle or emulator still running?") from exc
        if self._listen:
            if self.peer is not None and peer != self.peer:
                self.refused += 1
                if self.refused == 1:
                    log.warning("mavlink: %s: ignoring datagrams from %s:%d (the vehicle is at %s:%d); "
                                "further ones are counted, not logged", self.address, *peer, *self.peer)
                return b""
            self.source = peer
        self.bytes_in += len(data)
        return data

    def write(self, data: bytes) -> None:
        """Send one datagram (dropped, and counted in `unsent`, while a listening link is not locked).

        Raises:
            ConnectionLost: the socket failed.
        """
        with self._lock:
            try:
                if self._listen:
                    if self.peer is None:
                        self.unsent += 1
                        return
                    self._sock.sendto(data, self.peer)
                else:
                    self._sock.send(data)
            except OSError as exc:
                raise ConnectionLost(f"mavlink: cannot send on {self.address!r} ({exc}); "
                                     "is the vehicle or emulator still running?") from exc
        self.bytes_out += len(data)

    def close(self) -> None:
        """Close the socket (safe twice)."""
        self._sock.close()
