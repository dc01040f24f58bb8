"""LMS2xx codec: byte vectors from SICK's documents, round trips, property tests of the decoders."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robotexp.errors import ConfigError, ProtocolError
from robotexp_drivers.lasers.lms2xx import codec as k
from robotexp_drivers.lasers.lms2xx import constants as c

# Complete telegrams as printed in SICK's Quick Manual (QM, appendix C) and Telegram Listing (TL 7), and the
# power-on telegram of a real LMS200 (0x90, type "LMS200;30106", firmware V02.10): CRCs not computed by us.
DOCUMENTED = {
    "status": ("02 00 01 00 31 15 12", k.req_status),
    "type": ("02 00 01 00 3A 1E 12", k.req_type),
    "read config": ("02 00 01 00 74 50 12", k.req_config),
    "reset": ("02 00 01 00 10 34 12", k.req_reset),
    "installation": ("02 00 0A 00 20 00 53 49 43 4B 5F 4C 4D 53 BE C5", k.req_installation),
    "continuous": ("02 00 02 00 20 24 34 08", k.req_continuous),
    "stop": ("02 00 02 00 20 25 35 08", k.req_stop),
    "9600": ("02 00 02 00 20 42 52 08", lambda: k.req_baud(9600)),
    "19200": ("02 00 02 00 20 41 51 08", lambda: k.req_baud(19200)),
    "38400": ("02 00 02 00 20 40 50 08", lambda: k.req_baud(38400)),
    "500k": ("02 00 02 00 20 48 58 08", lambda: k.req_baud(500000)),
    "one scan": ("02 00 02 00 30 01 31 18", k.req_values),
    "180/1": ("02 00 05 00 3B B4 00 64 00 97 49", lambda: k.req_variant(180, 100)),
    "180/0.5": ("02 00 05 00 3B B4 00 32 00 3B 1F", lambda: k.req_variant(180, 50)),
    "100/0.25": ("02 00 05 00 3B 64 00 19 00 E7 72", lambda: k.req_variant(100, 25)),
    "A0 from 0x80": ("02 80 03 00 A0 00 10 16 0A", lambda: k.reply_mode(0)),
    "A0 from 0x81": ("02 81 03 00 A0 00 10 36 1A", lambda: k.reply_mode(0, address=1)),
    "power-on": ("02 80 17 00 90 4C 4D 53 32 30 30 3B 33 30 31 30 36 33 3B 56 30 32 2E 31 30 20 10 63 5E",
                 k.reply_power_on),
}


@pytest.mark.parametrize("name", sorted(DOCUMENTED))
def test_builders_make_the_documented_telegrams(name: str) -> None:
    wire, build = DOCUMENTED[name]
    expected = bytes.fromhex(wire)
    assert build() == expected
    assert k.crc16(expected[:-2]) == expected[-2] | expected[-1] << 8
    assert k.crc16_reference(expected[:-2]) == expected[-2] | expected[-1] << 8


@settings(deadline=None)       # the first call loads the numba kernel
@given(st.binary(max_size=900))
def test_crc_kernel_equals_reference(data: bytes) -> None:
    assert k.crc16(data) == k.crc16_reference(data)


def test_crc_by_hand() -> None:
    # "02 00": crc 0 -> <<1 = 0 ^ 0x0002 = 0x0002; next: 0x0004 ^ (0x02 << 8 | 0x00) = 0x0204
    assert k.crc16_reference(b"\x02") == 0x0002
    assert k.crc16_reference(b"\x02\x00") == 0x0204
    # "80 00 00": 0x0080; 0x0100 ^ 0x8000 = 0x8100; top bit set: (0x0100 << 1) ^ 0x8005 = 0x8205, ^ 0x0000
    assert k.crc16_reference(b"\x80\x00\x00") == 0x8205


def test_decoder_reads_requests_and_replies_in_garbage() -> None:
    requests = [bytes.fromhex(DOCUMENTED[n][0]) for n in ("status", "installation", "180/0.5")]
    dec = k.TelegramDecoder(replies=False)
    stream = b"\xff\x13" + requests[0] + b"\x00\x02\x81" + requests[1] + b"zz" + requests[2]
    out = []
    for i in range(0, len(stream), 3):
        out += dec.feed(stream[i:i + 3])
    out += dec.flush()
    assert [(t.address, t.command, t.data) for t in out] == [
        (0, 0x31, b""), (0, 0x20, b"\x00SICK_LMS"), (0, 0x3B, bytes.fromhex("B4 00 32 00"))]
    replies = k.TelegramDecoder(replies=True)
    got = replies.feed(b"\x06" + k.reply_mode(0) + b"\x15" + bytes.fromhex(DOCUMENTED["power-on"][0]))
    assert [(t.command, t.data, t.status) for t in got] == [
        (0xA0, b"\x00", 0x10), (0x90, b"LMS200;301063;V02.10 ", 0x10)]
    assert (replies.acks, replies.naks) == (1, 1)
    assert all(t.is_reply for t in got)


def test_decoder_drops_bad_crc_and_finds_the_telegram_inside() -> None:
    good = k.reply_mode(0)
    bad = bytearray(k.reply_variant(True, 180, 100))
    bad[-1] ^= 0xFF
    dec = k.TelegramDecoder()
    out = dec.feed(bytes(bad[:6]) + good + bytes(bad[6:]))     # a real telegram inside a broken one
    assert [t.command for t in out] == [0xA0]
    assert dec.bad_crcs >= 1


def test_measured_values_layout_by_hand() -> None:
    # 3 values in mm: 1000 mm, no echo, 2500 mm -> header 0x4003 (count 3, unit bits 01)
    frame = k.encode_scan([1.0, np.inf, 2.5])
    assert frame[:5] == bytes.fromhex("02 80 0A 00 B0")
    assert frame[5:13] == bytes.fromhex("03 40 E8 03 F7 1F C4 09")
    assert frame[13] == c.STATUS_OK
    # cm: 1.0 m -> 100 = 0x0064, header 0x0003
    assert k.encode_scan([1.0], units="cm")[5:9] == bytes.fromhex("01 00 64 00")
    dec = k.ScanDecoder()
    (ranges,) = dec.feed(frame)
    assert ranges.tolist() == [1.0, np.inf, 2.5]


def test_special_values_and_flag_bits() -> None:
    # TL 10.8: 0x1FF7..0x1FFF are no distance; flag bits 13-15 (fields / dazzle) are not part of the range
    values = np.array([0x1FF7, 0x1FFF, 0x1FFE, 0x1FF6, 0x2000 | 1234, 0xE000 | 42], dtype=np.uint16)
    r = k.values_to_ranges(values)
    assert r[:3].tolist() == [np.inf] * 3
    assert r[3:].tolist() == pytest.approx([8.182, 1.234, 0.042])
    # a 15-bit mode (ARIA's "1ref", 32 m) keeps bit 13/14 as range
    assert k.values_to_ranges(np.array([0x6000], dtype=np.uint16), bits=15).tolist() == [24.576]
    assert k.ranges_to_values([9.0, -1.0, np.nan, 7.9999], reach=8.0).tolist() == [0x1FF7, 0x1FF7, 0x1FF7, 8000]


def test_values_header_fields() -> None:
    mv = k.MeasuredValues(np.arange(5, dtype=np.uint16), c.Units.CM, partial=True, raster=2, extra=b"\x07")
    data = k.encode_values(mv)
    assert data[:2] == (5 | 2 << 11 | 0x2000 | 0 << 14).to_bytes(2, "little")
    back = k.decode_values(data)
    assert (back.values.tolist(), back.units, back.partial, back.raster, back.extra) == (
        [0, 1, 2, 3, 4], c.Units.CM, True, 2, b"\x07")
    with pytest.raises(ProtocolError):
        k.decode_values(data + b"\x00\x00")          # 3 bytes beyond the values
    with pytest.raises(ProtocolError):
        k.decode_values((0xC000 | 1).to_bytes(2, "little") + b"\x00\x00")    # reserved unit bits


def test_scan_decoder_skips_partial_and_wrong_count() -> None:
    partial = k.encode_telegram(c.Reply.VALUES, k.encode_values(
        k.MeasuredValues(np.ones(3, dtype=np.uint16), c.Units.MM, partial=True)), address=0x80, status=0x10)
    dec = k.ScanDecoder(beams=2)
    assert dec.feed(partial + k.encode_scan([1.0, 2.0, 3.0]) + k.encode_scan([1.0, 2.0]))[0].tolist() == [1.0, 2.0]
    assert (dec.partial, dec.bad_scans, dec.scans) == (1, 1, 1)


def test_config_and_status_round_trip() -> None:
    cfg = k.LMSConfig.default().with_(measuring_mode=c.MeasuringMode.M32_REFLECTOR, units=c.Units.CM)
    t = k.TelegramDecoder().feed(k.reply_configured(True, cfg))[0]
    ok, back = k.parse_config_reply(t)
    assert ok and back == cfg and back.raw[c.CFG_STOP_THRESHOLD] == 70
    assert k.req_configure(cfg)[:5] == bytes((0x02, 0x00, 35, 0x00, 0x77))
    st_in = k.LMSStatus("V02.10 ", 0x25, 0, 0, 180, 50, 38400, 0, 1)
    frame = k.reply_status(st_in)
    assert len(frame) == 4 + 1 + c.STATUS_DATA_LEN + 1 + 2
    assert frame[5 + c.ST_BAUD:5 + c.ST_BAUD + 2] == bytes.fromhex("19 80")      # TL p56: 0x8019 = 38400
    assert k.parse_status_reply(k.TelegramDecoder().feed(frame)[0]) == st_in
    assert k.parse_variant_reply(k.TelegramDecoder().feed(k.reply_variant(False, 100, 25))[0]) == (False, 100, 25)
    with pytest.raises(ProtocolError):
        k.parse_mode_reply(t)
    with pytest.raises(ProtocolError):
        k.LMSConfig.parse(b"\x00" * 33)


def test_bad_requests_refused() -> None:
    for bad in (lambda: k.req_variant(180, 25), lambda: k.req_baud(57600), lambda: k.req_installation(b"short"),
                lambda: k.units_of("inch"), lambda: k.range_bits(0x3F), lambda: k.encode_scan(np.ones(1024))):
        with pytest.raises(ConfigError):
            bad()


def test_geometry_helpers() -> None:
    assert [c.beams(180, 100), c.beams(180, 50), c.beams(100, 25)] == [181, 361, 401]
    assert c.scan_period(50) == pytest.approx(2 / 75)
    assert c.line_time(372, 38400) == pytest.approx(0.096875)
    assert k.reach_of(0, c.Units.MM) == 8.0 and k.reach_of(0, c.Units.CM) == 80.0
    assert k.reach_of(5, c.Units.MM) == 32.0 and k.reach_of(5, c.Units.CM) == 80.0


# -- properties -----------------------------------------------------------------------------------------------
ranges_st = st.lists(st.one_of(st.floats(0.0, 8.0), st.just(np.inf)), min_size=1, max_size=401)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=2000))
def test_decoders_never_raise(data: bytes) -> None:
    dec = k.ScanDecoder()
    for i in range(0, len(data), 97):
        dec.feed(data[i:i + 97])
    dec.flush()
    req = k.TelegramDecoder(replies=False)
    req.feed(data)
    req.flush()


@settings(max_examples=150, deadline=None)
@given(ranges_st, st.sampled_from(["mm", "cm"]))
def test_encoded_scans_round_trip(ranges: list[float], units: str) -> None:
    (back,) = k.ScanDecoder().feed(k.encode_scan(ranges, units=units))
    r = np.asarray(ranges)
    unit = 0.001 if units == "mm" else 0.01
    assert np.array_equal(np.isinf(back), np.isinf(r))
    assert np.all(np.abs(back[np.isfinite(r)] - r[np.isfinite(r)]) <= unit / 2 + 1e-12)


@settings(max_examples=150, deadline=None)
@given(st.binary(max_size=300), ranges_st, ranges_st, st.integers(1, 64))
def test_resynchronises_after_garbage(garbage: bytes, a: list[float], b: list[float], chunk: int) -> None:
    clean = garbage.replace(b"\x02", b"\x03")                   # no STX: no false candidate to wait on
    stream = clean + k.encode_scan(a) + clean + k.encode_scan(b)
    dec = k.ScanDecoder()
    out = []
    for i in range(0, len(stream), chunk):
        out += dec.feed(stream[i:i + chunk])
    assert len(out) == 2
    assert out[1].shape == (len(b),)


@settings(max_examples=100, deadline=None)
@given(st.binary(min_size=1, max_size=300), ranges_st)
def test_resynchronises_after_any_garbage_by_flush(garbage: bytes, a: list[float]) -> None:
    # garbage may hold an STX announcing a long telegram: the scan comes out at the latest on flush
    dec = k.ScanDecoder()
    out = dec.feed(garbage + k.encode_scan(a) + k.encode_scan(a))
    out += dec.flush()
    assert [x.shape for x in out] == [(len(a),)] * 2
