"""Tests of the ARIA / Pioneer codec against shared/protocols/aria-sip.md.

Byte vectors are copied from the document's worked examples (§2.1) or written by hand from its
field tables; checksums of hand-built packets come from `ref_checksum`, a literal transcription of
§2.1 independent of the codec.
"""

from __future__ import annotations

import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from robotexp_drivers.p3dx import codec as k
from robotexp_drivers.p3dx import constants as c

from robotexp.errors import ConfigError, ProtocolError


def ref_checksum(body: bytes) -> int:
    """§2.1 step by step."""
    chk = 0
    i = 0
    while len(body) - i > 1:
        chk += (body[i] << 8) | body[i + 1]
        chk &= 0xFFFF
        i += 2
    if len(body) - i > 0:
        chk ^= body[i]
    return chk


def hand_frame(body: bytes) -> bytes:
    """Header, COUNT, body and the §2.1 checksum (high byte first)."""
    chk = ref_checksum(body)
    return bytes([0xFA, 0xFB, len(body) + 2]) + body + bytes([chk >> 8, chk & 0xFF])


def h(text: str) -> bytes:
    return bytes.fromhex(text)


# --- worked examples of §2.1, both ways -----
DOC_COMMANDS = [
    # (bytes from the document, command, decoded argument, encoder call)
    ("FA FB 03 00 00 00", 0, None, k.cmd_sync0),
    ("FA FB 03 00 00 00", 0, None, k.cmd_pulse),
    ("FA FB 03 01 00 01", 1, None, k.cmd_sync1),
    ("FA FB 03 02 00 02", 2, None, k.cmd_sync2),
    ("FA FB 06 01 3B 01 00 02 3B", 1, 1, k.cmd_open),
    ("FA FB 06 04 3B 01 00 05 3B", 4, 1, lambda: k.cmd_enable(True)),
    ("FA FB 06 0B 3B 2C 01 37 3C", 11, 300, lambda: k.cmd_vel(300)),
    ("FA FB 06 0B 1B 2C 01 37 1C", 11, -300, lambda: k.cmd_vel(-300)),
    ("FA FB 06 15 3B 14 00 29 3B", 21, 20, lambda: k.cmd_rvel(20)),
    ("FA FB 06 0C 1B 2D 00 39 1B", 12, -45, lambda: k.cmd_head(-45)),
    ("FA FB 06 12 3B 01 00 13 3B", 18, 1, k.cmd_config),
    ("FA FB 10 E0 00 E8 03 00 00 30 F8 FF FF 5A 00 00 00 52 FA", 224, (1000, -2000, 90),
     lambda: k.cmd_sim_set_pose(1000, -2000, 90)),
]


@pytest.mark.parametrize(("vector", "cmd", "arg", "helper"), DOC_COMMANDS)
def test_doc_command_vectors_both_ways(vector, cmd, arg, helper):
    raw = h(vector)
    assert helper() == raw
    assert k.encode_command(cmd, arg) == raw
    dec = k.CommandDecoder()
    assert dec.feed(raw) == [k.Command(cmd, arg)]
    assert (dec.packets, dec.dropped_bytes, dec.bad_checksums, dec.bad_lengths) == (1, 0, 0, 0)
    assert k.checksum(raw[3:-2]) == int.from_bytes(raw[-2:], "big")
    assert ref_checksum(raw[3:-2]) == int.from_bytes(raw[-2:], "big")


SYNC2_DOC = "FA FB 1A 02 4D 6F 62 69 6C 65 53 69 6D 00 50 69 6F 6E 65 65 72 00 70 33 64 78 00 93 45"


def test_doc_sync2_reply_both_ways():
    raw = h(SYNC2_DOC)
    reply = k.SyncReply(2, "MobileSim", "Pioneer", "p3dx")
    assert k.encode_packet(reply) == raw
    assert k.PacketDecoder().feed(raw) == [reply]


def test_sync0_sync1_replies():
    dec = k.PacketDecoder()
    assert dec.feed(h("FA FB 03 00 00 00 FA FB 03 01 00 01")) == [k.SyncReply(0), k.SyncReply(1)]
    assert k.encode_packet(k.SyncReply(1)) == h("FA FB 03 01 00 01")


# --- checksum -----
def test_checksum_hand_values():
    assert k.checksum(b"") == 0
    assert k.checksum(h("01 02 03")) == 0x0102 ^ 0x03                 # odd byte XORed into the low byte
    assert k.checksum(h("FF FF 00 02")) == 0x0001                     # 0xFFFF + 0x0002 wraps
    assert k.checksum(h("12 34 AB")) == 0x1234 ^ 0xAB


@given(st.binary(max_size=300))
def test_checksum_matches_reference(body):
    assert k.checksum(body) == ref_checksum(body)


# --- commands -----
def test_vel2_hand_vector_and_clamp():
    # left 300/20 = 15 -> high byte 0x0F, right -15 -> low byte 0xF1: int 0x0FF1 = 4081 as INTARG.
    # checksum: 0x203B + 0xF10F = 0x1114A -> 0x114A.
    assert k.cmd_vel2(300, -300) == h("FA FB 06 20 3B F1 0F 11 4A")
    assert k.cmd_vel2(3000, 0) == k.encode_command(32, 0x7F00)        # clamped to +127, never 128
    assert k.cmd_vel2(-3000, -10) == k.encode_command(32, -0x8000)    # -128 and round(-0.5) = 0
    (cmd,) = k.CommandDecoder().feed(k.cmd_vel2(-40, 60))
    assert cmd.cmd == c.CMD_VEL2 and k.unpack_2bytes(cmd.arg) == (-2, 3)


def test_2bytes_match_aria_formula_exhaustively():
    for high in range(-128, 128):
        for low in range(-128, 128):
            # ARIA com2Bytes: (short)((high & 0xff) << 8) + (low & 0xff)
            shifted = (high & 0xFF) << 8
            aria = (shifted - 0x10000 if shifted >= 0x8000 else shifted) + (low & 0xFF)
            value = k.pack_2bytes(high, low)
            assert value == aria
            assert k.unpack_2bytes(value) == (high, low)


def test_string_and_special_arguments():
    # SIM_MESSAGE "hi": 2B, length 2, 'h' 'i', NUL (comStr).
    raw = k.encode_command(c.CMD_SIM_MESSAGE, "hi")
    assert raw == hand_frame(h("EE 2B 02 68 69 00"))
    assert k.CommandDecoder().feed(raw) == [k.Command(238, "hi")]
    # comStrN: no NUL; same decoded string.
    assert k.decode_command(238, h("2B 02 68 69")) == k.Command(238, "hi")
    # new laser commands carry an index byte after the int: SIM_LRF_ENABLE 2 for laser 1.
    raw = k.cmd_sim_lrf(c.CMD_SIM_LRF_ENABLE, 2, 1)
    assert raw == hand_frame(h("E6 3B 02 00 01"))
    assert k.CommandDecoder().feed(raw) == [k.Command(230, 2, b"\x01")]
    # extended SETO: INTARG type byte, then int16 x, y, th.
    raw = k.encode_command(c.CMD_SETO, (-1, 2, -3))
    assert raw == hand_frame(h("07 3B FF FF 02 00 FD FF"))
    assert k.decode_command(7, raw[4:-2]) == k.Command(7, (-1, 2, -3))
    # command 31 with bytes 11 and 1 (ARIA's laser power-on) is the int 0x0B01
    assert k.decode_command(31, h("3B 01 0B")) == k.Command(31, 0x0B01)
    # -32768 is sent as NINTARG 0x8000 (ARIA comInt on a short)
    assert k.encode_command(11, -32768) == hand_frame(h("0B 1B 00 80"))
    # DATA that is no argument stays raw
    assert k.decode_command(236, h("3B")) == k.Command(236, h("3B"))
    assert k.decode_command(236, h("2B 05 41")) == k.Command(236, h("2B 05 41"))


def test_sim_laser_setup_sequence():
    raw = k.cmd_sim_laser()
    cmds = k.CommandDecoder().feed(raw)
    assert cmds == [k.Command(36, -90), k.Command(37, 90), k.Command(38, 100), k.Command(35, 2)]


@pytest.mark.parametrize("bad", [32768, -32769, 10**6])
def test_int_argument_out_of_range(bad):
    with pytest.raises(ConfigError, match="-32768..32767"):
        k.cmd_vel(bad)


def test_encoder_limits():
    with pytest.raises(ConfigError, match="at most 199"):
        k.encode_command(c.CMD_SIM_MESSAGE, "x" * 200)
    with pytest.raises(ConfigError, match="COUNT"):
        k.frame(0x32, bytes(198))
    assert len(k.frame(0x32, bytes(197))) == 3 + 200
    with pytest.raises(ConfigError, match="NUL"):
        k.encode_command(3, "a\0b")
    with pytest.raises(ConfigError, match="2bytes"):
        k.pack_2bytes(128, 0)
    with pytest.raises(ConfigError, match="SIM_SET_POSE"):
        k.cmd_sim_set_pose(2**31, 0, 0)


@given(cmd=st.integers(0, 255).filter(lambda x: x not in (7, 224)),
       arg=st.one_of(st.none(), st.integers(-32768, 32767),
                     st.text(st.characters(min_codepoint=1, max_codepoint=255), max_size=190)),
       extra=st.binary(max_size=4))
def test_command_round_trip(cmd, arg, extra):
    if arg is None:
        extra = b""
    raw = k.encode_command(cmd, arg, extra)
    assert k.CommandDecoder().feed(raw) == [k.Command(cmd, arg, extra)]


# --- standard SIP, built by hand from the §5 table -----
SIP_BODY = h(
    "33"           # type 0x33: moving
    "23 81"        # XPOS 0x8123 -> low 15 bits 0x0123 = 291
    "10 00"        # YPOS 16
    "00 FC"        # THPOS 0xFC00 = -1024
    "FA 00"        # L VEL 250
    "FA FB"        # R VEL 0xFBFA = -1030 (a header pattern inside the body)
    "82"           # BATTERY 130 -> 13.0 V
    "05 83"        # STALL/BUMPERS 0x8305: left stall, rear seg 1, right stall, front segs 0 and 6
    "00 02"        # CONTROL 512
    "23 00"        # FLAGS 0x0023: motors, sonar array 1, E-stop
    "2D"           # COMPASS 45 -> 90 deg
    "02"           # SONAR COUNT 2
    "03 F4 01"     # sonar 3: 500
    "0C 88 13"     # sonar 12: 5000
    "01 02 03 FF 0F"  # GRIP_STATE 1, ANPORT 2, ANALOG 3, DIGIN 0xFF, DIGOUT 0x0F
    "83 00"        # BATTERYX10 131
    "03"           # CHARGESTATE 3 (float)
    "65 FF"        # ROTVEL 0xFF65 = -155 -> -15.5 deg/s
    "02 00"        # FAULTFLAGS 2
    "00 00"        # LATVEL 0
    "81"           # TEMPERATURE -127
    "57"           # STATE OF CHARGE 87
)
SIP_EXPECTED = k.StandardSip(
    moving=True, xpos=0x8123, ypos=16, thpos=-1024, left_vel=250, right_vel=-1030, battery_dv=130,
    stall_bumpers=0x8305, control=512, flags=0x23, compass=45, sonar=((3, 500), (12, 5000)),
    grip_state=1, analog_port=2, analog=3, digin=0xFF, digout=0x0F, battery_x10=131, charge_state=3,
    rot_vel_x10=-155, fault_flags=2, lat_vel=0, temperature=-127, state_of_charge=87)


def test_hand_built_sip_decodes():
    raw = hand_frame(SIP_BODY)
    dec = k.PacketDecoder()
    (sip,) = dec.feed(raw)
    assert sip == SIP_EXPECTED
    assert sip.xpos & c.POS_MASK == 291
    assert (sip.left_stalled, sip.right_stalled, sip.rear_bumpers, sip.front_bumpers) == (True, True, 0b10,
                                                                                          0b1000001)
    assert (sip.motors_enabled, sip.sonar_arrays, sip.estop, sip.compass_deg) == (True, 1, True, 90)
    assert sip.uc_time_us is None and sip.flags3 is None and sip.extra == b""
    assert k.encode_packet(sip) == raw
    assert dec.bad_payloads == 0


def test_sip_optional_tail_and_truncation():
    # fields 25 and 26 present: uC time 0x01020304, FLAGS3 0x80000001, then 2 unknown bytes
    body = SIP_BODY + h("04 03 02 01 01 00 00 80 AA BB")
    (sip,) = k.PacketDecoder().feed(hand_frame(body))
    assert (sip.uc_time_us, sip.flags3, sip.extra) == (0x01020304, 0x80000001, h("AA BB"))
    # only fields 1..12 (an old ARCOS SIP): all optional fields None
    short = SIP_BODY[:1 + 19 + 6]
    (sip,) = k.PacketDecoder().feed(hand_frame(short))
    assert sip.grip_state is None and sip.state_of_charge is None and sip.sonar == ((3, 500), (12, 5000))
    # a partial 13..17 group is kept as extra, not decoded
    (sip,) = k.PacketDecoder().feed(hand_frame(short + h("01 02 03")))
    assert sip.grip_state is None and sip.extra == h("01 02 03")
    assert k.encode_packet(sip) == hand_frame(short + h("01 02 03"))
    # a sonar count beyond the data is malformed: UnknownPacket, counted
    dec = k.PacketDecoder()
    bad = SIP_BODY[:1 + 18] + h("09 03 F4 01")
    assert dec.feed(hand_frame(bad)) == [k.UnknownPacket(0x33, bad[1:])]
    assert dec.bad_payloads == 1
    with pytest.raises(ProtocolError, match="sonar"):
        k.decode_packet(0x32, bad[1:])
    with pytest.raises(ProtocolError, match="19 fixed bytes"):
        k.decode_packet(0x32, b"\0" * 18)


def test_sip_encoder_rejects_gaps():
    with pytest.raises(ConfigError, match="prefix"):
        k.encode_packet(k.StandardSip(battery_x10=130))
    with pytest.raises(ConfigError, match="extra"):
        k.encode_packet(k.StandardSip(extra=b"12345"))
    with pytest.raises(ConfigError, match="fit"):
        k.encode_packet(k.StandardSip(thpos=40000))


# --- other server packets, by hand -----
def test_laser_packets_by_hand():
    # 0x60: pose (100, -1, 90), total 181, first 32, 2 readings 1000 and 32767.
    body60 = h("60 64 00 FF FF 5A 00 B5 00 20 00 02 E8 03 FF 7F")
    (p,) = k.PacketDecoder().feed(hand_frame(body60))
    assert p == k.SimLaserPacket(False, 181, 32, (1000, 32767), pose=(100, -1, 90))
    assert not p.complete and k.encode_packet(p) == hand_frame(body60)
    # 0x61: total 3, first 1, 2 readings (500 refl 7, 600 refl 0), 2 reserved each, index 0, flags 1.
    body61 = h("61 03 00 01 00 02 F4 01 07 00 00 58 02 00 00 00 00 01")
    (p,) = k.PacketDecoder().feed(hand_frame(body61))
    assert p == k.SimLaserPacket(True, 3, 1, (500, 600), (7, 0), None, 0, 1)
    assert p.complete and k.encode_packet(p) == hand_frame(body61)


def test_laser_scan_split_in_32s():
    ranges = list(range(1000, 1181))                                   # 181 readings
    packets = [p for raw in k.encode_laser_scan(ranges) for p in k.PacketDecoder().feed(raw)]
    assert [p.first for p in packets] == [0, 32, 64, 96, 128, 160]
    assert [len(p.ranges) for p in packets] == [32] * 5 + [21]
    assert [p.complete for p in packets] == [False] * 5 + [True]
    assert sum((p.ranges for p in packets), ()) == tuple(ranges)
    assert all(p.total == 181 and p.extended for p in packets)


def test_config_packet_by_hand_and_truncated():
    body = (h("20") + b"Pioneer\0p3dx\0SIM\0" + h("00") + h("0F 27") * 4 + h("90 01") + b"MobileSim\0"
            + h("64 00 00") + h("01 00"))                               # ... has gripper = 1, then cut
    (cfg,) = k.PacketDecoder().feed(hand_frame(body))
    assert (cfg.robot_type, cfg.robot_subtype, cfg.serial_number, cfg.name) == ("Pioneer", "p3dx", "SIM",
                                                                               "MobileSim")
    assert (cfg.rot_vel_top, cfg.pwm_max, cfg.sip_cycle_ms, cfg.has_gripper) == (9999, 400, 100, 1)
    assert cfg.present == 14 and cfg.watchdog_ms == 0 and cfg.firmware_version == ""
    assert k.encode_packet(cfg) == hand_frame(body)
    full = k.mobilesim_config()
    assert k.PacketDecoder().feed(k.encode_packet(full)) == [full]
    assert (full.watchdog_ms, full.autobaud, full.firmware_version) == (2000, 2, "S.0")


def test_simstat_encoder_siminfo_by_hand():
    body = (h("62 00 00") + struct.pack("<I", 5) + h("64 00 65 00 66 00")
            + struct.pack("<11i", 1000, -2000, 0, 90, 0, 0, 0, -1, 0, 0, 0))
    (s,) = k.PacketDecoder().feed(hand_frame(body))
    assert (s.flags, s.sim_interval_ms, s.real_interval_ms, s.last_interval_ms) == (5, 100, 101, 102)
    assert (s.true_x_mm, s.true_y_mm, s.true_th_deg, s.dop_x100) == (1000, -2000, 90, -1)
    assert k.encode_packet(s) == hand_frame(body)
    (e,) = k.PacketDecoder().feed(hand_frame(h("90 01 00 00 00 FE FF FF FF")))
    assert e == k.EncoderPacket(1, -2)
    body = h("63") + b"MobileSim\x000.9.8\0" + h("01 00 00 00 01 00 00 00") + b"laser\0lms2xx\0" + h(
        "00 02 00 00 00")
    (i,) = k.PacketDecoder().feed(hand_frame(body))
    assert i == k.SimInfo("MobileSim", "0.9.8", 1, (k.SimDevice("laser", "lms2xx", 0, 2),))
    (m,) = k.PacketDecoder().feed(hand_frame(h("66 01 01") + b"a.map\0"))
    assert m == k.SimMapChanged(1, 1, "a.map")
    (u,) = k.PacketDecoder().feed(hand_frame(h("F0 01 02")))
    assert u == k.UnknownPacket(0xF0, h("01 02"))


# --- §5.1 positions -----
@pytest.mark.parametrize(("prev", "new", "delta"), [
    (0x7FF0, 0x0010, 32),          # forward across the 15-bit wrap
    (0x0010, 0x7FF0, -32),         # backward across it
    (0x8005, 0x0007, 2),           # bit 15 is ignored
    (0, 0x1000, 0x1000),           # the threshold itself is a real move
    (0, 0x1001, 0x1001 - 0x8000),  # beyond it: taken as a wrap
    (0, 0xFFFE, -2),               # what position_to_raw(-1 mm) gives
])
def test_unwrap_position_delta(prev, new, delta):
    assert k.unwrap_position_delta(prev, new) == delta


def test_position_and_heading_to_raw():
    assert k.position_to_raw(-1.0) == 0xFFFE                            # int(-2.06) = -2 as uint16
    assert k.position_to_raw(97.0) == 200                               # 97 / 0.485
    assert k.position_to_raw(1000.0, 1.0) == 1000
    assert k.heading_to_raw(45.0) == 511                                # 0.785398 / 0.001534 = 511.99
    assert k.heading_to_raw(-90.0) == -1023
    assert k.heading_to_raw(270.0) == -1023


# --- round trips of server packets -----
u8, u16, i16 = st.integers(0, 255), st.integers(0, 0xFFFF), st.integers(-32768, 32767)
u32, i32 = st.integers(0, 2**32 - 1), st.integers(-(2**31), 2**31 - 1)
name = st.text(st.characters(min_codepoint=1, max_codepoint=255), max_size=12)


SIP_GROUP_SIZES = [5, 2, 1, 2, 2, 2, 1, 1, 4, 4]       # §5 fields 13..17, 18, ..., 26


@st.composite
def sips(draw):
    optional = [("grip_state", u8), ("analog_port", u8), ("analog", u8), ("digin", u8), ("digout", u8)]
    groups = [optional] + [[(n, s)] for n, s in [
        ("battery_x10", u16), ("charge_state", u8), ("rot_vel_x10", i16), ("fault_flags", u16),
        ("lat_vel", i16), ("temperature", st.integers(-128, 127)), ("state_of_charge", u8),
        ("uc_time_us", u32), ("flags3", u32)]]
    kept = draw(st.integers(0, len(groups)))
    kw = {n: draw(s) for group in groups[:kept] for n, s in group}
    return k.StandardSip(
        moving=draw(st.booleans()), xpos=draw(u16), ypos=draw(u16), thpos=draw(i16), left_vel=draw(i16),
        right_vel=draw(i16), battery_dv=draw(u8), stall_bumpers=draw(u16), control=draw(i16),
        flags=draw(u16), compass=draw(u8), sonar=tuple(draw(st.lists(st.tuples(u8, u16), max_size=32))),
        extra=draw(st.binary(max_size=SIP_GROUP_SIZES[kept] - 1 if kept < len(groups) else 6)), **kw)


@st.composite
def lasers(draw):
    n = draw(st.integers(0, 32))
    ranges = tuple(draw(st.lists(u16, min_size=n, max_size=n)))
    if draw(st.booleans()):
        return k.SimLaserPacket(True, draw(u16), draw(u16), ranges,
                                tuple(draw(st.lists(u8, min_size=n, max_size=n))), None, draw(u8), draw(u8))
    return k.SimLaserPacket(False, draw(u16), draw(u16), ranges, pose=(draw(i16), draw(i16), draw(i16)))


packets = st.one_of(
    sips(), lasers(),
    st.builds(k.SyncReply, st.just(2), name, name, name), st.builds(k.SyncReply, st.sampled_from([0, 1])),
    st.builds(k.SimStat, u32, u16, u16, u16, *[i32] * 11, extra=st.binary(max_size=4)),
    st.builds(k.EncoderPacket, i32, i32), st.builds(k.SimMapChanged, u8, u8, name),
    st.builds(k.SimInfo, name, name, u32, st.lists(st.builds(k.SimDevice, name, name, u8, u32),
                                                    max_size=3).map(tuple)),
    st.builds(k.ConfigPacket, robot_type=name, serial_number=name, watchdog_ms=u16, drift_factor=i16,
              high_temp_shutdown=st.integers(-128, 127), config_flags=u32, bootloader_version=name),
    st.builds(k.UnknownPacket, st.sampled_from([0x10, 0x90 + 1, 0xF0, 0xFF]), st.binary(max_size=40)),
)


@settings(max_examples=300)
@given(packets)
def test_packet_round_trip(packet):
    raw = k.encode_packet(packet)
    dec = k.PacketDecoder()
    assert dec.feed(raw) == [packet]
    assert dec.bad_payloads == 0 and dec.buffered == 0


@given(st.integers(0, 255), st.binary(max_size=120))
def test_any_valid_frame_decodes_without_error(ptype, data):
    # a well-framed packet of any type and payload gives exactly one packet, never an exception
    dec = k.PacketDecoder()
    (out,) = dec.feed(k.frame(ptype, data))
    if isinstance(out, k.UnknownPacket):
        assert out == k.UnknownPacket(ptype, data)


# --- stream properties -----
def feed_in_chunks(dec, stream, cuts):
    out, prev = [], 0
    for cut in sorted(cuts) + [len(stream)]:
        out += dec.feed(stream[prev:cut])
        prev = max(prev, cut)
    return out + dec.flush()


@given(st.binary(max_size=600), st.lists(st.integers(0, 600), max_size=8))
def test_random_bytes_never_raise(stream, cuts):
    for dec in (k.PacketDecoder(), k.CommandDecoder(), k.PacketDecoder(max_count=255)):
        feed_in_chunks(dec, stream, cuts)
        assert dec.buffered == 0
        assert dec.dropped_bytes <= len(stream)


def no_header(noise: bytes) -> bytes:
    out = bytearray(noise)
    for i in range(1, len(out)):
        if out[i - 1] == 0xFA and out[i] == 0xFB:
            out[i] = 0x00
    return bytes(out)


@settings(max_examples=150, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.binary(max_size=30), packets), min_size=1, max_size=6),
       st.binary(max_size=30), st.lists(st.integers(0, 2000), max_size=6))
def test_packets_in_noise_are_recovered(items, tail, cuts):
    stream, expected, noise_len = b"", [], 0
    for noise, packet in items:
        noise = no_header(noise)
        stream += noise + k.encode_packet(packet)
        expected.append(packet)
        noise_len += len(noise)
    tail = no_header(tail)
    stream += tail
    dec = k.PacketDecoder()
    assert feed_in_chunks(dec, stream, cuts) == expected
    assert dec.dropped_bytes == noise_len + len(tail)
    assert dec.packets == len(expected) and dec.buffered == 0


commands = st.tuples(st.integers(0, 255).filter(lambda x: x not in (7, 224)),
                     st.one_of(st.none(), st.integers(-32768, 32767), name))


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(commands, min_size=2, max_size=8), st.data())
def test_mutated_command_streams(cmds, data):
    frames = [k.encode_command(cmd, arg) for cmd, arg in cmds]
    victim = data.draw(st.integers(0, len(frames) - 1))
    raw = bytearray(frames[victim])
    pos = data.draw(st.integers(0, len(raw) - 1))
    kind = data.draw(st.sampled_from(["flip", "insert", "delete"]))
    if kind == "flip":
        raw[pos] ^= data.draw(st.integers(1, 255))
    elif kind == "insert":
        raw[pos:pos] = data.draw(st.binary(min_size=1, max_size=8))
    else:
        del raw[pos:pos + data.draw(st.integers(1, 4))]
    stream = b"".join(frames[:victim]) + bytes(raw) + b"".join(frames[victim + 1:])
    dec = k.CommandDecoder()
    out = feed_in_chunks(dec, stream, data.draw(st.lists(st.integers(0, len(stream)), max_size=4)))
    before = [k.Command(cmd, arg) for cmd, arg in cmds[:victim]]
    after = [k.Command(cmd, arg) for cmd, arg in cmds[victim + 1:]]
    assert out[:len(before)] == before
    if after:
        assert out[len(out) - len(after):] == after


@settings(max_examples=200, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(packets, min_size=2, max_size=5), st.data())
def test_mutated_packet_streams(pkts, data):
    frames = [k.encode_packet(p) for p in pkts]
    victim = data.draw(st.integers(0, len(frames) - 1))
    raw = bytearray(frames[victim])
    pos = data.draw(st.integers(0, len(raw) - 1))
    raw[pos] ^= data.draw(st.integers(1, 255))
    stream = b"".join(frames[:victim]) + bytes(raw) + b"".join(frames[victim + 1:])
    dec = k.PacketDecoder()
    out = dec.feed(stream) + dec.flush()
    assert out[:victim] == pkts[:victim]
    after = pkts[victim + 1:]
    if after:
        assert out[len(out) - len(after):] == after
    assert dec.dropped_bytes >= 1


# --- resynchronisation and counters by hand -----
def test_counters_by_hand():
    dec = k.PacketDecoder()
    stream = (h("00 11 FA")                                 # 3 garbage bytes
              + h("FA FB 02 00 00")                         # COUNT 2 < 3: bad length
              + h("FA FB 03 00 00 01")                      # bad checksum
              + h("FA FB 03 01 00 01"))                     # SYNC1 reply
    assert dec.feed(stream) == [k.SyncReply(1)]
    assert (dec.bad_lengths, dec.bad_checksums, dec.packets) == (1, 1, 1)
    assert dec.dropped_bytes == 3 + 5 + 6
    dec = k.PacketDecoder()
    assert dec.feed(h("FA FB C9") + bytes(200)) == []      # COUNT 201 > 200
    assert dec.bad_lengths == 1
    assert k.PacketDecoder(max_count=255).feed(hand_frame(bytes([0x10]) + bytes(198)))[0] == k.UnknownPacket(
        0x10, bytes(198))


def test_flush_releases_packet_behind_false_header():
    # a false header announcing 200 bytes swallows a real packet until the stream ends
    dec = k.PacketDecoder()
    stream = h("FA FB C8 01") + h("FA FB 03 01 00 01")
    assert dec.feed(stream) == []
    assert dec.buffered == len(stream)
    assert dec.flush() == [k.SyncReply(1)]
    assert (dec.truncated, dec.dropped_bytes, dec.buffered) == (1, 4, 0)


def test_header_split_across_feeds():
    dec = k.PacketDecoder()
    raw = h(SYNC2_DOC)
    out = []
    for i in range(len(raw)):
        out += dec.feed(raw[i:i + 1])
    assert out == [k.SyncReply(2, "MobileSim", "Pioneer", "p3dx")]
    assert dec.dropped_bytes == 0
