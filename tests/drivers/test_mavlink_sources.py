"""The MAVLink backend talks to one vehicle: locked to the system/component ids and the UDP address of
the first rover HEARTBEAT, it ignores a second sender (same or other system id, another port), sends
its commands to the vehicle only, listens on loopback by default, and ends the run with a robot error
(one line) when the vehicle reports a position that is not a number. Real UDP sockets throughout."""

from __future__ import annotations

import inspect
import math
import socket
import threading
import time
from collections.abc import Callable, Iterator

import pytest

from robotexp.errors import ProtocolError, RobotError
from robotexp.world.poses import resolve_pose
from robotexp.robot import Twist
from robotexp.world.model import World
from robotexp_drivers.mavlink import constants as C
from robotexp_drivers.mavlink.codec import MavlinkCodec, Message
from robotexp_drivers.mavlink.emulator import MavlinkEmulator
from robotexp_drivers.mavlink.robot import ROVER_RADIUS, MavlinkRobot

WaitFor = Callable[..., bool]


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Spoofer:
    """A second sender on its own UDP port: claims to be a rover (system `system`, component 1) far
    away at robot time 9998 s, and records what the backend sends it."""

    def __init__(self, port: int, system: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.01)
        self.dest = ("127.0.0.1", port)
        self.codec = MavlinkCodec(system, 1)
        self.received: list[Message] = []
        self.bytes_received = 0

    def send_round(self, t_ms: int) -> None:
        mav = self.codec.mav
        for m in (mav.heartbeat_encode(C.MAV_TYPE_GROUND_ROVER, C.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                       C.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | C.MAV_MODE_FLAG_SAFETY_ARMED,
                                       C.ROVER_MODE_GUIDED, C.MAV_STATE_ACTIVE, C.MAVLINK_VERSION),
                  mav.local_position_ned_encode(t_ms, 20.0, 20.0, 0.0, 1.0, 0.0, 0.0),
                  mav.attitude_encode(t_ms, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)):
            self.sock.sendto(self.codec.encode(m), self.dest)
        self.sock.sendto(b"\xfd\x09garbage that is not a frame", self.dest)
        try:
            while True:
                data = self.sock.recv(65536)
                self.bytes_received += len(data)
                self.received += MavlinkCodec(255, 190).feed(data)
        except (TimeoutError, BlockingIOError):
            pass

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def rover_to_gcs(world: World) -> Iterator[tuple[MavlinkEmulator, int]]:
    """An emulated rover sending to a ground-station port (as SITL `--out udp:...`), and that port."""
    port = free_udp_port()
    with MavlinkEmulator(world, pose=resolve_pose(world, "path1", ROVER_RADIUS)[0], speedup=10.0,
                         udp=f"127.0.0.1:{port}", obstacle_distance=True) as e:
        yield e, port


@pytest.mark.parametrize("system", [C.VEHICLE_SYSTEM_ID, 7])
def test_a_second_sender_is_ignored_and_gets_no_commands(rover_to_gcs: tuple[MavlinkEmulator, int],
                                                         wait_for: WaitFor, system: int) -> None:
    emu, port = rover_to_gcs
    with MavlinkRobot(f"udp:127.0.0.1:{port}") as robot:
        spoof = Spoofer(port, system)
        try:
            t0 = robot.read().time
            targets0 = emu.received["SET_POSITION_TARGET_LOCAL_NED"]
            for k in range(30):                          # 0.3 s of spoofing while commanding a slow turn
                spoof.send_round(9_998_000 + 50 * k)
                robot.command(Twist(0.0, 0.2))
                time.sleep(0.01)
            assert wait_for(lambda: emu.received["SET_POSITION_TARGET_LOCAL_NED"] > targets0 + 5)
            s = robot.read()
            true = emu.sim.read()
        finally:
            spoof.close()
    # nothing of ours went to the spoofer: no command, no heartbeat
    assert spoof.bytes_received == 0 and not spoof.received
    # the vehicle's pose and clock, not the spoofer's (20, 20) at 9998 s
    assert s.pose.distance_to(true.pose) < 0.05
    assert s.time - t0 < 100.0 and s.distance < 1.0       # 10x real time: a few s, not 9998
    assert s.extra["refused"] >= 30                     # counted (the link drops them unread)


def test_listens_on_loopback_by_default() -> None:
    default = inspect.signature(MavlinkRobot).parameters["address"].default
    assert default == f"udp:127.0.0.1:{C.DEFAULT_UDP_PORT}"


class FakeVehicle:
    """A rover in GUIDED, armed, with an EKF origin, sending pose and attitude at 50 Hz to a ground
    station port; `x` is the north position it reports (set it to NaN to break its estimate)."""

    def __init__(self, port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.connect(("127.0.0.1", port))
        self.codec = MavlinkCodec(C.VEHICLE_SYSTEM_ID, C.VEHICLE_COMPONENT_ID)
        self.x = 1.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        mav, k = self.codec.mav, 0
        while not self._stop.is_set():
            msgs = [mav.local_position_ned_encode(20 * k, self.x, 2.0, 0.0, 0.0, 0.0, 0.0),
                    mav.attitude_encode(20 * k, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0)]
            if k % 10 == 0:
                msgs.append(mav.heartbeat_encode(C.MAV_TYPE_GROUND_ROVER, C.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                                 C.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | C.MAV_MODE_FLAG_SAFETY_ARMED
                                                 | C.MAV_MODE_FLAG_GUIDED_ENABLED, C.ROVER_MODE_GUIDED,
                                                 C.MAV_STATE_ACTIVE, C.MAVLINK_VERSION))
            for m in msgs:
                try:
                    self.sock.send(self.codec.encode(m))
                except OSError:
                    pass
            k += 1
            time.sleep(0.02)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(1.0)
        self.sock.close()


def test_a_position_that_is_not_a_number_is_a_robot_error(wait_for: WaitFor) -> None:
    port = free_udp_port()
    vehicle = FakeVehicle(port)
    try:
        with MavlinkRobot(f"udp:127.0.0.1:{port}") as robot:
            s = robot.read()
            assert (s.pose.x, s.pose.y) == pytest.approx((2.0, 1.0))
            vehicle.x = math.nan

            def failed() -> bool:
                try:
                    robot.read()
                except RobotError:
                    return True
                return False

            assert wait_for(failed, 5.0)
            with pytest.raises(ProtocolError) as err:
                robot.read()
    finally:
        vehicle.close()
    text = str(err.value)
    assert "not a number" in text and "\n" not in text and f"udp:127.0.0.1:{port}" in text
