"""Pure codec of the Slamtec RPLidar A1/A2 protocol: requests, response descriptors, GET_INFO /
GET_HEALTH / GET_SAMPLERATE replies and the SCAN measurement nodes.

No I/O and no clocks here. A request is ``A5 CMD`` (``A5 CMD SIZE PAYLOAD CHECKSUM`` for commands
from 0x80); a reply starts with a 7-byte descriptor ``A5 5A LEN(30 bits)+MODE(2 bits) TYPE``; SCAN
streams 5-byte nodes, the first of each turn carrying the start flag (docs/protocols/rplidar.md).
The device measures clockwise from its front; `ScanDecoder` and `encode_scan` speak the laser frame
of robotexp.laser: beam i of `beams` at -pi + i * 2 pi / beams, counter-clockwise, metres.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robotexp import ConfigError, LaserGeometry, ProtocolError
from robotexp_drivers.lasers.rplidar import constants as C

_RUN_MAX = 4096     # nodes checked at once

__all__ = [
    "Capsule", "DeviceInfo", "ExpressDecoder", "Health", "Node", "Request", "RequestDecoder", "ScanDecoder",
    "beam_index", "bin_turn", "checksum", "decode_capsule", "encode_capsule",
    "decode_node", "descriptor", "encode_node", "encode_scan", "geometry", "node_angles_cw", "parse_descriptor",
    "request",
]


# --- requests -----------------------------------------------------------------------------------------
def checksum(data: bytes) -> int:
    """XOR of `data` (a request's bytes before its checksum)."""
    x = 0
    for b in data:
        x ^= b
    return x


def request(cmd: int, payload: bytes = b"") -> bytes:
    """A request: ``A5 cmd`` for commands below 0x80, else with size, payload and checksum.

    Raises:
        ConfigError: a payload on a command below 0x80, or longer than 255 bytes.
    """
    if not 0 <= cmd <= 0xFF:
        raise ConfigError(f"rplidar request: command must be a byte, got {cmd}")
    if not cmd & C.CMDFLAG_HAS_PAYLOAD:
        if payload:
            raise ConfigError(f"rplidar request 0x{cmd:02X}: commands below 0x80 carry no payload")
        return bytes((C.SYNC_BYTE, cmd))
    if len(payload) > C.MAX_PAYLOAD:
        raise ConfigError(f"rplidar request 0x{cmd:02X}: payload of {len(payload)} bytes exceeds 255")
    head = bytes((C.SYNC_BYTE, cmd, len(payload))) + payload
    return head + bytes((checksum(head),))


@dataclass(frozen=True)
class Request:
    """A request as the device receives it."""

    cmd: int
    payload: bytes = b""


class RequestDecoder:
    """Incremental decoder of requests (for an emulator): `feed` never raises; bytes that are not a
    request (or a payload request with a bad checksum) are dropped and counted."""

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.dropped_bytes = 0
        self.bad_checksums = 0

    def feed(self, data: bytes | bytearray | memoryview) -> list[Request]:
        """Append `data`; return the requests it completed, in order."""
        buf = self._buffer
        buf += data
        out: list[Request] = []
        pos = 0
        while True:
            start = buf.find(C.SYNC_BYTE, pos)
            if start < 0:
                self.dropped_bytes += len(buf) - pos
                pos = len(buf)
                break
            self.dropped_bytes += start - pos
            pos = start
            if len(buf) - pos < 2:
                break
            cmd = buf[pos + 1]
            if not cmd & C.CMDFLAG_HAS_PAYLOAD:
                out.append(Request(cmd))
                pos += 2
                continue
            if len(buf) - pos < 3:
                break
            end = pos + 3 + buf[pos + 2] + 1
            if len(buf) < end:
                break
            frame = bytes(buf[pos:end])
            if checksum(frame[:-1]) == frame[-1]:
                out.append(Request(cmd, frame[3:-1]))
                pos = end
            else:
                self.bad_checksums += 1
                self.dropped_bytes += 1
                pos += 1
        del buf[:pos]
        return out


# --- replies ------------------------------------------------------------------------------------------
def descriptor(length: int, mode: int, dtype: int) -> bytes:
    """A response descriptor: A5 5A, length (30 bits) and send mode (2 bits) little-endian, type."""
    return bytes((C.SYNC_BYTE, C.SYNC_BYTE2)) + struct.pack(
        "<IB", (length & C.LENGTH_MASK) | (mode << C.SEND_MODE_SHIFT), dtype)


def parse_descriptor(data: bytes) -> tuple[int, int, int]:
    """(length, send mode, data type) of a 7-byte descriptor.

    Raises:
        ProtocolError: not 7 bytes starting A5 5A.
    """
    if len(data) != C.DESCRIPTOR_LEN or data[0] != C.SYNC_BYTE or data[1] != C.SYNC_BYTE2:
        raise ProtocolError(f"rplidar: bad response descriptor {data.hex(' ')}")
    word, dtype = struct.unpack("<IB", data[2:])
    return word & C.LENGTH_MASK, word >> C.SEND_MODE_SHIFT, dtype


@dataclass(frozen=True)
class DeviceInfo:
    """GET_INFO: model, firmware (major, minor), hardware revision, 16-byte serial number."""

    model: int
    firmware: tuple[int, int]
    hardware: int
    serial: bytes

    def encode(self) -> bytes:
        """The 20 data bytes."""
        return bytes((self.model, self.firmware[1], self.firmware[0], self.hardware)) + self.serial

    @classmethod
    def decode(cls, data: bytes) -> DeviceInfo:
        """From the 20 data bytes. Raises ProtocolError on another length."""
        if len(data) != C.DEVINFO_LEN:
            raise ProtocolError(f"rplidar GET_INFO: {len(data)} data bytes, expected {C.DEVINFO_LEN}")
        return cls(data[0], (data[2], data[1]), data[3], bytes(data[4:]))

    def describe(self) -> str:
        """The identity in a line: model and series, firmware, hardware, serial in hex."""
        return (f"model 0x{self.model:02X} (A{self.model >> 4} series) firmware "
                f"{self.firmware[0]}.{self.firmware[1]:02d} hardware {self.hardware} "
                f"serial {self.serial.hex().upper()}")


@dataclass(frozen=True)
class Health:
    """GET_HEALTH: status (0 good, 1 warning, 2 error) and error code."""

    status: int
    error_code: int = 0

    def encode(self) -> bytes:
        """The 3 data bytes."""
        return struct.pack("<BH", self.status, self.error_code)

    @classmethod
    def decode(cls, data: bytes) -> Health:
        """From the 3 data bytes. Raises ProtocolError on another length."""
        if len(data) != C.HEALTH_LEN:
            raise ProtocolError(f"rplidar GET_HEALTH: {len(data)} data bytes, expected {C.HEALTH_LEN}")
        status, code = struct.unpack("<BH", data)
        return cls(status, code)


# --- measurement nodes -----------------------------------------------------------------------------
@dataclass(frozen=True)
class Node:
    """One SCAN measurement in the protocol's units."""

    start: bool         # first node of a new turn
    quality: int        # 0..63
    angle_q6: int       # [1/64 deg] clockwise
    distance_q2: int    # [1/4 mm], 0 = no measurement


def encode_node(start: bool, quality: int, angle_q6: int, distance_q2: int) -> bytes:
    """The 5 bytes of a node (fields masked to their widths)."""
    s = 1 if start else 0
    b0 = ((quality & C.QUALITY_MAX) << C.NODE_QUALITY_SHIFT) | ((1 - s) << 1) | s
    a = angle_q6 & 0x7FFF
    return struct.pack("<BBBH", b0, ((a & 0x7F) << C.NODE_ANGLE_SHIFT) | C.NODE_CHECKBIT, a >> 7,
                       distance_q2 & 0xFFFF)


def decode_node(data: bytes | bytearray, pos: int = 0) -> Node | None:
    """The node at `data[pos:pos + 5]`, or None when its start bits or check bit are wrong or its
    angle is 360 deg or more."""
    b0, b1 = data[pos], data[pos + 1]
    if ((b0 ^ (b0 >> 1)) & 1) == 0 or not b1 & C.NODE_CHECKBIT:
        return None
    angle = (b1 >> 1) | (data[pos + 2] << 7)
    if angle >= C.ANGLE_Q6_TURN:
        return None
    return Node(bool(b0 & C.NODE_SYNCBIT), b0 >> C.NODE_QUALITY_SHIFT, angle, data[pos + 3] | (data[pos + 4] << 8))


def geometry(beams: int, range_min: float, range_max: float, period: float) -> LaserGeometry:
    """The beams a turn is binned into: beam i at -pi + i * 2 pi / beams (counter-clockwise)."""
    return LaserGeometry(-math.pi, 2 * math.pi / beams, beams, range_min, range_max, period)


def beam_index(angle_q6: npt.ArrayLike, beams: int) -> npt.NDArray[np.int64]:
    """The beam (see `geometry`) nearest to clockwise angles `angle_q6`."""
    ccw_deg = -np.asarray(angle_q6, np.float64) / C.ANGLE_Q6_PER_DEG
    return np.rint((ccw_deg + 180.0) * beams / 360.0).astype(np.int64) % beams


def node_angles_cw(beams: int) -> npt.NDArray[np.int64]:
    """The clockwise angles [1/64 deg] of one turn sampled at each beam once, in the order the device
    sweeps them (from 0 at the front, clockwise); node k falls in beam (beams/2 - k) mod beams."""
    return np.rint(np.arange(beams) * (C.ANGLE_Q6_TURN / beams)).astype(np.int64)


def encode_scan(ranges: npt.ArrayLike, *, quality: int = 47, first: int = 0, count: int | None = None) -> bytes:
    """One turn (or part of it) as SCAN streams it: one node per beam of `geometry(len(ranges))`, in
    the device's clockwise order from the front, the first node of the turn with the start flag.

    Args:
        ranges: [m] per beam; inf or NaN (no echo) goes out as distance 0, quality 0.
        quality: the quality of the other nodes (0..63).
        first, count: only nodes `first` .. `first + count - 1` of the turn (an emulator streams a
            turn in pieces); the start flag goes with node 0.

    Raises:
        ConfigError: no ranges, or `first`/`count` outside the turn.
    """
    r = np.asarray(ranges, dtype=np.float64).ravel()
    n = r.size
    count = n - first if count is None else count
    if n == 0 or not (0 <= first and count >= 0 and first + count <= n):
        raise ConfigError(f"rplidar encode_scan: nodes {first}..{first + count - 1} of a {n}-beam turn")
    angles = node_angles_cw(n)[first:first + count]
    beam = beam_index(angles, n)
    d = r[beam]
    ok = np.isfinite(d) & (d > 0)
    q2 = np.zeros(count, np.int64)
    q2[ok] = np.clip(np.rint(d[ok] * 1000.0 * C.DISTANCE_Q2_PER_MM), 1, 0xFFFF)
    out = np.empty((count, C.NODE_LEN), np.uint8)
    start = np.zeros(count, np.int64)
    if first == 0 and count:
        start[0] = 1
    qual = np.where(ok, quality & C.QUALITY_MAX, 0)
    out[:, 0] = (qual << C.NODE_QUALITY_SHIFT) | ((1 - start) << 1) | start
    out[:, 1] = ((angles & 0x7F) << C.NODE_ANGLE_SHIFT) | C.NODE_CHECKBIT
    out[:, 2] = angles >> 7
    out[:, 3] = q2 & 0xFF
    out[:, 4] = q2 >> 8
    return out.tobytes()


class _Turns:
    """What both stream decoders share: a turn's samples gathered in runs, split where a new turn
    begins, and binned (`bin_turn`) when it ends."""

    def _init_turns(self, who: str, beams: int, min_nodes: int | None, range_min: float) -> None:
        if beams < 1:
            raise ConfigError(f"rplidar {who}: beams must be >= 1, got {beams}")
        self.beams = beams
        self.min_nodes = max(1, beams // 4) if min_nodes is None else min_nodes
        self.range_min = range_min
        self._buffer = bytearray()
        self._angles: list[npt.NDArray[np.generic]] = []     # the open turn's samples, in runs
        self._dist: list[npt.NDArray[np.int64]] = []
        self._in_turn = False
        self.scans = 0
        self.dropped_bytes = 0
        self.short_turns = 0
        self.turn_samples = 0       # samples of the newest complete turn

    def _add(self, angles_q6: npt.NDArray[np.generic], dist_q2: npt.NDArray[np.int64], starts: npt.NDArray[np.intp],
             out: list[npt.NDArray[np.float64]]) -> None:
        """Append a run of samples in which a new turn begins at each index of `starts`."""
        begin = 0
        for s in starts:
            if self._in_turn:
                self._angles.append(angles_q6[begin:s])
                self._dist.append(dist_q2[begin:s])
                done = self._finish()
                if done is not None:
                    out.append(done)
            self._in_turn = True
            begin = int(s)
        if self._in_turn:
            self._angles.append(angles_q6[begin:])
            self._dist.append(dist_q2[begin:])

    def _finish(self) -> npt.NDArray[np.float64] | None:
        angles = np.concatenate(self._angles) if self._angles else np.zeros(0, np.int64)
        dist_q2 = np.concatenate(self._dist) if self._dist else np.zeros(0, np.int64)
        self._angles, self._dist = [], []
        if angles.size < self.min_nodes:
            self.short_turns += 1
            return None
        self.scans += 1
        self.turn_samples = int(angles.size)
        return bin_turn(angles, dist_q2, self.beams, self.range_min)

    @property
    def open_samples(self) -> int:
        """Samples of the turn in progress (received after the newest complete turn ended)."""
        return sum(len(a) for a in self._angles) if self._in_turn else 0


class ScanDecoder(_Turns):
    """Incremental decoder of the SCAN node stream: feed it any bytes, get the ranges of every turn
    completed by them (a turn completes when the next turn's first node arrives).

    Nodes are checked by their start/inverse-start bits, their check bit and their angle; on a bad
    node the decoder drops one byte and looks again (resynchronising). A turn's nodes are binned to
    the nearest of `beams` beams (`geometry`), keeping the nearest echo; a beam no node fell in reads
    NaN (not measured this turn), a node without a distance reads inf (no echo). Nodes before the
    first start flag (a turn seen in part) are dropped; so are turns of fewer than `min_nodes` nodes
    (a false start flag in noise). `feed` never raises on any bytes.

    Attributes:
        scans: turns decoded.
        nodes: valid nodes seen.
        dropped_bytes: bytes skipped while resynchronising.
        short_turns: turns dropped for having fewer than `min_nodes` nodes.
    """

    def __init__(self, beams: int = 360, *, min_nodes: int | None = None, range_min: float = 0.0) -> None:
        self._init_turns("ScanDecoder", beams, min_nodes, range_min)
        self.nodes = 0

    def feed(self, data: bytes | bytearray | memoryview) -> list[npt.NDArray[np.float64]]:
        """Append `data` to the stream; return the ranges [m] of the turns it completed, in order.

        Runs of valid nodes are checked and split at their start flags with numpy (`_run`); a bad
        node is skipped byte by byte as `decode_node` finds it.
        """
        buf = self._buffer
        buf += data
        out: list[npt.NDArray[np.float64]] = []
        n = len(buf)
        pos = 0
        while n - pos >= C.NODE_LEN:
            if decode_node(buf, pos) is None:
                pos += 1
                self.dropped_bytes += 1
                continue
            pos += C.NODE_LEN * self._run(buf, pos, min((n - pos) // C.NODE_LEN, _RUN_MAX), out)
        del buf[:pos]
        return out

    def _run(self, buf: bytearray, pos: int, count: int, out: list[npt.NDArray[np.float64]]) -> int:
        """Take the valid nodes among the `count` at `pos` up to the first bad one (the first is
        valid); return how many were taken."""
        a = np.frombuffer(buf, np.uint8, count * C.NODE_LEN, pos).reshape(count, C.NODE_LEN).astype(np.int64)
        b0, b1 = a[:, 0], a[:, 1]
        angle = (b1 >> C.NODE_ANGLE_SHIFT) | (a[:, 2] << 7)
        ok = (((b0 ^ (b0 >> 1)) & 1) == 1) & ((b1 & C.NODE_CHECKBIT) == 1) & (angle < C.ANGLE_Q6_TURN)
        k = count if ok.all() else int(np.argmin(ok))
        self.nodes += k
        self._add(angle[:k], a[:k, 3] | (a[:k, 4] << 8), np.flatnonzero(b0[:k] & C.NODE_SYNCBIT), out)
        return k


def bin_turn(angles_q6: npt.ArrayLike, dist_q2: npt.ArrayLike, beams: int, range_min: float = 0.0
             ) -> npt.NDArray[np.float64]:
    """A turn's measurements (clockwise angles [1/64 deg], distances [1/4 mm]) binned to the nearest of
    `beams` beams (`geometry`): the nearest echo per beam; inf where the nodes had no distance (or one
    under `range_min` [m]); NaN where no node fell."""
    angles = np.asarray(angles_q6, np.float64)
    idx = beam_index(angles, beams)
    d = np.asarray(dist_q2, np.float64) / (1000.0 * C.DISTANCE_Q2_PER_MM)
    d[(d <= 0) | (d < range_min)] = math.inf
    ranges = np.full(beams, math.inf)
    np.minimum.at(ranges, idx, d)
    seen = np.zeros(beams, bool)
    seen[idx] = True
    ranges[~seen] = math.nan
    return ranges


# --- express scan (legacy capsules) --------------------------------------------------------------------
@dataclass(frozen=True)
class Capsule:
    """One EXPRESS_SCAN capsule: the start angle of its first sample, the start flag (first capsule
    after the request), and 32 samples: distance [mm] (0: none) and angle compensation dθ [1/8 deg]."""

    start_q6: int
    new_scan: bool
    distance_mm: tuple[int, ...]
    dtheta_q3: tuple[int, ...]


def encode_capsule(start_q6: int, new_scan: bool, distance_mm: npt.ArrayLike, dtheta_q3: npt.ArrayLike | None = None
                   ) -> bytes:
    """The 84 bytes of a capsule: sync nibbles 0xA / 0x5 around the XOR checksum of bytes 2..83, the
    start angle (15 bits) with the start flag in bit 15, and 16 cabins of two samples: distance
    [mm] << 2 | dθ bits 4-5 (u16 LE each), then both dθ's low nibbles.

    Raises:
        ConfigError: not 32 samples, or a distance or dθ that does not fit (14 / 6 bits).
    """
    d = np.asarray(distance_mm, np.int64).ravel()
    t = np.zeros(C.EXPRESS_SAMPLES, np.int64) if dtheta_q3 is None else np.asarray(dtheta_q3, np.int64).ravel()
    if d.size != C.EXPRESS_SAMPLES or t.size != C.EXPRESS_SAMPLES:
        raise ConfigError(f"rplidar capsule: {C.EXPRESS_SAMPLES} samples needed, got {d.size} and {t.size}")
    if d.min() < 0 or d.max() > C.EXPRESS_DISTANCE_MAX_MM or t.min() < 0 or t.max() > 63:
        raise ConfigError("rplidar capsule: distances must be 0..16383 mm and dθ 0..63 (1/8 deg)")
    body = bytearray(struct.pack("<H", (start_q6 & 0x7FFF) | (C.EXPRESS_SYNCBIT if new_scan else 0)))
    for c in range(C.EXPRESS_CABINS):
        d1, d2, t1, t2 = d[2 * c], d[2 * c + 1], t[2 * c], t[2 * c + 1]
        body += struct.pack("<HHB", int(d1 << 2 | t1 >> 4), int(d2 << 2 | t2 >> 4), int((t1 & 0xF) | (t2 & 0xF) << 4))
    cs = checksum(bytes(body))
    return bytes((C.EXPRESS_SYNC_1 << 4 | cs & 0xF, C.EXPRESS_SYNC_2 << 4 | cs >> 4)) + bytes(body)


def decode_capsule(data: bytes | bytearray, pos: int = 0) -> Capsule | None:
    """The capsule at `data[pos:pos + 84]`, or None when its sync nibbles or checksum are wrong."""
    if len(data) - pos < C.EXPRESS_CAPSULE_LEN:
        return None
    b0, b1 = data[pos], data[pos + 1]
    if b0 >> 4 != C.EXPRESS_SYNC_1 or b1 >> 4 != C.EXPRESS_SYNC_2:
        return None
    body = bytes(data[pos + 2:pos + C.EXPRESS_CAPSULE_LEN])
    if checksum(body) != (b0 & 0xF) | (b1 & 0xF) << 4:
        return None
    start = body[0] | body[1] << 8
    cab = np.frombuffer(body, np.uint8, offset=2).reshape(C.EXPRESS_CABINS, 5).astype(np.int64)
    w1, w2, off = cab[:, 0] | cab[:, 1] << 8, cab[:, 2] | cab[:, 3] << 8, cab[:, 4]
    dist = np.stack([w1 >> 2, w2 >> 2], axis=1).ravel()
    dtheta = np.stack([(off & 0xF) | (w1 & 0x3) << 4, (off >> 4) | (w2 & 0x3) << 4], axis=1).ravel()
    return Capsule(start & 0x7FFF, bool(start & C.EXPRESS_SYNCBIT), tuple(int(x) for x in dist),
                   tuple(int(x) for x in dtheta))


class ExpressDecoder(_Turns):
    """Incremental decoder of the EXPRESS_SCAN capsule stream, with the same output as `ScanDecoder`.

    Sample k of capsule i lies at start_i + k * (start_{i+1} - start_i) / 32 - dθ_k (Slamtec's rule:
    a capsule is decoded when the next one arrives); a turn ends where the sample angles wrap past
    360 deg. A capsule with a bad sync or checksum is skipped byte by byte; one that carries the start
    flag, or follows a step of more than `max_step` deg or half again the step before (a capsule was
    lost), starts afresh: the capsule before it cannot be placed and its samples are left out.
    `feed` never raises on any bytes.

    Attributes:
        scans: turns decoded.
        capsules: valid capsules seen.
        dropped_bytes: bytes skipped while resynchronising.
        gaps: capsules dropped because the next one could not place them.
        short_turns: turns dropped for having fewer than `min_nodes` samples.
    """

    def __init__(self, beams: int = 720, *, min_nodes: int | None = None, range_min: float = 0.0,
                 max_step: float = 45.0) -> None:
        self._init_turns("ExpressDecoder", beams, min_nodes, range_min)
        self.max_step_q6 = max_step * C.ANGLE_Q6_PER_DEG
        self._prev: Capsule | None = None
        self._last_raw = -1.0
        self._last_diff = 0
        self.capsules = 0
        self.gaps = 0

    def feed(self, data: bytes | bytearray | memoryview) -> list[npt.NDArray[np.float64]]:
        """Append `data` to the stream; return the ranges [m] of the turns it completed, in order."""
        buf = self._buffer
        buf += data
        out: list[npt.NDArray[np.float64]] = []
        pos = 0
        while len(buf) - pos >= C.EXPRESS_CAPSULE_LEN:
            cap = decode_capsule(buf, pos)
            if cap is None:
                pos += 1
                self.dropped_bytes += 1
                continue
            pos += C.EXPRESS_CAPSULE_LEN
            self.capsules += 1
            self._place(cap, out)
        del buf[:pos]
        return out

    def _place(self, cap: Capsule, out: list[npt.NDArray[np.float64]]) -> None:
        prev, self._prev = self._prev, cap
        if prev is None:
            return
        diff = (cap.start_q6 - prev.start_q6) % C.ANGLE_Q6_TURN
        last, self._last_diff = self._last_diff, diff
        # a capsule lost in between shows as a step much longer than the last one
        if cap.new_scan or diff > self.max_step_q6 or (last > 0 and diff > 1.5 * last + C.ANGLE_Q6_PER_DEG):
            self.gaps += 1
            return
        raw = prev.start_q6 + diff * np.arange(C.EXPRESS_SAMPLES) / C.EXPRESS_SAMPLES
        raw_mod = raw % C.ANGLE_Q6_TURN
        angles = (raw - 8.0 * np.array(prev.dtheta_q3)) % C.ANGLE_Q6_TURN
        dist_q2 = np.array(prev.distance_mm, np.int64) * C.DISTANCE_Q2_PER_MM
        # where the raw angle wraps past 360 deg a new turn begins
        wraps = np.flatnonzero(np.diff(np.concatenate(([self._last_raw], raw_mod))) < 0)
        self._last_raw = float(raw_mod[-1])
        self._add(angles, dist_q2, wraps, out)
