"""RPLidar codec: byte vectors from Slamtec's protocol document, a real A1M8's GET_INFO fields,
round trips, and property tests (the decoder never raises and finds turns again after noise)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robotexp.errors import ConfigError, ProtocolError
from robotexp_drivers.lasers.rplidar import codec as k
from robotexp_drivers.lasers.rplidar import constants as C


def test_requests_as_documented() -> None:
    assert k.request(C.CMD_STOP) == bytes.fromhex("A5 25")
    assert k.request(C.CMD_RESET) == bytes.fromhex("A5 40")
    assert k.request(C.CMD_SCAN) == bytes.fromhex("A5 20")
    assert k.request(C.CMD_GET_INFO) == bytes.fromhex("A5 50")
    assert k.request(C.CMD_GET_HEALTH) == bytes.fromhex("A5 52")
    assert k.request(C.CMD_GET_SAMPLERATE) == bytes.fromhex("A5 59")
    # a payload request: size, payload, XOR of everything before: SET_MOTOR_PWM 660
    assert k.request(C.CMD_SET_MOTOR_PWM, bytes.fromhex("94 02")) == bytes.fromhex("A5 F0 02 94 02 C1")
    # EXPRESS_SCAN with its 5 zero bytes: A5 82 05 00 00 00 00 00 22
    assert k.request(C.CMD_EXPRESS_SCAN, bytes(5)) == bytes.fromhex("A5 82 05 00 00 00 00 00 22")
    with pytest.raises(ConfigError):
        k.request(C.CMD_SCAN, b"\x00")


def test_descriptors_as_documented() -> None:
    assert k.descriptor(20, C.SEND_MODE_SINGLE, C.ANS_TYPE_DEVINFO) == bytes.fromhex("A5 5A 14 00 00 00 04")
    assert k.descriptor(3, C.SEND_MODE_SINGLE, C.ANS_TYPE_DEVHEALTH) == bytes.fromhex("A5 5A 03 00 00 00 06")
    assert k.descriptor(5, C.SEND_MODE_MULTI, C.ANS_TYPE_MEASUREMENT) == bytes.fromhex("A5 5A 05 00 00 40 81")
    assert k.descriptor(4, C.SEND_MODE_SINGLE, C.ANS_TYPE_SAMPLE_RATE) == bytes.fromhex("A5 5A 04 00 00 00 15")
    assert k.parse_descriptor(bytes.fromhex("A5 5A 05 00 00 40 81")) == (5, 1, 0x81)
    with pytest.raises(ProtocolError):
        k.parse_descriptor(bytes.fromhex("A5 5B 05 00 00 40 81"))


def test_device_info_and_health() -> None:
    # a real A1M8 reports model 24, firmware 1.29, hardware 7: minor before major on the wire
    raw = bytes((24, 29, 1, 7)) + bytes(range(16))
    info = k.DeviceInfo.decode(raw)
    assert info.model == 0x18 and info.firmware == (1, 29) and info.hardware == 7
    assert info.encode() == raw and "A1 series" in info.describe() and "firmware 1.29" in info.describe()
    assert k.Health.decode(bytes.fromhex("02 34 12")) == k.Health(2, 0x1234)     # error code little-endian
    assert k.Health(1, 5).encode() == bytes.fromhex("01 05 00")
    with pytest.raises(ProtocolError):
        k.DeviceInfo.decode(raw[:19])


def test_node_bits_as_documented() -> None:
    # start of a turn, quality 47, 90.5 deg (q6 5792), 1234.25 mm (q2 4937)
    node = k.encode_node(True, 47, 5792, 4937)
    assert node == bytes((47 << 2 | 0b01, (5792 & 0x7F) << 1 | 1, 5792 >> 7)) + (4937).to_bytes(2, "little")
    assert node.hex() == "bd412d4913"
    assert k.decode_node(node) == k.Node(True, 47, 5792, 4937)
    assert k.decode_node(k.encode_node(False, 0, 0, 0)) == k.Node(False, 0, 0, 0)
    assert k.decode_node(bytes((0b11, 1, 0, 0, 0))) is None          # S == !S
    assert k.decode_node(bytes((0b01, 0, 0, 0, 0))) is None          # check bit 0
    assert k.decode_node(k.encode_node(False, 1, 360 * 64, 4)) is None   # 360 deg


def test_clockwise_device_angles_become_counter_clockwise_beams() -> None:
    # 90 deg clockwise (the right) is -90 deg in the laser frame: beam 90 of 360 (beam 0 at -180)
    assert int(k.beam_index(90 * 64, 360)) == 90
    assert int(k.beam_index(0, 360)) == 180             # the front
    assert int(k.beam_index(270 * 64, 360)) == 270      # the left, +90 deg
    g = k.geometry(360, 0.15, 12.0, 0.18)
    assert g.angles()[90] == pytest.approx(-math.pi / 2) and g.angles()[270] == pytest.approx(math.pi / 2)


def test_round_trip_two_turns_in_chunks() -> None:
    rng = np.random.default_rng(2)
    turns = [np.round(rng.uniform(0.15, 12.0, 360) * 4000) / 4000 for _ in range(3)]
    turns[1][::9] = math.inf
    stream = b"".join(k.encode_scan(t) for t in turns)
    dec = k.ScanDecoder(360)
    out = []
    for i in range(0, len(stream), 37):
        out += dec.feed(stream[i:i + 37])
    # a turn is complete when the next begins: the last one is still open
    assert len(out) == 2 and dec.scans == 2 and dec.dropped_bytes == 0 and dec.nodes == 1080
    for got, want in zip(out, turns[:2], strict=True):
        np.testing.assert_array_equal(got, want)


def test_turn_binning_keeps_the_nearest_and_marks_unsampled_beams() -> None:
    nodes = (k.encode_node(True, 10, 0, 4000) + k.encode_node(False, 10, 16, 2000)      # both in the front beam
             + k.encode_node(False, 0, 90 * 64, 0)                                      # no echo at the right
             + k.encode_node(True, 10, 0, 4000))
    (r,) = k.ScanDecoder(360, min_nodes=1).feed(nodes)
    assert r[180] == 0.5 and r[90] == math.inf
    assert np.isnan(r[0]) and np.sum(np.isnan(r)) == 358


def test_partial_first_turn_and_short_turns_are_dropped() -> None:
    full = k.encode_scan(np.ones(360))
    dec = k.ScanDecoder(360)
    out = dec.feed(full[5 * 200:] + full + full[:5])       # starts mid-turn
    assert len(out) == 1 and dec.short_turns == 0
    dec2 = k.ScanDecoder(360)
    assert dec2.feed(full[:50] + full[:5]) == [] and dec2.short_turns == 1     # 10 nodes < 360 / 4
    assert dec2.feed(full[:5]) == [] and dec2.short_turns == 2


def test_request_decoder() -> None:
    dec = k.RequestDecoder()
    stream = (b"\x00\x13" + k.request(C.CMD_GET_INFO) + k.request(C.CMD_SET_MOTOR_PWM, b"\x94\x02")
              + bytes.fromhex("A5 F0 02 94 02 C2") + k.request(C.CMD_SCAN))
    got = dec.feed(stream[:7]) + dec.feed(stream[7:])
    assert got == [k.Request(C.CMD_GET_INFO), k.Request(C.CMD_SET_MOTOR_PWM, b"\x94\x02"), k.Request(C.CMD_SCAN)]
    assert dec.bad_checksums == 1 and dec.dropped_bytes >= 2


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=800), st.integers(1, 60))
def test_decoders_never_raise(data: bytes, step: int) -> None:
    dec, req = k.ScanDecoder(360), k.RequestDecoder()
    for i in range(0, len(data), step):
        for r in dec.feed(data[i:i + step]):
            assert r.shape == (360,)
        req.feed(data[i:i + step])


@settings(max_examples=150, deadline=None)
@given(st.binary(max_size=200), st.lists(st.integers(600, 48000), min_size=72, max_size=72))
def test_decoder_resynchronises_after_noise(noise: bytes, q2: list[int]) -> None:
    ranges = np.array(q2, np.float64) / 4000.0
    turn = k.encode_scan(ranges)
    out = k.ScanDecoder(72).feed(noise + turn + turn + turn[:5])
    # noise may pass for nodes and corrupt the turn it runs into, never the ones after it
    assert len(out) >= 1 and np.array_equal(out[-1], ranges)


def _reference_turns(stream: bytes, beams: int, min_nodes: int) -> list[np.ndarray]:
    """The decoder's rules node by node: skip a byte on a bad node, a turn ends at the next start."""
    turns, current, pos = [], None, 0
    while len(stream) - pos >= 5:
        node = k.decode_node(stream, pos)
        if node is None:
            pos += 1
            continue
        pos += 5
        if node.start:
            if current is not None and len(current) >= min_nodes:
                r = np.full(beams, np.nan)
                for angle, q2 in current:
                    i = int(k.beam_index(angle, beams))
                    d = q2 / 4000.0 if q2 > 0 else math.inf
                    r[i] = d if np.isnan(r[i]) else min(r[i], d)
                turns.append(r)
            current = []
        if current is not None:
            current.append((node.angle_q6, node.distance_q2))
    return turns


@settings(max_examples=150, deadline=None)
@given(st.lists(st.one_of(st.binary(max_size=12),
                          st.tuples(st.booleans(), st.integers(0, 63), st.integers(0, 23039), st.integers(0, 65535))),
                max_size=120),
       st.integers(1, 300))
def test_vectorised_decoder_matches_the_node_by_node_reference(parts: list, step: int) -> None:
    stream = b"".join(p if isinstance(p, bytes) else k.encode_node(*p) for p in parts)
    dec = k.ScanDecoder(24, min_nodes=2)
    got = []
    for i in range(0, len(stream), step):
        got += dec.feed(stream[i:i + step])
    want = _reference_turns(stream, 24, 2)
    assert len(got) == len(want)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)


def test_capsule_layout() -> None:
    dist = np.arange(32) * 100 + 7
    dtheta = np.arange(32) % 64
    cap = k.encode_capsule(90 * 64 + 5, True, dist, dtheta)
    assert len(cap) == 84 and cap[0] >> 4 == 0xA and cap[1] >> 4 == 0x5
    assert (cap[0] & 0xF) | (cap[1] & 0xF) << 4 == k.checksum(cap[2:])
    assert int.from_bytes(cap[2:4], "little") == 0x8000 | (90 * 64 + 5)
    # first cabin: u16 distance1 << 2 | dθ1 >> 4, u16 distance2 << 2 | dθ2 >> 4, both low nibbles
    assert cap[4:9] == bytes.fromhex("1c 00 ac 01 10")
    # cabin 8: samples 16, 17 with dθ 16, 17 put their bit 4 in the distance words
    assert cap[44:49] == bytes.fromhex("1d 19 ad 1a 10")
    got = k.decode_capsule(cap)
    assert got == k.Capsule(90 * 64 + 5, True, tuple(int(x) for x in dist), tuple(int(x) for x in dtheta))
    spoilt = bytearray(cap)
    spoilt[40] ^= 1
    assert k.decode_capsule(bytes(spoilt)) is None
    with pytest.raises(ConfigError):
        k.encode_capsule(0, False, np.full(32, 16384))


def test_express_sample_angles_follow_the_sdk_rule() -> None:
    # sample j of capsule i: start_i + j * (start_{i+1} - start_i) / 32 - dθ_j / 8 deg
    dtheta = np.zeros(32, np.int64)
    dtheta[3] = 16                                           # 2 deg of compensation on sample 3
    caps = [k.encode_capsule(s * 64, False, np.full(32, 1000), dtheta if s == 350 else None)
            for s in (342, 350, 358, 6, 14)]
    dec = k.ExpressDecoder(720, min_nodes=1)
    dec.feed(b"".join(caps))
    # the turn in progress began where the raw angles wrapped: at 360 deg = 358 + 8 * 8/32 (sample 8 of
    # the third capsule); sample 3 of the second capsule lies at 350 + 3 * 0.25 - 2 = 348.75 deg
    assert dec.capsules == 5 and dec.gaps == 0
    assert np.concatenate(dec._angles)[0] == 0.0
    out = k.ExpressDecoder(720, min_nodes=1)
    first = out.feed(b"".join(caps[:2]))
    assert first == [] and out._angles == []                 # no turn begun yet


def test_express_round_trip_and_gap() -> None:
    n = 720
    rng = np.random.default_rng(3)
    turn = rng.integers(150, 12000, n)
    turn[::11] = 0
    caps = []
    for i in range(70):                                      # 3.1 turns of 720 samples
        j = i * 32
        idx = (j + np.arange(32)) % n
        caps.append(k.encode_capsule(int(round(idx[0] * 23040 / n)), i == 0, turn[idx]))
    dec = k.ExpressDecoder(n)
    out = []
    stream = b"".join(caps)
    for i in range(0, len(stream), 50):
        out += dec.feed(stream[i:i + 50])
    assert len(out) == 2
    want = np.where(turn > 0, turn / 1000.0, np.inf)[k.beam_index(k.node_angles_cw(n), n).argsort()]
    for got in out:
        np.testing.assert_array_equal(got, want)
    # capsule 30 lost: capsule 29 cannot be placed; the turn misses their 64 samples (NaN), no more
    dec2 = k.ExpressDecoder(n)
    out2 = dec2.feed(b"".join(caps[:30] + caps[31:]))
    assert dec2.gaps == 1 and len(out2) == 2
    assert np.isnan(out2[0]).sum() == 64 and np.isnan(out2[1]).sum() == 0
    fin = ~np.isnan(out2[0])
    np.testing.assert_array_equal(out2[0][fin], want[fin])


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=1200), st.integers(1, 90))
def test_express_decoder_never_raises(data: bytes, step: int) -> None:
    dec = k.ExpressDecoder(72, min_nodes=1)
    for i in range(0, len(data), step):
        for r in dec.feed(data[i:i + step]):
            assert r.shape == (72,)
