"""The MAVLink emulator as ArduPilot Rover runs it, and the backend's EKF origin and DISTANCE_SENSOR scan.

Frames sent by hand are written from the MAVLink XML definitions: fields in wire order (sorted by
type size, extensions last), CRC_EXTRA computed here from the field list as the MAVLink generator
does it, checksum X.25 (test_mavlink_codec.x25). Behaviour is ArduPilot's (GCS_Common.cpp
_set_mode_common, handle_command_ack fields, Rover handle_set_position_target_local_ned).
"""

from __future__ import annotations

import math
import socket
import struct
import time
from collections.abc import Callable

import pytest

from robotexp.world.poses import resolve_pose
from robotexp.robot import Pose
from robotexp.world.model import World
from robotexp_drivers.mavlink import constants as C
from robotexp_drivers.mavlink.codec import MavlinkCodec, Message, mavlink
from robotexp_drivers.mavlink.emulator import ROVER_PARAMS, MavlinkEmulator
from robotexp_drivers.mavlink.robot import MavlinkRobot, scan_from_distance_sensors

from test_mavlink_codec import x25  # the spec's X.25 CRC, written out there

WaitFor = Callable[..., bool]
GCS = (255, 190)


def crc_extra(name: str, fields: list[tuple[str, str, int]]) -> int:
    """CRC_EXTRA of a message from its XML fields (type, name, array length or 0), extensions left out."""
    size = {"char": 1, "uint8_t": 1, "int8_t": 1, "uint16_t": 2, "int16_t": 2, "uint32_t": 4, "int32_t": 4,
            "float": 4, "uint64_t": 8, "int64_t": 8, "double": 8}
    text = (name + " ").encode()
    crc = 0xFFFF
    data = bytearray(text)
    for ftype, fname, n in sorted(fields, key=lambda f: -size[f[0]]):   # stable: wire order
        data += f"{ftype} {fname} ".encode()
        if n:
            data.append(n)
    crc = x25(bytes(data))
    return (crc & 0xFF) ^ (crc >> 8)


PARAM_REQUEST_LIST = ("PARAM_REQUEST_LIST", [("uint8_t", "target_system", 0), ("uint8_t", "target_component", 0)])
PARAM_VALUE = ("PARAM_VALUE", [("char", "param_id", 16), ("float", "param_value", 0), ("uint8_t", "param_type", 0),
                               ("uint16_t", "param_count", 0), ("uint16_t", "param_index", 0)])
SET_GPS_GLOBAL_ORIGIN = ("SET_GPS_GLOBAL_ORIGIN", [("uint8_t", "target_system", 0), ("int32_t", "latitude", 0),
                                                   ("int32_t", "longitude", 0), ("int32_t", "altitude", 0)])
COMMAND_ACK = ("COMMAND_ACK", [("uint16_t", "command", 0), ("uint8_t", "result", 0)])


def v2_frame(msgid: int, payload: bytes, extra: int, seq: int = 0) -> bytes:
    """A MAVLink 2 frame from the GCS ids (255, 190)."""
    header = bytes([0xFD, len(payload), 0, 0, seq, *GCS]) + msgid.to_bytes(3, "little")
    return header + payload + struct.pack("<H", x25(header[1:] + payload + bytes([extra])))


@pytest.mark.untimed
def test_crc_extras_from_the_definitions_match_the_dialect() -> None:
    for (name, fields), msgid in ((PARAM_REQUEST_LIST, C.MAVLINK_MSG_ID_PARAM_REQUEST_LIST),
                                  (PARAM_VALUE, C.MAVLINK_MSG_ID_PARAM_VALUE),
                                  (SET_GPS_GLOBAL_ORIGIN, C.MAVLINK_MSG_ID_SET_GPS_GLOBAL_ORIGIN),
                                  (COMMAND_ACK, C.MAVLINK_MSG_ID_COMMAND_ACK)):
        assert mavlink.mavlink_map[msgid].crc_extra == crc_extra(name, fields), name
    for const, name in ((C.MAVLINK_MSG_ID_HOME_POSITION, "HOME_POSITION"), (C.MAVLINK_MSG_ID_DISTANCE_SENSOR,
                        "DISTANCE_SENSOR"), (C.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN, "GPS_GLOBAL_ORIGIN")):
        assert mavlink.mavlink_map[const].msgname == name
    for name in ("MAV_CMD_GET_HOME_POSITION", "MAV_RESULT_FAILED", "MAV_PARAM_TYPE_INT16", "MAV_SYS_STATUS_AHRS",
                 "MAV_SYS_STATUS_SENSOR_PROXIMITY", "ROVER_MODE_GUIDED", "ROVER_MODE_INITIALIZING",
                 "POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE", "MAV_DATA_STREAM_EXTRA3"):
        assert getattr(C, name) == getattr(mavlink, name), name


class Gcs:
    """A ground station on a UDP socket talking to the emulator (pymavlink's codec for what comes back)."""

    def __init__(self, emu: MavlinkEmulator) -> None:
        host, port = emu.address.split(":")[1:]
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.connect((host, int(port)))
        self.codec = MavlinkCodec(*GCS)
        self.got: list[Message] = []

    def send(self, data: bytes | Message) -> None:
        self.sock.send(data if isinstance(data, bytes) else self.codec.encode(data))

    def recv(self, kind: str, timeout: float = 3.0, cond: Callable[[Message], bool] = lambda m: True) -> Message:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            for i, m in enumerate(self.got):
                if m.get_type() == kind and cond(m):
                    del self.got[i]
                    return m
            self.sock.settimeout(max(end - time.monotonic(), 0.01))
            try:
                self.got += self.codec.feed(self.sock.recv(65536))
            except TimeoutError:
                break
        raise AssertionError(f"no {kind} within {timeout} s")

    def none_of(self, kind: str, seconds: float) -> bool:
        try:
            self.recv(kind, seconds)
        except AssertionError:
            return True
        return False

    def close(self) -> None:
        self.sock.close()

    def __enter__(self) -> Gcs:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def command(self, cmd: int, *params: float) -> Message:
        p = [*params, 0, 0, 0, 0, 0, 0, 0][:7]
        self.send(self.codec.mav.command_long_encode(1, 1, cmd, 0, *p))
        return self.recv("COMMAND_ACK", cond=lambda m: m.command == cmd)


@pytest.fixture
def rover(world: World) -> MavlinkEmulator:
    with MavlinkEmulator(world, pose=resolve_pose(world, "path1", 0.25)[0], speedup=10.0) as e:
        yield e  # type: ignore[misc]


def test_parameters_on_the_first_request(rover: MavlinkEmulator) -> None:
    with Gcs(rover) as gcs:
        name, fields = PARAM_REQUEST_LIST
        gcs.send(v2_frame(C.MAVLINK_MSG_ID_PARAM_REQUEST_LIST, bytes([1, 1]), crc_extra(name, fields)))
        values = [gcs.recv("PARAM_VALUE") for _ in ROVER_PARAMS]
        n = len(ROVER_PARAMS)
        assert [m.param_index for m in values] == list(range(n)) and {m.param_count for m in values} == {n}
        assert {m.param_id: (m.param_type, m.param_value) for m in values}["ATC_STR_RAT_MAX"] == (
            C.MAV_PARAM_TYPE_REAL32, pytest.approx(120.0))
        assert {m.param_id: m.param_type for m in values}["SYSID_THISMAV"] == C.MAV_PARAM_TYPE_INT16
        # PARAM_SET answers with the new value, rounded for an integer parameter; it acts on the rover
        gcs.send(gcs.codec.mav.param_set_encode(1, 1, b"WP_PIVOT_ANGLE", 45.4, C.MAV_PARAM_TYPE_INT16))
        m = gcs.recv("PARAM_VALUE", cond=lambda m: m.param_id == "WP_PIVOT_ANGLE")
        assert m.param_value == 45.0 and rover.param("WP_PIVOT_ANGLE") == 45.0
        gcs.send(gcs.codec.mav.param_request_read_encode(1, 1, b"GUID_TIMEOUT", -1))
        assert gcs.recv("PARAM_VALUE").param_value == pytest.approx(3.0)
        gcs.send(gcs.codec.mav.param_request_read_encode(1, 1, b"", 0))
        assert gcs.recv("PARAM_VALUE").param_id == ROVER_PARAMS[0][0]
        gcs.send(gcs.codec.mav.param_set_encode(1, 1, b"NO_SUCH_PARAM", 1.0, C.MAV_PARAM_TYPE_REAL32))
        gcs.send(gcs.codec.mav.param_set_encode(7, 1, b"GUID_TIMEOUT", 1.0, C.MAV_PARAM_TYPE_REAL32))  # other vehicle
        assert gcs.none_of("PARAM_VALUE", 0.5) and rover.param("GUID_TIMEOUT") == 3.0


def test_modes_acks_and_denials_as_ardupilot(rover: MavlinkEmulator) -> None:
    with Gcs(rover) as gcs:
        ack = gcs.command(C.MAV_CMD_DO_SET_MODE, 0, C.ROVER_MODE_HOLD)      # no CUSTOM_MODE_ENABLED flag
        assert ack.result == C.MAV_RESULT_DENIED and rover.mode == C.ROVER_MODE_MANUAL     # booted in MANUAL
        assert (ack.target_system, ack.target_component) == GCS
        assert gcs.command(C.MAV_CMD_DO_SET_MODE, 1, 99).result == C.MAV_RESULT_FAILED
        assert gcs.command(C.MAV_CMD_DO_SET_MODE, 1, C.ROVER_MODE_INITIALIZING).result == C.MAV_RESULT_FAILED
        assert gcs.command(C.MAV_CMD_DO_SET_MODE, 1, C.ROVER_MODE_GUIDED).result == C.MAV_RESULT_ACCEPTED
        gcs.send(gcs.codec.mav.set_mode_encode(1, 1, C.ROVER_MODE_MANUAL))
        ack = gcs.recv("COMMAND_ACK", cond=lambda m: m.command == C.MAVLINK_MSG_ID_SET_MODE)
        assert ack.result == C.MAV_RESULT_ACCEPTED and rover.mode == C.ROVER_MODE_MANUAL
        assert gcs.command(C.MAV_CMD_COMPONENT_ARM_DISARM, 2).result == C.MAV_RESULT_UNSUPPORTED
        assert gcs.command(12345).result == C.MAV_RESULT_UNSUPPORTED
        # hand-framed ACK decoding: command 176, result 2 as the definitions lay it out
        name, fields = COMMAND_ACK
        (m,) = MavlinkCodec(*GCS).feed(v2_frame(C.MAVLINK_MSG_ID_COMMAND_ACK, struct.pack("<HB", 176, 2),
                                                crc_extra(name, fields)))
        assert (m.command, m.result) == (176, 2)


def test_origin_home_and_targets_need_an_origin(rover: MavlinkEmulator, wait_for: WaitFor) -> None:
    with Gcs(rover) as gcs:
        gcs.send(gcs.codec.mav.request_data_stream_encode(1, 1, C.MAV_DATA_STREAM_ALL, 10, 1))
        assert gcs.recv("ATTITUDE") and gcs.none_of("LOCAL_POSITION_NED", 0.6)       # no origin indoors
        assert gcs.command(C.MAV_CMD_GET_HOME_POSITION).result == C.MAV_RESULT_FAILED
        gcs.command(C.MAV_CMD_DO_SET_MODE, 1, C.ROVER_MODE_GUIDED)
        # GUIDED needs a position estimate to arm (Rover AP_Arming gps_checks)
        assert gcs.command(C.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == C.MAV_RESULT_FAILED
        target = gcs.codec.mav.set_position_target_local_ned_encode(0, 1, 1, C.MAV_FRAME_BODY_NED,
                                                                    C.MASK_VELOCITY_YAW_RATE, 0, 0, 0, 0.3, 0, 0,
                                                                    0, 0, 0, 0, 0)
        gcs.send(target)
        assert wait_for(lambda: rover.ignored_targets == 1)
        name, fields = SET_GPS_GLOBAL_ORIGIN
        lat, lon, alt = -198697000, -439637000, 800000                  # degE7, degE7, mm
        gcs.send(v2_frame(C.MAVLINK_MSG_ID_SET_GPS_GLOBAL_ORIGIN, struct.pack("<iiiB", lat, lon, alt, 1),
                          crc_extra(name, fields)))
        o = gcs.recv("GPS_GLOBAL_ORIGIN")
        assert (o.latitude, o.longitude, o.altitude) == (lat, lon, alt)
        assert gcs.recv("LOCAL_POSITION_NED")
        assert gcs.command(C.MAV_CMD_GET_HOME_POSITION).result == C.MAV_RESULT_ACCEPTED
        home = gcs.recv("HOME_POSITION")
        assert gcs.command(C.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == C.MAV_RESULT_ACCEPTED
        p = rover.home
        assert p is not None and (home.x, home.y) == pytest.approx((p[3], p[4]), abs=1e-4)
        # home latitude: origin + x_ned / R (rad), within the int32 degE7 rounding
        assert home.latitude == round((lat / 1e7 + math.degrees(home.x / 6378137.0)) * 1e7)
        gcs.send(target)
        assert wait_for(lambda: rover.sim.read().velocity.v > 0.1)


def test_sys_status_health_bits(rover: MavlinkEmulator) -> None:
    with Gcs(rover) as gcs:
        gcs.send(gcs.codec.mav.request_data_stream_encode(1, 1, C.MAV_DATA_STREAM_EXTENDED_STATUS, 10, 1))
        s = gcs.recv("SYS_STATUS")
        must = (C.MAV_SYS_STATUS_SENSOR_3D_GYRO | C.MAV_SYS_STATUS_SENSOR_3D_ACCEL | C.MAV_SYS_STATUS_SENSOR_3D_MAG
                | C.MAV_SYS_STATUS_AHRS | C.MAV_SYS_STATUS_SENSOR_BATTERY | C.MAV_SYS_STATUS_SENSOR_PROXIMITY)
        assert s.onboard_control_sensors_present & must == must
        assert s.onboard_control_sensors_health & must == must                             # nothing failing
        assert not s.onboard_control_sensors_present & C.MAV_SYS_STATUS_GEOFENCE             # no fence...
        assert s.onboard_control_sensors_health & C.MAV_SYS_STATUS_GEOFENCE                  # ...and no breach
        assert not s.onboard_control_sensors_enabled & C.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS  # disarmed
        gcs.command(C.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        s = gcs.recv("SYS_STATUS",
                     cond=lambda m: m.onboard_control_sensors_enabled & C.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS)
        assert s.voltage_battery == 12600


def _heading_deg(rover: MavlinkEmulator) -> float:
    return math.degrees(rover.sim.read().pose.theta)


@pytest.mark.parametrize("mask", [C.MASK_VELOCITY_MAVPROXY, C.MASK_VELOCITY])
def test_velocity_only_targets_turn_to_face_the_vector(world: World, wait_for: WaitFor, mask: int) -> None:
    # facing east (NED yaw 90 deg), asked to go north at 0.4 m/s (LOCAL_NED, masks 4039 as MAVProxy's
    # `velocity` and 3559 as the Rover wiki's): the rover used to drive sideways; it pivots north
    # (error 90 > WP_PIVOT_ANGLE 60), then drives north
    p1 = resolve_pose(world, "path1", 0.25)[0]
    start = Pose(p1.x, p1.y, 0.0)
    with MavlinkEmulator(world, pose=start, speedup=10.0, origin=C.DEFAULT_ORIGIN) as rover:
        with Gcs(rover) as gcs:
            gcs.command(C.MAV_CMD_DO_SET_MODE, 1, C.ROVER_MODE_GUIDED)
            gcs.command(C.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            target = gcs.codec.mav.set_position_target_local_ned_encode(0, 1, 1, C.MAV_FRAME_LOCAL_NED, mask,
                                                                        0, 0, 0, 0.4, 0.0, 0, 0, 0, 0, 0, 0)
            moved_while_turning = []
            end = time.monotonic() + 1.5                   # 15 s of robot time at 10x
            while time.monotonic() < end:
                gcs.send(target)
                s = rover.sim.read()
                if abs(math.degrees(s.pose.theta) - 90) > 60:
                    moved_while_turning.append(s.pose.distance_to(start))
                time.sleep(0.05)
            p = rover.sim.read().pose
    assert max(moved_while_turning) < 0.02                    # a pivot: turned in place
    assert math.degrees(p.theta) == pytest.approx(90.0, abs=3.0)
    assert p.y - start.y > 0.3 and abs(p.x - start.x) < 0.1   # then north, not east


def test_body_frame_velocity_target_is_relative_to_the_heading(world: World) -> None:
    p1 = resolve_pose(world, "path1", 0.25)[0]
    start = Pose(p1.x, p1.y, 0.0)        # facing east: NED yaw 90 deg
    with MavlinkEmulator(world, pose=start, speedup=10.0, origin=C.DEFAULT_ORIGIN) as rover:
        with Gcs(rover) as gcs:
            gcs.command(C.MAV_CMD_DO_SET_MODE, 1, C.ROVER_MODE_GUIDED)
            gcs.command(C.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            # BODY_NED: vy > 0 is to the right: from east, the goal is south (NED yaw 180 deg)
            gcs.send(gcs.codec.mav.set_position_target_local_ned_encode(0, 1, 1, C.MAV_FRAME_BODY_NED, C.MASK_VELOCITY,
                                                                        0, 0, 0, 0.0, 0.3, 0, 0, 0, 0, 0, 0))
            # the target travels on its own: a heartbeat already on its way may come before it is handled
            deadline = time.monotonic() + 2.0
            while rover._heading_goal is None and time.monotonic() < deadline:
                gcs.recv("HEARTBEAT")
            goal = rover._heading_goal
    assert goal is not None and abs(abs(math.degrees(goal[0])) - 180.0) < 0.1 and goal[1] == pytest.approx(0.3)


def test_backend_sets_the_origin_and_scans_from_distance_sensors(world: World) -> None:
    start = resolve_pose(world, "path1", 0.25)[0]
    with MavlinkEmulator(world, pose=start, speedup=10.0) as rover:       # proximity on, no OBSTACLE_DISTANCE
        with MavlinkRobot(rover.address) as robot:
            assert robot.origin_set and rover.origin == pytest.approx(C.DEFAULT_ORIGIN, abs=1e-7)
            assert robot.describe()["ekf_origin"] == "set by robotexp"
            s = robot.read()
            assert s.pose.distance_to(rover.sim.read().pose) < 1e-5
            assert s.laser is not None and s.laser.angles.size == C.PROXIMITY_SECTORS
            # each sector reads the nearest echo of the emulator's full-circle scan within +-22.5 deg
            scan = rover.sim.scan()
            for a, r in zip(s.laser.angles.tolist(), s.laser.ranges.tolist(), strict=True):
                near = [rr for aa, rr in zip(scan.angles.tolist(), scan.ranges.tolist(), strict=True)
                        if abs(math.remainder(aa - a, 2 * math.pi)) <= math.radians(22.5) + 1e-9]
                want = min(near)
                assert (r == math.inf and want == math.inf) or r == pytest.approx(want, abs=0.011)
    with MavlinkEmulator(world, pose=start, speedup=10.0, origin=(10.0, 20.0, 5.0)) as rover:
        with MavlinkRobot(rover.address) as robot:
            assert not robot.origin_set and rover.origin == (10.0, 20.0, 5.0)


def test_distance_sensor_scan_units_and_orientations() -> None:
    mav = MavlinkCodec(1, 1).mav
    msgs = [mav.distance_sensor_encode(0, 20, 300, 150, 0, 10, 0, 0),      # ahead, 1.5 m
            mav.distance_sensor_encode(0, 20, 300, 301, 0, 12, 2, 0),      # right (clockwise 90): nothing
            mav.distance_sensor_encode(0, 20, 300, 10, 0, 14, 4, 0),       # behind, below min: left out
            mav.distance_sensor_encode(0, 20, 300, 80, 0, 19, 24, 0)]      # up (PITCH_90): left out
    scan = scan_from_distance_sensors(msgs)
    assert scan is not None and scan.range_max == 3.0
    assert scan.angles.tolist() == pytest.approx([-math.pi / 2, 0.0])
    assert scan.ranges.tolist() == [math.inf, 1.5]
    assert scan_from_distance_sensors(msgs[2:]) is None
