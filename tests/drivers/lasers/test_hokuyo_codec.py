"""SCIP 2.0 codec: byte vectors from Hokuyo's specification and a real URG-04LX's replies, round
trips, and property tests (the decoder never raises and finds scans again after noise)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robotexp.errors import ConfigError, ProtocolError
from robotexp_drivers.lasers.hokuyo import codec as k
from robotexp_drivers.lasers.hokuyo import constants as C

# The VV reply of a URG-04LX-UG01 (firmware 3.4.03), as a public capture shows it, and its BM reply
# when the laser was already on.
REAL_VV = (b"VV\n00P\nVEND:Hokuyo Automatic Co.,Ltd.;[\nPROD:SOKUIKI Sensor URG-04LX-UG01(Simple-URG);[\n"
           b"FIRM:3.4.03(17/Dec./2012);T\nPROT:SCIP 2.0;N\nSERI:H1510998;V\n\n")
REAL_BM_ALREADY_ON = b"BM\n02R\n\n"


def test_sums_of_documented_lines() -> None:
    assert k.encode_reply(b"BM", C.STATUS_BM_ALREADY_ON) == REAL_BM_ALREADY_ON
    assert k.encode_reply(b"QT", C.STATUS_OK) == b"QT\n00P\n\n"
    assert bytes((k.scip_sum(C.STATUS_SCAN),)) == b"b"          # every MD scan's "99b"
    assert k.param_line("VEND", "Hokuyo Automatic Co.,Ltd.") == b"VEND:Hokuyo Automatic Co.,Ltd.;["
    assert k.param_line("PROT", "SCIP 2.0") == b"PROT:SCIP 2.0;N"
    assert k.param_line("SERI", "H1510998") == b"SERI:H1510998;V"
    assert k.param_line("FIRM", "3.4.03(17/Dec./2012)") == b"FIRM:3.4.03(17/Dec./2012);T"
    assert k.param_line("TIME", "081615") == b"TIME:081615;N"          # a URG-04LX's II reply


def test_real_vv_reply_parses() -> None:
    blocks, cut = k.split_blocks(bytearray(REAL_VV))
    assert cut == 0 and len(blocks) == 1
    reply = k.parse_reply(blocks[0])
    assert reply.echo == b"VV" and reply.status == b"00"
    params = k.parse_params(reply)
    assert params["PROD"] == "SOKUIKI Sensor URG-04LX-UG01(Simple-URG)"
    assert params["SERI"] == "H1510998" and params["PROT"] == "SCIP 2.0"
    spoilt = REAL_VV.replace(b"SCIP 2.0;N", b"SCIP 2.0;O")
    with pytest.raises(ProtocolError, match="bad sum"):
        k.parse_reply(k.split_blocks(bytearray(spoilt))[0][0])


def test_character_encoding_examples() -> None:
    # the specification's examples: 1234 in 2 characters is "CB", 5432 in 3 characters is "1Dh"
    assert k.encode_values([1234], 2) == b"CB"
    assert k.encode_values([5432], 3) == b"1Dh"
    assert list(k.decode_values(b"CB1Dh"[:2], 2)) == [1234]
    assert list(k.decode_values(b"1Dh", 3)) == [5432]
    assert k.encode_values([C.ENC2_MAX], 2) == b"oo" and k.encode_values([0], 3) == b"000"
    with pytest.raises(ConfigError):
        k.encode_values([C.ENC2_MAX + 1], 2)
    with pytest.raises(ProtocolError):
        k.decode_values(b"0p", 2)          # 'p' is 0x70, past 0x6F
    with pytest.raises(ProtocolError):
        k.decode_values(b"000", 2)


def test_commands() -> None:
    assert k.md_command(44, 725, 1, 0, 0) == b"MD0044072501000\n"
    assert k.md_command(0, 1080, 3, 1, 5, encoding=C.CMD_MS, string="ab") == b"MS0000108003105;ab\n"
    assert k.gd_command(44, 725, 0) == b"GD0044072500\n"
    with pytest.raises(ConfigError):
        k.md_command(0, 10000)
    with pytest.raises(ConfigError):
        k.command(C.CMD_VV, string="x" * 17)


def test_gd_reply_size_of_a_full_urg04_scan() -> None:
    # a GD0044072500 reply of a URG-04LX is 2134 bytes (682 values of 3 characters in 32 lines)
    data = k.encode_scan(np.full(682, 1.0), start=44, end=725, cluster=0, encoding=C.CMD_GD)
    assert len(data) == 2134
    lines = data.split(b"\n")
    assert lines[0] == b"GD0044072500" and lines[1] == b"00P"
    assert all(len(line) == 65 for line in lines[3:34]) and len(lines[34]) == 63


def test_scan_line_layout_and_timestamp() -> None:
    data = k.encode_scan([1.234, 5.432, math.inf], start=100, end=102, remaining=7, timestamp_ms=(1 << 24) + 5)
    echo, status, stamp, values, end1, end2 = data.split(b"\n")
    assert echo == b"MD0100010201007" and status == b"99b"
    assert stamp[:4] == b"0005" and k.sum_ok(stamp)             # the counter wraps at 2**24 ms
    assert values[:9] == b"0CB1Dh001" and k.sum_ok(values)      # inf goes out as error code 1
    assert end1 == end2 == b""


@pytest.mark.parametrize("encoding", [C.CMD_MD, C.CMD_MS, C.CMD_GD, C.CMD_GS])
def test_round_trip_in_chunks(encoding: bytes) -> None:
    rng = np.random.default_rng(1)
    top = 4.0 if encoding in (C.CMD_MS, C.CMD_GS) else 30.0
    scans = [np.round(rng.uniform(0.03, top, 682), 3) for _ in range(3)]
    scans[1][::7] = math.inf
    stream = b"".join(k.encode_scan(s, encoding=encoding, timestamp_ms=i) for i, s in enumerate(scans))
    dec = k.ScanDecoder()
    out = []
    for i in range(0, len(stream), 97):
        out += dec.feed(stream[i:i + 97])
    assert len(out) == 3 and dec.scans == 3 and dec.dropped_bytes == 0
    for got, want in zip(out, scans, strict=True):
        np.testing.assert_array_equal(got, want)
    assert dec.timestamp_ms == 2


def test_decoder_skips_replies_and_reads_remaining() -> None:
    ack = k.encode_reply(b"MD0044072501003", C.STATUS_OK)
    stream = ack + b"".join(k.encode_scan(np.ones(682), remaining=r, string="id") for r in (2, 1, 0))
    dec = k.ScanDecoder()
    assert len(dec.feed(stream)) == 3
    assert dec.replies == 1 and dec.remaining == 0 and dec.echo == b"MD0044072501000;id"


def test_decoder_values_outside_dmin_dmax_are_no_echo() -> None:
    dec = k.ScanDecoder(dmin_mm=20, dmax_mm=5600)
    (r,) = dec.feed(k.encode_scan([0.019, 0.020, 5.6, 5.601], start=0, end=3))
    assert list(r) == [math.inf, 0.02, 5.6, math.inf]


def test_decoder_rejects_bad_sum_and_bad_count_then_recovers() -> None:
    good = k.encode_scan(np.ones(682))
    bad_sum = bytearray(good)
    bad_sum[30] ^= 0x01                                          # one data character flipped
    short = good.replace(b"MD0044072501000", b"MD0044072601000")   # echo says 683 values
    dec = k.ScanDecoder()
    out = dec.feed(bytes(bad_sum) + short + good)
    assert len(out) == 1 and dec.bad_sums == 1 and dec.bad_lengths == 1


def test_decoder_bounds_its_buffer() -> None:
    dec = k.ScanDecoder()
    assert dec.feed(b"x" * 40000) == []
    assert len(dec._buffer) <= k.MAX_BLOCK and dec.dropped_bytes >= 40000 - k.MAX_BLOCK
    assert len(dec.feed(b"\n\n" + k.encode_scan(np.ones(10), start=0, end=9))) == 1


def test_geometry_of_the_urg04lx() -> None:
    p = k.ScanParams(C.URG04_MODL, 20, 5600, 1024, 44, 725, 384, 600)
    g = k.geometry(p, 44, 725, 1, 4.0)
    assert g.beams == 682 and g.period == pytest.approx(0.1)
    assert math.degrees(g.angle_min) == pytest.approx((44 - 384) * 360 / 1024)
    assert math.degrees(g.angles()[-1]) == pytest.approx((725 - 384) * 360 / 1024)
    g3 = k.geometry(p, 44, 725, 3, 4.0)
    assert g3.beams == 228 and math.degrees(g3.angle_min) == pytest.approx((45 - 384) * 360 / 1024)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=600), st.integers(1, 50))
def test_decoder_never_raises(data: bytes, step: int) -> None:
    dec = k.ScanDecoder()
    for i in range(0, len(data), step):
        for r in dec.feed(data[i:i + step]):
            assert r.dtype == np.float64


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300), st.booleans(), st.lists(st.integers(20, 4000), min_size=1, max_size=70))
def test_decoder_resynchronises_after_noise(noise: bytes, same_line: bool, mm: list[int]) -> None:
    ranges = np.array(mm, np.float64) / 1000.0
    scan = k.encode_scan(ranges, start=0, end=len(mm) - 1)
    if same_line:           # noise glued to the echo, without an empty line in between
        noise = noise.replace(b"\n", b"")
        stream = b"\n\n" + noise + scan
    else:
        stream = noise + b"\n\n" + scan
    out = k.ScanDecoder().feed(stream)
    assert out and np.array_equal(out[-1], ranges)
