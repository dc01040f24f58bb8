"""P3DXRobot against a scripted robot on a real TCP socket: handshake, units, wrap-around, commands.

Byte vectors come from shared/protocols/aria-sip.md §2.1; expected SI values are computed by
hand from §5 and §9 (DistConvFactor 0.485 mm/unit, AngleConvFactor 0.001534 rad/unit).
"""

from __future__ import annotations

import math
import socket
import threading
import time

import pytest

from robotexp.errors import ConfigError, ConnectionLost, ProtocolError
from robotexp.robot import Twist
from robotexp_drivers.p3dx import codec as k
from robotexp_drivers.p3dx.link import SerialLink, address_to_url
from robotexp_drivers.p3dx.robot import P3DXRobot

SYNC2_REPLY = bytes.fromhex("FAFB1A024D6F62696C6553696D0050696F6E65657200703364780093 45".replace(" ", ""))
VEL_300 = bytes.fromhex("FAFB060B3B2C01373C")
RVEL_20 = bytes.fromhex("FAFB06153B1400293B")


class ScriptedRobot:
    """A robot side written from the document: answers the handshake, then sends given SIPs."""

    def __init__(self, sips: list[bytes], *, config: bool = True, silent_after: bool = True) -> None:
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.sips, self.config, self.silent_after = sips, config, silent_after
        self.received = bytearray()
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        conn, _ = self.server.accept()
        conn.settimeout(0.02)
        dec = k.CommandDecoder(max_count=255)
        opened, queue = False, list(self.sips)
        next_sip = 0.0
        try:
            while not self.done.is_set():
                try:
                    data = conn.recv(4096)
                    if not data:
                        break
                except TimeoutError:
                    data = b""
                self.received += data
                for cmd in dec.feed(data):
                    if not opened and cmd.cmd in (0, 1) and cmd.arg is None:
                        conn.sendall(k.frame(cmd.cmd))
                    elif not opened and cmd.cmd == 2:
                        conn.sendall(SYNC2_REPLY)
                    elif cmd.cmd == 1 and cmd.arg == 1:
                        opened = True
                    elif cmd.cmd == k.c.CMD_CONFIG and self.config:
                        conn.sendall(k.encode_packet(k.mobilesim_config()))
                if opened and time.monotonic() >= next_sip and (queue or not self.silent_after):
                    if queue:
                        conn.sendall(queue.pop(0) if len(queue) > 1 or self.silent_after else queue[0])
                    next_sip = time.monotonic() + 0.3
        finally:
            conn.close()
            self.server.close()

    def close(self) -> None:
        self.done.set()
        self.thread.join(timeout=2)


def sip(**kw: object) -> bytes:
    return k.encode_packet(k.StandardSip(**kw))  # type: ignore[arg-type]


def test_address_forms() -> None:
    assert address_to_url("localhost") == "socket://localhost:8101"
    assert address_to_url("10.0.0.5:8102") == "socket://10.0.0.5:8102"
    assert address_to_url("/dev/ttyUSB0") == "/dev/ttyUSB0"
    assert address_to_url("COM3") == "COM3"
    assert address_to_url("socket://h:1") == "socket://h:1"
    assert address_to_url("loop://") == "loop://"
    with pytest.raises(ConfigError):
        address_to_url("host:70000")
    with pytest.raises(ConfigError):
        address_to_url("  ")
    # tcp://host:port, the form other tools write, is host:port; without a port it is refused
    assert address_to_url("tcp://127.0.0.1:8131") == address_to_url("TCP://127.0.0.1:8131/") == "socket://127.0.0.1:8131"
    with pytest.raises(ConfigError, match="p3dx: address 'tcp://robot': give host:port"):
        address_to_url("tcp://robot")


def test_every_driver_takes_host_port_and_tcp_urls() -> None:
    from robotexp_drivers.kobuki.link import KobukiLink
    from robotexp_drivers.lasers.base import laser_url

    assert laser_url("urg", "tcp://10.0.0.9:10940") == laser_url("urg", "10.0.0.9:10940") == "socket://10.0.0.9:10940"
    assert laser_url("urg", "/dev/ttyACM0") == "/dev/ttyACM0" and laser_url("urg", "host") == "host"
    with pytest.raises(ConfigError, match="kobuki: address 'host:0': TCP port must be 1..65535"):
        KobukiLink("host:0")
    with pytest.raises(ConfigError, match="kobuki: empty address"):
        KobukiLink(" ")


def test_link_loop_and_unreachable() -> None:
    link = SerialLink("loop://", timeout=0.01)
    link.write(b"\xfa\xfb\x03\x00\x00\x00")
    assert link.read() == b"\xfa\xfb\x03\x00\x00\x00"
    assert link.read() == b""
    link.close()
    with pytest.raises(ConnectionLost):
        link.write(b"x")
    free = socket.create_server(("127.0.0.1", 0))
    port = free.getsockname()[1]
    free.close()
    with pytest.raises(ConnectionLost):
        SerialLink(f"127.0.0.1:{port}")


def test_link_eof_is_connection_lost() -> None:
    server = socket.create_server(("127.0.0.1", 0))
    link = SerialLink(f"127.0.0.1:{server.getsockname()[1]}", timeout=0.05)
    conn, _ = server.accept()
    conn.close()
    server.close()
    with pytest.raises(ConnectionLost):
        for _ in range(20):
            link.read()
    link.close()


def test_units_wraparound_and_commands() -> None:
    sips = [
        sip(xpos=0x7FF0, ypos=0x0010, thpos=1024, left_vel=100, right_vel=300, battery_dv=124,
            stall_bumpers=0x0200, sonar=((3, 1234), (4, 5000)), grip_state=0, analog_port=0, analog=0,
            digin=0, digout=0, battery_x10=125, charge_state=0, rot_vel_x10=150),
        # x crosses the 15-bit wrap forward by 0x20 units, y backwards by 0x20 units
        sip(xpos=0x0010, ypos=0x7FF0, thpos=-1024, battery_dv=124),
    ]
    robot_side = ScriptedRobot(sips)
    try:
        with P3DXRobot(f"127.0.0.1:{robot_side.port}", laser=False) as robot:
            assert robot.describe()["name"] == "MobileSim" and robot.robot_subtype == "p3dx"
            assert robot.is_simulator
            first = robot.read()
            assert first.pose.x == pytest.approx(32752 * 0.485 / 1000)
            assert first.pose.y == pytest.approx(16 * 0.485 / 1000)
            assert first.pose.theta == pytest.approx(1024 * 0.001534)
            assert first.velocity.v == pytest.approx(0.2)
            assert first.velocity.w == pytest.approx(math.radians(15.0))
            assert first.battery == pytest.approx(12.5)
            assert first.stalled and first.bumpers[0] and not any(first.bumpers[1:])
            assert first.sonar is not None
            assert first.sonar.ranges[3] == pytest.approx(1.234) and math.isinf(first.sonar.ranges[4])
            assert first.time == pytest.approx(0.1)
            deadline = time.monotonic() + 2
            while robot.read().time < 0.15 and time.monotonic() < deadline:
                time.sleep(0.01)
            second = robot.read()
            assert second.pose.x == pytest.approx((32752 + 32) * 0.485 / 1000)
            assert second.pose.y == pytest.approx((16 - 32) * 0.485 / 1000)
            assert second.pose.theta == pytest.approx(-1024 * 0.001534)
            assert second.battery == pytest.approx(12.4)
            assert not second.stalled and second.extra["collisions"] == 1
            robot.command(Twist(0.3, math.radians(20)))
            time.sleep(0.05)
            assert VEL_300 + RVEL_20 in robot_side.received
            # the scripted robot is silent now: the link is lost within ~1 s
            deadline = time.monotonic() + 3
            with pytest.raises(ConnectionLost):
                while time.monotonic() < deadline:
                    robot.read()
                    time.sleep(0.02)
    finally:
        robot_side.close()
    sent = bytes(robot_side.received)
    assert sent.startswith(bytes.fromhex("FAFB03000000"))          # flush, then SYNC0
    assert bytes.fromhex("FAFB060 13B0100023B".replace(" ", "")) in sent   # OPEN int 1
    assert bytes.fromhex("FAFB06043B0100053B") in sent               # ENABLE 1


def test_handshake_fails_cleanly() -> None:
    server = socket.create_server(("127.0.0.1", 0))     # accepts, never answers
    try:
        with pytest.raises(ProtocolError, match="no handshake"):
            P3DXRobot(f"127.0.0.1:{server.getsockname()[1]}", connect_timeout=0.3)
    finally:
        server.close()
