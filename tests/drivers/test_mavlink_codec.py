"""MAVLink codec: frames written out from the MAVLink spec (CRC computed here, independently), round
trips, and random / mutated streams."""

from __future__ import annotations

import math
import struct

import numpy as np

from hypothesis import given, settings
from hypothesis import strategies as st

from robotexp_drivers.mavlink import constants as C
from robotexp_drivers.mavlink.codec import MavlinkCodec
from robotexp_drivers.mavlink.link import parse_address
from robotexp_drivers.mavlink.robot import ned_to_enu, scan_from_obstacle_distance


def x25(data: bytes) -> int:
    """CRC-16/MCRF4XX as the MAVLink serialization spec describes it (crc_accumulate, seed 0xFFFF)."""
    crc = 0xFFFF
    for b in data:
        tmp = (b ^ (crc & 0xFF)) & 0xFF
        tmp = (tmp ^ (tmp << 4)) & 0xFF
        crc = ((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xFFFF
    return crc


# HEARTBEAT (id 0) payload in wire order (fields sorted by size): custom_mode uint32 = 15 (GUIDED),
# type = 10 (GROUND_ROVER), autopilot = 3 (ARDUPILOTMEGA), base_mode = 0x81, system_status = 4, version = 3
HB_PAYLOAD = bytes([0x0F, 0x00, 0x00, 0x00, 0x0A, 0x03, 0x81, 0x04, 0x03])
# MAVLink 2 header: STX 0xFD, len 9, incompat 0, compat 0, seq 7, sys 1, comp 1, msgid 0 (3 bytes LE)
HB_V2_HEADER = bytes([0xFD, 0x09, 0x00, 0x00, 0x07, 0x01, 0x01, 0x00, 0x00, 0x00])
# MAVLink 1 header: STX 0xFE, len 9, seq 7, sys 1, comp 1, msgid 0
HB_V1_HEADER = bytes([0xFE, 0x09, 0x07, 0x01, 0x01, 0x00])


def frame(header: bytes, payload: bytes, crc_extra: int) -> bytes:
    crc = x25(header[1:] + payload + bytes([crc_extra]))
    return header + payload + struct.pack("<H", crc)


def test_spec_heartbeat_v2_and_v1_decode() -> None:
    for header in (HB_V2_HEADER, HB_V1_HEADER):
        codec = MavlinkCodec(255, 190)
        (m,) = codec.feed(frame(header, HB_PAYLOAD, C.MAVLINK_MSG_ID_HEARTBEAT_CRC))
        assert m.get_type() == "HEARTBEAT" and m.get_msgId() == C.MAVLINK_MSG_ID_HEARTBEAT
        assert (m.type, m.autopilot, m.base_mode, m.custom_mode, m.system_status, m.mavlink_version) == (
            10, 3, 0x81, 15, 4, 3)
        assert (m.get_srcSystem(), m.get_srcComponent(), m.get_seq()) == (1, 1, 7)


def test_our_encoder_writes_the_spec_bytes() -> None:
    codec = MavlinkCodec(1, 1)
    codec.mav.seq = 7
    out = codec.encode(codec.mav.heartbeat_encode(10, 3, 0x81, 15, 4, 3))
    assert out == frame(HB_V2_HEADER, HB_PAYLOAD, C.MAVLINK_MSG_ID_HEARTBEAT_CRC)
    assert codec.mav.seq == 8


def test_wrong_checksum_and_wrong_crc_extra_are_counted_not_raised() -> None:
    codec = MavlinkCodec(255, 190)
    good = frame(HB_V2_HEADER, HB_PAYLOAD, C.MAVLINK_MSG_ID_HEARTBEAT_CRC)
    bad = good[:-1] + bytes([good[-1] ^ 0xFF])
    assert codec.feed(bad) == []
    assert codec.feed(frame(HB_V2_HEADER, HB_PAYLOAD, 0)) == []     # CRC without the CRC_EXTRA byte
    assert codec.bad_frames == 2
    assert len(codec.feed(good)) == 1


def test_round_trip_of_every_message_the_driver_uses() -> None:
    a, b = MavlinkCodec(1, 1), MavlinkCodec(255, 190)
    mav = a.mav
    msgs = [mav.heartbeat_encode(10, 3, 0x81, 15, 4, 3), mav.local_position_ned_encode(1234, 1.5, -2.25, 0, 0.5, 0, 0),
            mav.attitude_encode(1234, 0, 0, -1.0, 0, 0, 0.25),
            mav.set_position_target_local_ned_encode(5, 1, 1, 8, 1511, 0, 0, 0, 0.3, 0, 0, 0, 0, 0, 0, -0.5),
            mav.obstacle_distance_encode(7, 0, list(range(100, 172)), 5, 10, 300, 5.0, 0.0, 12),
            mav.command_long_encode(1, 1, 176, 0, 1, 15, 0, 0, 0, 0, 0), mav.command_ack_encode(400, 0),
            mav.request_data_stream_encode(1, 1, 6, 20, 1),
            mav.sys_status_encode(0, 0, 0, 0, 12600, -1, -1, 0, 0, 0, 0, 0, 0)]
    out = b.feed(b"".join(a.encode(m) for m in msgs))
    assert [m.get_type() for m in out] == [m.get_type() for m in msgs]
    assert out[1].y == -2.25 and out[3].type_mask == 1511 and out[3].coordinate_frame == 8
    assert out[4].distances == list(range(100, 172)) and out[4].increment_f == 5.0 and out[4].frame == 12
    assert [m.get_seq() for m in out] == list(range(len(msgs)))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.binary(max_size=300), min_size=1, max_size=6), st.data())
def test_valid_frames_in_noise_are_recovered(noise: list[bytes], data: st.DataObject) -> None:
    a, b = MavlinkCodec(1, 1), MavlinkCodec(255, 190)
    frames = [a.encode(a.mav.attitude_encode(i, 0, 0, 0.1 * i, 0, 0, 0)) for i in range(len(noise))]
    stream = b"".join(n + f for n, f in zip(noise, frames, strict=True)) + bytes(300)  # zeros flush a pending partial
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=5)))
    got = []
    for lo, hi in zip([0, *cuts], [*cuts, len(stream)], strict=True):
        got += b.feed(stream[lo:hi])
    times = [m.time_boot_ms for m in got if m.get_type() == "ATTITUDE"]
    assert set(range(len(noise))) <= set(times)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=600), st.integers(0, 10 ** 6))
def test_mutated_streams_never_raise(noise: bytes, seed: int) -> None:
    a, b = MavlinkCodec(1, 1), MavlinkCodec(255, 190)
    good = a.encode(a.mav.obstacle_distance_encode(7, 0, [300] * 72, 5, 10, 300, 5.0, 0.0, 12)) * 3
    raw = bytearray(good + noise)
    for k in range(seed % 7):
        raw[(seed * (k + 13)) % len(raw)] ^= 1 << (k % 8)
    b.feed(bytes(raw))          # no exception; counters only
    b.feed(bytes(600))          # zeros complete any frame a mutated length left pending
    assert b.frames >= 3 - seed % 7     # each flip spoils at most one frame; resync recovers the rest


def test_frames_and_units() -> None:
    p = ned_to_enu(2.0, 1.0, math.radians(30))       # 2 m north, 1 m east, heading 30 deg east of north
    assert (p.x, p.y) == (1.0, 2.0) and math.isclose(p.theta, math.radians(60))
    codec = MavlinkCodec(1, 1)
    d = [C.OBSTACLE_UNKNOWN] * 72
    d[0], d[18], d[36], d[1] = 150, 301, 5, 250      # ahead 1.5 m, right: nothing, behind: too close
    m = codec.mav.obstacle_distance_encode(0, 0, d, 5, 10, 300, 5.0, 0.0, C.MAV_FRAME_BODY_FRD)
    scan = scan_from_obstacle_distance(m, 0.0)
    assert scan.range_max == 3.0
    assert np.allclose(scan.angles, [0.0, math.radians(-5), math.radians(-90)], rtol=0, atol=1e-12)
    assert scan.ranges.tolist() == [1.5, 2.5, math.inf]
    north = codec.mav.obstacle_distance_encode(0, 0, d, 5, 10, 300, 5.0, 0.0, C.MAV_FRAME_LOCAL_NED)
    east_facing = scan_from_obstacle_distance(north, math.radians(90))  # element 0 = north = robot's left
    assert math.isclose(east_facing.angles[0], math.radians(90))


def test_address_forms() -> None:
    assert parse_address("udp:127.0.0.1:14550") == ("udpin", ("127.0.0.1", 14550), 115200)
    assert parse_address("udpout:10.0.0.5:14550")[:2] == ("udpout", ("10.0.0.5", 14550))
    assert parse_address("127.0.0.1:14550")[0] == "udpin"
    assert parse_address("tcp:127.0.0.1:5760")[:2] == ("serial", "socket://127.0.0.1:5760")
    assert parse_address("/dev/ttyUSB0,57600") == ("serial", "/dev/ttyUSB0", 57600)
    assert parse_address("/dev/ttyACM0") == ("serial", "/dev/ttyACM0", 115200)
    assert parse_address("loop://")[:2] == ("serial", "loop://")
