"""Forty ground-station checks of the MAVLink rover emulator against ArduPilot Rover's behaviour.

pymavlink's `mavutil` is the ground station (system 255, component 190) over UDP. Each check names, in
a comment, the Rover (or shared GCS library) source file and function whose behaviour it checks. The
rover stands at the middle of an empty 20 x 20 m hall facing east (NED yaw 90 deg), so NED north is
our +y and east our +x.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest
from pymavlink import mavutil

from robotexp.robot import Pose
from robotexp.world.model import World
from robotexp_drivers.mavlink import constants as C
from robotexp_drivers.mavlink.codec import Message
from robotexp_drivers.mavlink.emulator import MavlinkEmulator

# a 20 x 20 m hall with 0.2 m walls
HALL = World("hall", np.array([[0.0, 10.0, 10.0, 0.1, 0.0], [0.0, -10.0, 10.0, 0.1, 0.0],
                               [10.0, 0.0, 0.1, 10.0, 0.0], [-10.0, 0.0, 0.1, 10.0, 0.0]]))
ORIGIN = C.DEFAULT_ORIGIN
R_EARTH = 6378137.0


class Station:
    """A pymavlink ground station talking to `emu`."""

    def __init__(self, emu: MavlinkEmulator) -> None:
        self.emu = emu
        self.conn = mavutil.mavlink_connection(emu.address, source_system=255, source_component=190)
        self.mav = self.conn.mav
        self.mav.heartbeat_send(C.MAV_TYPE_GCS, C.MAV_AUTOPILOT_INVALID, 0, 0, 0)

    def recv(self, kind: str, cond: Callable[[Message], bool] = lambda m: True, timeout: float = 3.0) -> Message:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.conn.recv_match(type=kind, blocking=True, timeout=max(end - time.monotonic(), 0.01))
            if m is not None and cond(m):
                return m
        raise AssertionError(f"no {kind} within {timeout} s")

    def none_of(self, kind: str, seconds: float) -> bool:
        try:
            self.recv(kind, timeout=seconds)
        except AssertionError:
            return True
        return False

    def heartbeat(self) -> Message:
        """The next vehicle HEARTBEAT (one already queued is skipped: it may predate a change)."""
        self.recv("HEARTBEAT")
        return self.recv("HEARTBEAT")

    def command(self, cmd: int, *params: float) -> Message:
        p = [*params, 0, 0, 0, 0, 0, 0, 0][:7]
        self.mav.command_long_send(1, 1, cmd, 0, *p)
        return self.recv("COMMAND_ACK", lambda m: m.command == cmd)

    def command_int(self, cmd: int, frame: int, p1: float, p2: float, lat_e7: int, lon_e7: int) -> Message:
        self.mav.command_int_send(1, 1, frame, cmd, 0, 0, p1, p2, 0, 0, lat_e7, lon_e7, 0)
        return self.recv("COMMAND_ACK", lambda m: m.command == cmd)

    def mode(self, mode: int) -> int:
        return int(self.command(C.MAV_CMD_DO_SET_MODE, C.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode).result)

    def arm(self, on: bool = True) -> int:
        return int(self.command(C.MAV_CMD_COMPONENT_ARM_DISARM, 1 if on else 0).result)

    def guided_armed(self) -> None:
        assert self.mode(C.ROVER_MODE_GUIDED) == C.MAV_RESULT_ACCEPTED
        assert self.arm() == C.MAV_RESULT_ACCEPTED

    def target(self, frame: int, mask: int, x: float = 0.0, y: float = 0.0, vx: float = 0.0, vy: float = 0.0,
               yaw: float = 0.0, yaw_rate: float = 0.0) -> None:
        self.mav.set_position_target_local_ned_send(0, 1, 1, frame, mask, x, y, 0.0, vx, vy, 0.0, 0.0, 0.0, 0.0,
                                                    yaw, yaw_rate)

    def streams(self, hz: int = 20) -> None:
        self.mav.request_data_stream_send(1, 1, C.MAV_DATA_STREAM_ALL, hz, 1)

    def close(self) -> None:
        self.conn.close()


def _station(origin: tuple[float, float, float] | None) -> Iterator[Station]:
    with MavlinkEmulator(HALL, pose=Pose(0.0, 0.0, 0.0), speedup=20.0, origin=origin) as emu:
        gcs = Station(emu)
        try:
            gcs.recv("HEARTBEAT")
            yield gcs
        finally:
            gcs.close()


@pytest.fixture
def indoor() -> Iterator[Station]:
    """The rover without an EKF origin (indoors, no GPS)."""
    yield from _station(None)


@pytest.fixture
def outdoor() -> Iterator[Station]:
    """The rover with an EKF origin (GPS)."""
    yield from _station(ORIGIN)


def until(cond: Callable[[], bool], timeout: float = 5.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.005)
    return cond()


def pose(gcs: Station) -> Pose:
    return gcs.emu.sim.read().pose


def stopped(gcs: Station) -> bool:
    v = gcs.emu.sim.read().velocity
    return v.v == 0.0 and v.w == 0.0


def yaw_ned_deg(gcs: Station) -> float:
    return math.degrees(math.remainder(math.pi / 2 - pose(gcs).theta, 2 * math.pi))


# -- HEARTBEAT ------------------------------------------------------------------------------------
def test_01_heartbeat_type_and_autopilot(indoor: Station) -> None:
    # Rover GCS_Mavlink.cpp GCS_Rover::frame_type: GROUND_ROVER (not a boat); autopilot ARDUPILOTMEGA
    hb = indoor.heartbeat()
    assert (hb.type, hb.autopilot, hb.get_srcSystem(), hb.get_srcComponent()) == (
        C.MAV_TYPE_GROUND_ROVER, C.MAV_AUTOPILOT_ARDUPILOTMEGA, 1, 1)


def test_02_boots_in_manual(indoor: Station) -> None:
    # Rover Parameters.cpp INITIAL_MODE default 0 (MANUAL); Rover system.cpp init_ardupilot sets it
    assert indoor.heartbeat().custom_mode == C.ROVER_MODE_MANUAL


def test_03_base_mode_manual_has_manual_input(indoor: Station) -> None:
    # Rover GCS_Mavlink.cpp GCS_MAVLINK_Rover::base_mode: MANUAL_INPUT_ENABLED when has_manual_input()
    # (ModeManual, mode.h); no GUIDED_ENABLED (not is_autopilot_mode); disarmed
    assert indoor.heartbeat().base_mode == C.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | C.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED


def test_04_base_mode_guided(indoor: Station) -> None:
    # Rover GCS_Mavlink.cpp base_mode: GUIDED_ENABLED for is_autopilot_mode() (ModeGuided), no manual input
    assert indoor.mode(C.ROVER_MODE_GUIDED) == C.MAV_RESULT_ACCEPTED
    hb = indoor.heartbeat()
    assert (hb.custom_mode, hb.base_mode) == (C.ROVER_MODE_GUIDED, C.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
                                              | C.MAV_MODE_FLAG_GUIDED_ENABLED)


def test_05_base_mode_hold_and_acro(indoor: Station) -> None:
    # Rover mode.h: ModeHold has no manual input and is no autopilot mode; ModeAcro has manual input
    assert indoor.mode(C.ROVER_MODE_HOLD) == C.MAV_RESULT_ACCEPTED
    assert indoor.heartbeat().base_mode == C.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert indoor.mode(C.ROVER_MODE_ACRO) == C.MAV_RESULT_ACCEPTED
    assert indoor.heartbeat().base_mode & C.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED


def test_06_system_status_standby_in_hold(indoor: Station) -> None:
    # Rover GCS_Mavlink.cpp vehicle_system_status: STANDBY in HOLD, ACTIVE otherwise
    assert indoor.heartbeat().system_status == C.MAV_STATE_ACTIVE
    indoor.mode(C.ROVER_MODE_HOLD)
    assert indoor.heartbeat().system_status == C.MAV_STATE_STANDBY


def test_07_armed_flag(indoor: Station) -> None:
    # Rover GCS_Mavlink.cpp base_mode: SAFETY_ARMED when armed (and not initialising)
    assert indoor.arm() == C.MAV_RESULT_ACCEPTED
    assert indoor.heartbeat().base_mode & C.MAV_MODE_FLAG_SAFETY_ARMED


# -- modes ------------------------------------------------------------------------------------------
def test_08_set_mode_needs_custom_mode_flag(indoor: Station) -> None:
    # GCS_Common.cpp GCS_MAVLINK::_set_mode_common: base mode without CUSTOM_MODE_ENABLED is DENIED
    assert indoor.command(C.MAV_CMD_DO_SET_MODE, 0, C.ROVER_MODE_HOLD).result == C.MAV_RESULT_DENIED
    assert indoor.emu.mode == C.ROVER_MODE_MANUAL


def test_09_unknown_mode_fails(indoor: Station) -> None:
    # Rover mode.cpp Rover::mode_from_mode_num: no mode 2 -> set_mode fails -> FAILED
    assert indoor.mode(2) == C.MAV_RESULT_FAILED


def test_10_set_mode_message_acked_with_its_id(indoor: Station) -> None:
    # GCS_Common.cpp handle_set_mode: COMMAND_ACK with command = MAVLINK_MSG_ID_SET_MODE (11)
    indoor.mav.set_mode_send(1, C.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, C.ROVER_MODE_HOLD)
    ack = indoor.recv("COMMAND_ACK", lambda m: m.command == C.MAVLINK_MSG_ID_SET_MODE)
    assert ack.result == C.MAV_RESULT_ACCEPTED and indoor.emu.mode == C.ROVER_MODE_HOLD


def test_11_armed_without_position_guided_refused(indoor: Station) -> None:
    # Rover mode.cpp Mode::enter: armed, a mode that requires_position() without a position estimate fails;
    # HOLD needs none (ModeHold::requires_position false)
    assert indoor.arm() == C.MAV_RESULT_ACCEPTED
    assert indoor.mode(C.ROVER_MODE_GUIDED) == C.MAV_RESULT_FAILED
    assert indoor.mode(C.ROVER_MODE_HOLD) == C.MAV_RESULT_ACCEPTED


def test_12_disarmed_any_mode(indoor: Station) -> None:
    # Rover mode.cpp Mode::enter: checks are skipped while disarmed (the arming checks do them)
    assert indoor.mode(C.ROVER_MODE_GUIDED) == C.MAV_RESULT_ACCEPTED


# -- arming -----------------------------------------------------------------------------------------
def test_13_arm_in_manual_without_position(indoor: Station) -> None:
    # Rover AP_Arming.cpp AP_Arming_Rover::gps_checks: MANUAL requires neither position nor velocity
    assert indoor.arm() == C.MAV_RESULT_ACCEPTED and indoor.emu.armed


def test_14_arm_in_guided_needs_position(indoor: Station) -> None:
    # Rover AP_Arming.cpp gps_checks: "Need Position Estimate" -> arming fails (COMMAND_ACK FAILED)
    indoor.mode(C.ROVER_MODE_GUIDED)
    assert indoor.arm() == C.MAV_RESULT_FAILED and not indoor.emu.armed


def test_15_arm_in_guided_with_position(outdoor: Station) -> None:
    # Rover AP_Arming.cpp gps_checks: passes with an EKF position estimate
    outdoor.mode(C.ROVER_MODE_GUIDED)
    assert outdoor.arm() == C.MAV_RESULT_ACCEPTED and outdoor.emu.armed


def test_16_arm_in_rtl_refused(outdoor: Station) -> None:
    # Rover AP_Arming.cpp mode_checks: ModeRTL::allows_arming() is false ("Mode not armable")
    assert outdoor.mode(C.ROVER_MODE_RTL) == C.MAV_RESULT_ACCEPTED
    assert outdoor.arm() == C.MAV_RESULT_FAILED


def test_17_disarm(outdoor: Station) -> None:
    # GCS_Common.cpp handle_command_component_arm_disarm: param1 0 disarms (ACCEPTED)
    outdoor.arm()
    assert outdoor.arm(False) == C.MAV_RESULT_ACCEPTED
    assert not outdoor.heartbeat().base_mode & C.MAV_MODE_FLAG_SAFETY_ARMED


# -- SET_POSITION_TARGET_LOCAL_NED (Rover GCS_Mavlink.cpp handle_set_position_target_local_ned) -------
def test_18_position_local_ned(outdoor: Station) -> None:
    # LOCAL_NED position (mask 3576: x, y, z): an offset from the EKF origin -> ModeGuided set_desired_location
    outdoor.guided_armed()
    outdoor.target(C.MAV_FRAME_LOCAL_NED, C.MASK_POSITION, x=1.0, y=1.5)      # 1 m north, 1.5 m east
    assert until(lambda: pose(outdoor).distance_to(Pose(1.5, 1.0, 0.0)) < 0.06 and stopped(outdoor))


def test_19_position_body_ned(outdoor: Station) -> None:
    # BODY_NED position (MAVProxy `position`): rotated by the heading and added to the current location
    outdoor.guided_armed()
    outdoor.target(C.MAV_FRAME_BODY_NED, C.MASK_POSITION, x=1.5)              # 1.5 m ahead = east
    assert until(lambda: pose(outdoor).x > 1.4 and stopped(outdoor))
    assert (pose(outdoor).x, pose(outdoor).y) == pytest.approx((1.5, 0.0), abs=0.06)


def test_20_position_local_offset_ned(outdoor: Station) -> None:
    # LOCAL_OFFSET_NED position: added to the current location without rotation
    outdoor.guided_armed()
    outdoor.target(C.MAV_FRAME_LOCAL_OFFSET_NED, C.MASK_POSITION, x=-1.0)     # 1 m south
    assert until(lambda: pose(outdoor).y < -0.9 and stopped(outdoor))
    assert (pose(outdoor).x, pose(outdoor).y) == pytest.approx((0.0, -1.0), abs=0.06)


def test_21_position_target_does_not_time_out(outdoor: Station) -> None:
    # Rover mode_guided.cpp ModeGuided::update: the WP submode has no GUID_TIMEOUT (only heading / turn rate)
    outdoor.guided_armed()
    outdoor.target(C.MAV_FRAME_LOCAL_NED, C.MASK_POSITION, x=0.0, y=5.0)      # 5 m east: > 5 s at 1 m/s
    assert until(lambda: pose(outdoor).x > 4.9 and stopped(outdoor), 8.0)
    assert outdoor.emu.sim.time > C.GUID_TIMEOUT


def test_22_mission_item_reached(outdoor: Station) -> None:
    # Rover mode_guided.cpp ModeGuided::update: send_mission_item_reached_message(0) on arrival
    outdoor.guided_armed()
    outdoor.target(C.MAV_FRAME_BODY_NED, C.MASK_POSITION, x=0.5)
    assert outdoor.recv("MISSION_ITEM_REACHED", timeout=5.0).seq == 0


def test_23_yaw_only(outdoor: Station) -> None:
    # mask 2559 (yaw only): set_desired_heading_and_speed(yaw, 0): turns in place to the heading
    outdoor.guided_armed()
    outdoor.target(C.MAV_FRAME_LOCAL_NED, C.MASK_YAW, yaw=0.0)                # north
    assert until(lambda: abs(yaw_ned_deg(outdoor)) < 2.0)
    assert pose(outdoor).distance_to(Pose(0.0, 0.0, 0.0)) < 0.01


def test_24_velocity_and_yaw(outdoor: Station) -> None:
    # mask 2503 (velocity + yaw): heading from yaw, speed |vx, vy| (set_desired_heading_and_speed)
    outdoor.guided_armed()
    for _ in range(20):
        outdoor.target(C.MAV_FRAME_LOCAL_NED, C.MASK_VELOCITY_YAW, vx=0.5, yaw=0.0)   # north at 0.5 m/s
        time.sleep(0.01)
    assert until(lambda: pose(outdoor).y > 0.3)
    assert abs(yaw_ned_deg(outdoor)) < 10.0 and outdoor.emu.sim.read().velocity.v <= 0.5 + 1e-6


def test_25_velocity_only_faces_the_vector(outdoor: Station) -> None:
    # mask 4039 (MAVProxy `velocity`): heading atan2(vy, vx), speed |vx, vy|
    outdoor.guided_armed()
    outdoor.target(C.MAV_FRAME_LOCAL_NED, C.MASK_VELOCITY_MAVPROXY, vx=-0.4)   # south
    assert until(lambda: abs(abs(yaw_ned_deg(outdoor)) - 180.0) < 5.0 and pose(outdoor).y < -0.05)


def test_26_velocity_and_turn_rate(outdoor: Station) -> None:
    # mask 1511: set_desired_turn_rate_and_speed(yaw_rate, speed signed by vx)
    outdoor.guided_armed()
    outdoor.target(C.MAV_FRAME_BODY_NED, C.MASK_VELOCITY_YAW_RATE, vx=0.3, yaw_rate=0.5)
    assert until(lambda: outdoor.emu.sim.read().velocity.v == pytest.approx(0.3, abs=1e-6)
                 and outdoor.emu.sim.read().velocity.w == pytest.approx(-0.5, abs=1e-6))


def test_27_turn_rate_only(outdoor: Station) -> None:
    # mask 1535: set_desired_turn_rate_and_speed(yaw_rate, 0): turns in place
    outdoor.guided_armed()
    outdoor.target(C.MAV_FRAME_BODY_NED, C.MASK_YAW_RATE, yaw_rate=-0.6)
    assert until(lambda: outdoor.emu.sim.read().velocity.w == pytest.approx(0.6, abs=1e-6))
    assert outdoor.emu.sim.read().velocity.v == 0.0


def test_28_global_frame_ignored(outdoor: Station) -> None:
    # only LOCAL_NED, LOCAL_OFFSET_NED, BODY_NED, BODY_OFFSET_NED are accepted: MAV_FRAME_GLOBAL is ignored
    outdoor.guided_armed()
    outdoor.target(C.MAV_FRAME_GLOBAL, C.MASK_VELOCITY_MAVPROXY, vx=0.5)
    assert until(lambda: outdoor.emu.ignored_targets == 1)
    time.sleep(0.05)
    assert stopped(outdoor) and outdoor.emu.sim.read().pose.distance_to(Pose(0.0, 0.0, 0.0)) < 1e-6


def test_29_targets_need_guided(outdoor: Station) -> None:
    # "exit if vehicle is not in Guided mode": in MANUAL a target does nothing
    outdoor.arm()
    outdoor.target(C.MAV_FRAME_BODY_NED, C.MASK_VELOCITY_YAW_RATE, vx=0.5)
    assert until(lambda: outdoor.emu.ignored_targets == 1) and stopped(outdoor)


def test_30_targets_need_an_origin(indoor: Station) -> None:
    # "need ekf origin": without one the target is dropped
    indoor.mode(C.ROVER_MODE_GUIDED)
    indoor.target(C.MAV_FRAME_BODY_NED, C.MASK_VELOCITY_YAW_RATE, vx=0.5)
    assert until(lambda: indoor.emu.ignored_targets == 1) and stopped(indoor)


def test_31_velocity_capped_at_the_default_speed(outdoor: Station) -> None:
    # velocity targets: constrain_float(|v|, -speed_max, speed_max), speed_max = get_speed_default()
    # (Rover mode.cpp: WP_SPEED, or CRUISE_SPEED when WP_SPEED is 0)
    outdoor.mav.param_set_send(1, 1, b"CRUISE_SPEED", 0.3, C.MAV_PARAM_TYPE_REAL32)
    outdoor.recv("PARAM_VALUE", lambda m: m.param_id == "CRUISE_SPEED")
    outdoor.guided_armed()
    outdoor.target(C.MAV_FRAME_LOCAL_NED, C.MASK_VELOCITY_YAW, vx=0.9, yaw=math.pi / 2)   # east, 0.9 m/s asked
    assert until(lambda: outdoor.emu.sim.read().velocity.v > 0.29)
    assert outdoor.emu.sim.read().velocity.v == pytest.approx(0.3, abs=1e-6)


def test_32_heading_target_times_out(outdoor: Station) -> None:
    # Rover mode_guided.cpp ModeGuided::update HeadingAndSpeed: stop after GUID_TIMEOUT without a target
    outdoor.guided_armed()
    outdoor.target(C.MAV_FRAME_LOCAL_NED, C.MASK_VELOCITY_YAW, vx=0.4, yaw=math.pi / 2)
    assert until(lambda: outdoor.emu.sim.read().velocity.v > 0.3)
    t0 = outdoor.emu.sim.time
    assert until(lambda: stopped(outdoor))
    assert outdoor.emu.sim.time - t0 == pytest.approx(C.GUID_TIMEOUT, abs=0.6)


# -- COMMAND_INT DO_REPOSITION (Rover GCS_Mavlink.cpp handle_command_int_do_reposition) ----------------
def _latlon_e7(north: float, east: float) -> tuple[int, int]:
    lat0, lon0, _ = ORIGIN
    return (round((lat0 + math.degrees(north / R_EARTH)) * 1e7),
            round((lon0 + math.degrees(east / (R_EARTH * math.cos(math.radians(lat0))))) * 1e7))


def test_33_reposition_changes_mode_and_drives(outdoor: Station) -> None:
    # CHANGE_MODE flag: switches to GUIDED, then set_desired_location (MAVProxy `guided LAT LON ALT`)
    assert outdoor.arm() == C.MAV_RESULT_ACCEPTED                      # in MANUAL
    lat, lon = _latlon_e7(2.0, 0.0)
    ack = outdoor.command_int(C.MAV_CMD_DO_REPOSITION, C.MAV_FRAME_GLOBAL_RELATIVE_ALT, -1,
                              C.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE, lat, lon)
    assert ack.result == C.MAV_RESULT_ACCEPTED and outdoor.emu.mode == C.ROVER_MODE_GUIDED
    assert until(lambda: pose(outdoor).y > 1.9 and stopped(outdoor))
    assert pose(outdoor).distance_to(Pose(0.0, 2.0, 0.0)) < 0.06


def test_34_reposition_outside_guided_without_flag_denied(outdoor: Station) -> None:
    # not in guided mode and no CHANGE_MODE flag -> DENIED
    lat, lon = _latlon_e7(2.0, 0.0)
    ack = outdoor.command_int(C.MAV_CMD_DO_REPOSITION, C.MAV_FRAME_GLOBAL_RELATIVE_ALT, -1, 0, lat, lon)
    assert ack.result == C.MAV_RESULT_DENIED and outdoor.emu.mode == C.ROVER_MODE_MANUAL


def test_35_reposition_to_zero_zero_denied(outdoor: Station) -> None:
    # "packet.x == 0 && packet.y == 0" -> DENIED
    outdoor.guided_armed()
    ack = outdoor.command_int(C.MAV_CMD_DO_REPOSITION, C.MAV_FRAME_GLOBAL_RELATIVE_ALT, -1, 0, 0, 0)
    assert ack.result == C.MAV_RESULT_DENIED


def test_36_reposition_speed(outdoor: Station) -> None:
    # param1 > 0: set_desired_speed (ModeGuided::set_desired_speed -> the WP speed)
    outdoor.guided_armed()
    lat, lon = _latlon_e7(0.0, 3.0)                                       # 3 m east
    assert outdoor.command_int(C.MAV_CMD_DO_REPOSITION, C.MAV_FRAME_GLOBAL_RELATIVE_ALT, 0.4, 0, lat, lon
                               ).result == C.MAV_RESULT_ACCEPTED
    assert until(lambda: pose(outdoor).x > 1.0)
    assert outdoor.emu.sim.read().velocity.v == pytest.approx(0.4, abs=1e-6)


# -- telemetry (GCS_Common.cpp) ----------------------------------------------------------------------
def test_37_global_position_int(outdoor: Station) -> None:
    # GCS_Common.cpp send_global_position_int (POSITION stream, with LOCAL_POSITION_NED): lat/lon degE7,
    # alt mm, velocity cm/s, hdg cdeg
    outdoor.streams()
    m = outdoor.recv("GLOBAL_POSITION_INT")
    lat0, lon0, alt0 = ORIGIN
    assert (m.lat, m.lon, m.alt) == (round(lat0 * 1e7), round(lon0 * 1e7), round(alt0 * 1000))
    assert m.hdg == 9000                                                 # facing east
    assert outdoor.recv("LOCAL_POSITION_NED")


def test_38_no_local_position_without_origin(indoor: Station) -> None:
    # GCS_Common.cpp send_local_position returns without a relative position (no origin);
    # send_global_position_int sends anyway (with the last known, here no, location)
    indoor.streams()
    m = indoor.recv("GLOBAL_POSITION_INT")
    assert (m.lat, m.lon) == (0, 0)
    assert indoor.none_of("LOCAL_POSITION_NED", 0.3)


def test_39_sys_status_geofence_healthy(indoor: Station) -> None:
    # GCS_Common.cpp update_sensor_status_flags: no fence -> GEOFENCE not present, not enabled, but healthy
    # (sys_status_failed() false), so a ground station sees no breach
    indoor.streams()
    s = indoor.recv("SYS_STATUS")
    assert not s.onboard_control_sensors_present & C.MAV_SYS_STATUS_GEOFENCE
    assert not s.onboard_control_sensors_enabled & C.MAV_SYS_STATUS_GEOFENCE
    assert s.onboard_control_sensors_health & C.MAV_SYS_STATUS_GEOFENCE


def test_40_guided_mission_item(outdoor: Station) -> None:
    # GCS_Common.cpp handle_mission_item: current == 2 is a guided request (Rover handle_guided_request),
    # answered with MISSION_ACK (ACCEPTED in GUIDED; MAVProxy `guided` without DO_REPOSITION)
    outdoor.guided_armed()
    lat, lon = _latlon_e7(-1.0, 0.0)
    outdoor.mav.mission_item_int_send(1, 1, 0, C.MAV_FRAME_GLOBAL_RELATIVE_ALT, C.MAV_CMD_NAV_WAYPOINT, 2, 0,
                                      0, 0, 0, 0, lat, lon, 0)
    assert outdoor.recv("MISSION_ACK").type == C.MAV_MISSION_ACCEPTED
    assert until(lambda: pose(outdoor).y < -0.9 and stopped(outdoor))
