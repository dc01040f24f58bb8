"""KobukiLink and KobukiRobot against a scripted Kobuki on a real TCP socket.

Expected SI values are computed by hand from shared/protocols/kobuki.md: 0.085292090497737556558 mm
per encoder tick (section 6), 0.01 deg per inertial unit (4.3), 0.1 V per battery unit (4.1),
20 ms per frame, Base Control conversion of 3.1 (b = 230 mm).
"""

from __future__ import annotations

import math
import socket
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from robotexp.errors import ConfigError, ConnectionLost, ProtocolError, RobotError
from robotexp.robot import Pose, Twist
from robotexp_drivers.kobuki import constants as K
from robotexp_drivers.kobuki.codec import (
    BaseControl,
    BasicSensorData,
    FirmwareVersion,
    FrameDecoder,
    HardwareVersion,
    InertialSensor,
    Message,
    RequestExtra,
    SoundSequence,
    UniqueDeviceID,
    encode_messages,
)
from robotexp_drivers.kobuki.link import KobukiLink
from robotexp_drivers.kobuki.robot import KobukiRobot

WaitFor = Callable[..., bool]                # the `wait_for` fixture (conftest.py)

TICK_MM = 0.085292090497737556558


def basic(ts: int, left: int, right: int, *, bumper: int = 0, cliff: int = 0, wheel_drop: int = 0,
          battery_dv: int = 160) -> BasicSensorData:
    return BasicSensorData(ts, bumper, wheel_drop, cliff, left, right, 0, 0, 0, 0, battery_dv, 0)


class ScriptedKobuki:
    """A robot side on TCP: streams `frames(i)` every `period` s, answers Request Extra, records commands."""

    def __init__(self, frames: Callable[[int], list[Message] | bytes | None], *, period: float = 0.005,
                 answer: bool = True) -> None:
        self.server = socket.create_server(("127.0.0.1", 0))
        self.address = f"socket://127.0.0.1:{self.server.getsockname()[1]}"
        self.frames, self.period, self.answer = frames, period, answer
        self.commands: list[Message] = []
        self.done = threading.Event()
        self.index = 0
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def base_controls(self) -> list[BaseControl]:
        return [c for c in list(self.commands) if isinstance(c, BaseControl)]

    def _run(self) -> None:
        self.server.settimeout(5.0)
        try:
            conn, _ = self.server.accept()
        except TimeoutError:
            return
        dec = FrameDecoder("command")
        pending = 0
        next_send = time.monotonic()
        try:
            while not self.done.is_set():
                now = time.monotonic()
                if now >= next_send:          # a steady stream, whatever the host sends
                    next_send = max(next_send + self.period, now)
                    content = self.frames(self.index)
                    if content is None:       # the script ends: close the connection
                        break
                    if isinstance(content, bytes):
                        out = content
                    else:
                        extra: list[Message] = []
                        if pending and content:
                            extra = [HardwareVersion(0x010004), FirmwareVersion(0x010104), UniqueDeviceID(1, 2, 3)]
                            pending = 0
                        out = encode_messages(*content, *extra) if content else b""
                    if out:
                        conn.sendall(out)
                    self.index += 1
                conn.settimeout(max(next_send - time.monotonic(), 1e-4))
                try:
                    data = conn.recv(4096)
                except TimeoutError:
                    data = b""
                else:
                    if not data:
                        break
                for frame in dec.feed(data):
                    for m in frame:
                        self.commands.append(m)
                        if isinstance(m, RequestExtra) and self.answer:
                            pending = m.flags
        except OSError:
            pass
        finally:
            conn.close()

    def close(self) -> None:
        self.done.set()
        self.thread.join(timeout=2.0)
        self.server.close()


@pytest.fixture
def scripted() -> Iterator[Callable[..., ScriptedKobuki]]:
    peers: list[ScriptedKobuki] = []

    def make(frames: Callable[[int], list[Message] | bytes | None], **kw: object) -> ScriptedKobuki:
        peer = ScriptedKobuki(frames, **kw)  # type: ignore[arg-type]
        peers.append(peer)
        return peer

    yield make
    for p in peers:
        p.close()


# ------------------------------------------------------------------------------------------ link
def test_link_loop_round_trip_and_double_close() -> None:
    link = KobukiLink("loop://")
    link.write(b"\xaa\x55\x03\x04\x01\x00\x06")
    got = b""
    for _ in range(10):
        got += link.read_some()
        if len(got) >= 7:
            break
    assert got == b"\xaa\x55\x03\x04\x01\x00\x06"
    assert (link.bytes_in, link.bytes_out) == (7, 7)
    link.close()
    link.close()
    assert not link.is_open


def test_link_refused_address_is_connection_lost() -> None:
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    server.close()                              # nobody listens there any more
    with pytest.raises(ConnectionLost, match=f"127.0.0.1:{port}"):
        KobukiLink(f"socket://127.0.0.1:{port}")


def test_link_eof_is_connection_lost() -> None:
    server = socket.create_server(("127.0.0.1", 0))
    link = KobukiLink(f"socket://127.0.0.1:{server.getsockname()[1]}")
    conn, _ = server.accept()
    conn.sendall(b"\x01\x02")
    conn.close()
    server.close()
    with pytest.raises(ConnectionLost, match="gone"):
        for _ in range(1000):
            link.read_some()
    link.close()


# ------------------------------------------------------------------------------------ odometry etc.
def test_odometry_units_encoder_wrap_gyro_offset_and_info(scripted: Callable[..., ScriptedKobuki],
                                                          wait_for: WaitFor) -> None:
    # frames 0..9: references (encoders near the top of uint16, gyro at 10.00 deg, timestamp 65530 ms;
    # repeated so that the stale-input flush on connect cannot eat them all); then both wheels
    # +1000 ticks across the wrap (65000 -> 464), gyro still 10.00 deg, timestamp 65530 -> 14 (+20 ms),
    # repeated (zero deltas).
    def frames(i: int) -> list[Message]:
        if i < 10:
            return [basic(65530, 65000, 65000), InertialSensor(1000, 0)]
        return [basic(14, 464, 464, battery_dv=158), InertialSensor(1000, 0)]

    peer = scripted(frames)
    with KobukiRobot(peer.address, pose=Pose(1.0, 2.0, math.radians(30)), sound=True) as robot:
        assert wait_for(lambda: robot.read().extra["frames"] >= 15)
        s = robot.read()
        d = 1000 * TICK_MM / 1000.0                       # 1000 ticks [m] = 0.0852920905 m
        assert s.time == pytest.approx(0.020)             # 65530 -> 14 ms is one 20 ms step
        assert s.pose.x == pytest.approx(1.0 + d * math.cos(math.radians(30)), abs=1e-9)
        assert s.pose.y == pytest.approx(2.0 + d * math.sin(math.radians(30)), abs=1e-9)
        assert s.pose.theta == pytest.approx(math.radians(30))   # gyro minus its first reading
        assert s.velocity.v == pytest.approx(d / 0.020)
        assert s.battery == pytest.approx(15.8)
        assert s.distance == pytest.approx(d)
        assert not s.stalled and s.bumpers == (False, False, False)
        info = robot.describe()
        assert (info["hardware"], info["firmware"], info["udid"]) == ("1.0.4", "1.1.4", "1-2-3")
    sounds = [c for c in peer.commands if isinstance(c, SoundSequence)]
    assert sounds == [SoundSequence(K.SOUND_ON)]
    assert any(isinstance(c, RequestExtra) and c.flags == 0x0B for c in peer.commands)
    assert peer.base_controls()[-1] == BaseControl(0, 0)      # close() stops the robot


def test_pure_turn_heading_from_gyro(scripted: Callable[..., ScriptedKobuki], wait_for: WaitFor) -> None:
    def frames(i: int) -> list[Message]:
        if i < 10:
            return [basic(0, 100, 100), InertialSensor(-500, 0)]          # -5.00 deg: the offset
        # left -250 ticks, right +250 ticks: no translation; gyro now at +85.00 deg, 45 deg/s
        return [basic(20, 100 - 250 + 65536, 100 + 250), InertialSensor(8500, 4500)]

    peer = scripted(frames)
    with KobukiRobot(peer.address, version_timeout=0.05) as robot:
        assert wait_for(lambda: robot.read().extra["frames"] >= 15)
        s = robot.read()
        assert s.pose.theta == pytest.approx(math.radians(90.0))
        assert (s.pose.x, s.pose.y) == (pytest.approx(0.0, abs=1e-12), pytest.approx(0.0, abs=1e-12))
        assert s.velocity.w == pytest.approx(math.radians(45.0))
        assert s.distance == pytest.approx(0.0, abs=1e-12)


def test_commands_and_hazard_filter(scripted: Callable[..., ScriptedKobuki], wait_for: WaitFor) -> None:
    hazard = {"bumper": 0, "cliff": 0, "wheel_drop": 0}
    peer = scripted(lambda i: [basic(20 * i % 65536, 0, 0, **hazard)])
    with KobukiRobot(peer.address, version_timeout=0.05, sound=False) as robot:
        robot.command(Twist(0.2, 0.5))                        # kobuki.md 3.1 example: (257, 400)
        assert wait_for(lambda: peer.base_controls()[-1:] == [BaseControl(257, 400)])
        hazard["bumper"] = K.BUMPER_LEFT
        assert wait_for(lambda: robot.read().stalled)
        s = robot.read()
        assert s.bumpers == (False, False, True) and s.extra["collisions"] == 1.0
        robot.command(Twist(0.2, 0.5))          # forward refused while bumped: turn in place 0.5 rad/s
        assert wait_for(lambda: peer.base_controls()[-1:] == [BaseControl(57, 1)])   # 230 * 0.5 / 2 = 57.5
        robot.command(Twist(-0.2, 0.0))         # backing away is allowed
        assert wait_for(lambda: peer.base_controls()[-1:] == [BaseControl(-200, 0)])
        hazard.update(bumper=0, wheel_drop=K.WHEEL_DROP_RIGHT)
        assert wait_for(lambda: robot.read().extra["wheel_drop"] == 1.0)
        robot.command(Twist(-0.2, 0.3))         # a dropped wheel refuses everything
        assert wait_for(lambda: peer.base_controls()[-1:] == [BaseControl(0, 0)])
        hazard.update(wheel_drop=0, cliff=K.CLIFF_CENTRE)
        assert wait_for(lambda: robot.read().extra["cliff"] == 2.0 and robot.read().stalled)
        robot.command(Twist(0.3, 0.0))
        assert wait_for(lambda: peer.base_controls()[-1:] == [BaseControl(0, 0)])
        assert robot.read().extra["collisions"] == 1.0       # one bumper press


def test_watchdog_stops_a_silent_control_loop(scripted: Callable[..., ScriptedKobuki], wait_for: WaitFor,
                                             cpu_wait: Any) -> None:
    peer = scripted(lambda i: [basic(20 * i % 65536, 0, 0)])
    with KobukiRobot(peer.address, version_timeout=0.05, sound=False, watchdog=0.2) as robot:
        robot.command(Twist(0.1, 0.0))
        assert wait_for(lambda: peer.base_controls()[-1:] == [BaseControl(100, 0)])
        n = len(peer.base_controls())
        t0, mark = time.monotonic(), cpu_wait.total()
        assert wait_for(lambda: robot.watchdog_stops == 1, timeout=30.0)
        assert time.monotonic() - t0 < 1.0 + cpu_wait.since(mark)   # bounded: 0.2 s + a frame (+ a loaded CPU's wait)
        assert wait_for(lambda: peer.base_controls()[-1:] == [BaseControl(0, 0)])
        assert len(peer.base_controls()) > n + 1        # re-sent with the stream before the stop


def test_connect_errors(scripted: Callable[..., ScriptedKobuki]) -> None:
    silent = scripted(lambda i: b"")
    with pytest.raises(ConnectionLost, match="no data"):
        KobukiRobot(silent.address, connect_timeout=0.2)
    noisy = scripted(lambda i: bytes([0xAA, 0x55, 0x05, 1, 2, 3, 4, 5, 0x77]))   # checksum wrong
    with pytest.raises(ProtocolError, match="no valid Kobuki frame"):
        KobukiRobot(noisy.address, connect_timeout=0.2)
    with pytest.raises(ConfigError, match="watchdog"):
        KobukiRobot(silent.address, watchdog=0.0)


def test_peer_closing_raises_connection_lost_and_close_is_quiet(scripted: Callable[..., ScriptedKobuki]) -> None:
    peer = scripted(lambda i: [basic(20 * i % 65536, 0, 0)] if i < 60 else None)
    robot = KobukiRobot(peer.address, version_timeout=0.05, sound=False)
    with pytest.raises(ConnectionLost):
        clock = robot.make_clock(0.1)
        for _ in range(100):                     # 60 frames at 20 ms: 1.2 s of robot time, then EOF
            clock.tick()
            robot.read()
    robot.close()                                # the stop cannot be sent: logged, not raised
    assert robot.closed
    with pytest.raises(RobotError, match="closed"):
        robot.read()


def test_paced_clock_ticks_every_five_frames(scripted: Callable[..., ScriptedKobuki]) -> None:
    peer = scripted(lambda i: [basic(20 * i % 65536, 0, 0)])
    with KobukiRobot(peer.address, version_timeout=0.05, sound=False) as robot:
        clock = robot.make_clock(0.1)
        t0 = robot.read().time
        frames0 = robot.read().extra["frames"]
        for _ in range(4):
            clock.tick()
        s = robot.read()
        # each tick waits for >= 0.1 s of robot time (5 frames); a tick may end later when
        # several frames arrive in one read, and the next period counts from there
        assert 0.4 - 1e-9 <= clock.now() <= s.time - t0 + 1e-9
        assert s.extra["frames"] - frames0 >= 20
