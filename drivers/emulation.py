"""What the emulators share: the serving thread's lifecycle, transports, pacing and fault injection.

`EmulatorBase` is the lifecycle of every emulator here: `start()` serves in a daemon thread,
`serve_forever()` in the calling one, `close()` stops the thread and releases the transport and the
simulator (safe twice), and `with emulator:` does both.

`StreamEmulator` adds what the Kobuki and MAVLink emulators have in common, a robot that streams:

- transports: a TCP listener (one client at a time) or a pseudo-terminal (`os.openpty`, raw mode;
  frames nobody reads are dropped, as on a serial line);
- the serving loop: accept a client, step the robot every `_period` s of wall time (robot time /
  `speedup`; late steps are not caught up in a burst) and send what `_step()` returns, and in
  between wait for command bytes and hand them to `_on_bytes`;
- fault injection: `pause_stream`/`resume_stream` (a stalled link), `send_raw` (garbage before the
  next step's bytes), `corrupt_frames` (wrong checksums), `drop_client` handled by the loop.
"""

from __future__ import annotations

import logging
import os
import select
import socket
import threading
import time
import tty
from abc import ABC, abstractmethod
from typing import ClassVar, Self

from robotexp import Twist
from robotexp.sim import OdometryError, SimRobot, odometry_error

__all__ = ["EmulatorBase", "StreamEmulator", "odometry_model"]

log = logging.getLogger(__name__)


def odometry_model(odometry: OdometryError | str | None) -> OdometryError | None:
    """The odometry error an emulator's simulated encoders get: a model, an `--odometry-error` text
    (`p3dx`, `kobuki`, `p3dx:drift=0.5`, `mismatch=0.01,...`) or None (error-free).

    Raises:
        ConfigError: a text that is not an odometry-error spec.
    """
    if odometry is None or isinstance(odometry, OdometryError):
        return odometry
    return odometry_error(odometry)


class EmulatorBase(ABC):
    """The serving thread of an emulator: `start`, `serve_forever`, `close`, `with`.

    A subclass sets `label` (for the thread's name and messages), `address` and `sim`, calls
    `_init_serving()` in `__init__` and implements `_serve()` (return when `_stop` is set) and
    `_release()`.
    """

    label: ClassVar[str] = "emulator"
    join_timeout: ClassVar[float] = 2.0     # [s] how long `close()` waits for the serving thread
    address: str
    sim: SimRobot

    def _init_serving(self) -> None:
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> Self:
        """Start serving in a background thread; returns self."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._serve, name=f"{self.label} {self.address}", daemon=True)
            self._thread.start()
        return self

    def serve_forever(self) -> None:
        """Serve in this thread until `close()` from another thread (or Ctrl-C)."""
        try:
            self._serve()
        finally:
            self.close()

    def close(self) -> None:
        """Stop serving, then release the transport and the simulator. Safe to call twice."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=self.join_timeout)
        self._release()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def closed(self) -> bool:
        """True once `close()` ran."""
        return self._stop.is_set()

    @abstractmethod
    def _serve(self) -> None:
        """Serve until `_stop` is set."""

    @abstractmethod
    def _release(self) -> None:
        """Close the transport and the simulator (after the serving thread stopped)."""


class StreamEmulator(EmulatorBase):
    """A streaming robot on TCP or a pseudo-terminal (see the module docstring).

    A subclass calls `_init_stream(speedup)` first, then opens its transport with `_open_pty()` or
    `_listen()` (or one of its own), and implements `_step()` (advance the robot one step, return
    the bytes to send) and `_on_bytes()` (handle command bytes); `_period` is the wall time
    between steps [s].
    """

    speedup: float

    def _init_stream(self, speedup: float) -> None:
        self._init_serving()
        self.speedup = speedup
        self.lock = threading.RLock()      # guards the simulator: the serving thread and the callers
        self._paused = False
        self._drop = False
        self._raw: list[bytes] = []
        self._corrupt = 0
        self._client: socket.socket | None = None
        self._listener: socket.socket | None = None
        self._master = self._slave = -1

    # -- transports ----------------------------------------------------------------------
    def _open_pty(self) -> str:
        """Open a pseudo-terminal in raw mode; return the path of its slave device."""
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)        # binary bytes: no echo, no CR/LF translation
        os.set_blocking(self._master, False)
        return os.ttyname(self._slave)

    def _listen(self, host: str, port: int) -> tuple[str, int]:
        """Listen on TCP `host`:`port` (0: any free port); return the bound host and port."""
        self._listener = socket.create_server((host, port))
        self._listener.setblocking(False)
        bound_host, bound_port = self._listener.getsockname()[:2]
        return bound_host, bound_port

    @property
    def connected(self) -> bool:
        """A TCP client is connected (always True on a pseudo-terminal)."""
        return self._client is not None or self._master >= 0

    # -- fault injection (tests, and trying out drivers) ---------------------------------
    def pause_stream(self) -> None:
        """Stop sending (and advancing the robot) without closing: a stalled link. Commands still arrive."""
        self._paused = True

    def resume_stream(self) -> None:
        """Undo `pause_stream`."""
        self._paused = False

    def send_raw(self, data: bytes) -> None:
        """Send `data` as is before the next frame (e.g. a burst of garbage)."""
        self._raw.append(bytes(data))

    def corrupt_frames(self, n: int) -> None:
        """Send the next `n` frames with a wrong checksum."""
        self._corrupt += n

    def _take_raw(self) -> bytes:
        # take the list before joining it: a send_raw() from another thread between the join and a
        # reset would be lost (it lands in the list we take, or the next one)
        taken, self._raw = self._raw, []
        return b"".join(taken)

    def _maybe_corrupt(self, frame: bytes) -> bytes:
        """`frame` with its checksum byte spoilt while `corrupt_frames` asks for it."""
        if self._corrupt > 0:
            self._corrupt -= 1
            return frame[:-1] + bytes((frame[-1] ^ 0x5A,))
        return frame

    # -- hooks ---------------------------------------------------------------------------
    @property
    @abstractmethod
    def _period(self) -> float:
        """Wall time between two steps [s]."""

    @abstractmethod
    def _step(self) -> bytes:
        """Advance the robot by one step; the bytes to send then."""

    @abstractmethod
    def _on_bytes(self, data: bytes) -> None:
        """Handle command bytes from the client."""

    def _on_connect(self) -> None:
        """A TCP client connected (a new session)."""

    def _active(self) -> bool:
        """Someone may be listening: steps are sent (and the robot advanced) only then."""
        return self._client is not None or self._master >= 0

    # -- serving -------------------------------------------------------------------------
    def _serve(self) -> None:
        next_step = time.perf_counter()
        while not self._stop.is_set():
            try:
                if self._listener is not None and self._client is None and not self._accept():
                    next_step = time.perf_counter()
                    continue
                if self._drop:
                    self._drop = False
                    self._disconnect()
                    continue
                now = time.perf_counter()
                if now >= next_step:
                    if self._active() and not self._paused:
                        raw = self._take_raw()
                        self._transmit(raw + self._step())
                    next_step = max(next_step + self._period, now)   # late: no burst of steps
                self._receive(max(0.0, next_step - time.perf_counter()))
            except OSError as exc:
                log.info("%s: client gone (%s)", self.label, exc)
                self._disconnect()

    def _accept(self) -> bool:
        assert self._listener is not None
        ready, _, _ = select.select([self._listener], [], [], 0.05)
        if not ready:
            return False
        try:
            client, peer = self._listener.accept()
        except BlockingIOError:
            return False
        client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._client = client
        self._on_connect()
        log.info("%s: client %s connected", self.label, peer)
        return True

    def _halt(self) -> None:
        """The client went away: stop the robot (an emulator without one overrides this)."""
        with self.lock:
            self.sim.command(Twist.ZERO)

    def _release_device(self) -> None:
        """Release what the emulator simulates (after the transport): the simulator by default."""
        with self.lock:
            self.sim.close()

    def _disconnect(self) -> None:
        self._halt()
        if self._client is not None:
            self._client.close()
            self._client = None

    def _transmit(self, data: bytes) -> None:
        if not data:
            return
        if self._client is not None:
            self._client.sendall(data)
        elif self._master >= 0:
            _, writable, _ = select.select([], [self._master], [], 0)
            if writable:            # nobody reading the terminal: drop the bytes, as a serial line does
                try:
                    os.write(self._master, data)
                except BlockingIOError:
                    pass

    def _input(self) -> socket.socket | int | None:
        """Where command bytes come from (None: nowhere yet)."""
        if self._client is not None:
            return self._client
        return self._master if self._master >= 0 else None

    def _read_input(self, fd: socket.socket | int) -> bytes:
        """Read what `fd` has (it is ready); b"" when nothing came or the client left."""
        if isinstance(fd, socket.socket):
            data = fd.recv(65536)
            if not data:
                log.info("%s: client closed the connection", self.label)
                self._disconnect()
            return data
        try:
            return os.read(fd, 65536)
        except BlockingIOError:
            return b""

    def _receive(self, wait: float) -> None:
        """Wait up to `wait` s for command bytes and handle them."""
        fd = self._input()
        if fd is None:
            time.sleep(wait)
            return
        ready, _, _ = select.select([fd], [], [], wait)
        if ready:
            data = self._read_input(fd)
            if data:
                self._on_bytes(data)

    def _release(self) -> None:
        for s in (self._client, self._listener):
            if s is not None:
                s.close()
        self._client = self._listener = None
        for fd in (self._master, self._slave):
            if fd >= 0:
                os.close(fd)
        self._master = self._slave = -1
        self._release_device()
