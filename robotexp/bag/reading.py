"""Bounded reading of an MCAP recording: every record, chunk and message is checked against a size
limit before it is read, decompressed or decoded, so that a small file cannot ask for gigabytes
(a zstd chunk of zeros decompresses 20000-fold), and a message that does not decode as its topic's
type is one clear error (`ConfigError`), never a traceback.

The file is read in one pass, record by record (chunks decompressed one at a time and dropped), so a
recording without a summary (a run that was killed) reads as well as a finished one.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import struct
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import IO, Any

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import MAX_CELLS
from robotexp.signals import held

__all__ = ["MAX_RECORD_BYTES", "MAX_CHUNK_BYTES", "MAX_MESSAGE_BYTES", "MAX_READ_BYTES", "MAX_POSITION", "TOPIC_TYPES",
           "TEAM_TOPIC_TYPES", "MAX_ROBOTS", "Record", "read_records", "finite"]

MAX_RECORD_BYTES = 128 * 2**20     # a record as stored (a compressed chunk, a message, a metadata record)
MAX_CHUNK_BYTES = 128 * 2**20      # a chunk once decompressed
MAX_MESSAGE_BYTES = 16 * 2**20     # a message of any topic but the maps (a scan of 2 M beams)
MAX_MAP_BYTES = MAX_CELLS + 4096    # an OccupancyGrid: MAX_CELLS cells and its header
MAX_READ_BYTES = 2 * 2**30       # all the messages a replay reads, together (what it keeps is about as much)
MAX_POSITION = 1e6                 # [m] a recorded position farther from the origin is refused

# the type each topic a replay reads must have (the ROS 2 type names; "pkg/Type" accepted too)
TOPIC_TYPES = {
    "/odom": "nav_msgs/msg/Odometry",
    "/scan": "sensor_msgs/msg/LaserScan",
    "/ground_truth": "nav_msgs/msg/Odometry",
    "/ground_truth/map": "nav_msgs/msg/OccupancyGrid",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/robotexp/scan": "robotexp_msgs/msg/ExactScan",
    "/robotexp/markers": "visualization_msgs/msg/MarkerArray",
}
# a team recording's topics: each robot's under its namespace, /robot_1 ... (`robotexp.bag.recorder`), for
# as many robots as a team has at most (`robotexp.sim.team.MAX_TEAM`, not imported: it brings the simulator)
MAX_ROBOTS = 64
ROBOT_TOPICS = ("/odom", "/scan", "/ground_truth", "/tf_static", "/robotexp/scan")
TEAM_TOPIC_TYPES = {f"/robot_{i}{topic}": TOPIC_TYPES[topic]
                    for i in range(1, MAX_ROBOTS + 1) for topic in ROBOT_TOPICS}
_MAPS = {"/ground_truth/map"}

_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK, _OP_METADATA, _OP_FOOTER = 0x03, 0x04, 0x05, 0x06, 0x0C, 0x02
_OP_DATA_END = 0x0F     # the data section ends: what follows (the summary, its indexes) one pass does not need
_MAGIC = b"\x89MCAP0\r\n"


@dataclass
class Record:
    """A decoded message (`topic`, `time` [ns], `msg`) or a metadata record (`topic` None, `name`,
    `metadata`)."""

    topic: str | None
    time: int = 0
    msg: Any = None
    name: str = ""
    metadata: dict[str, str] | None = None


def finite(value: Any, what: str, limit: float = math.inf) -> float:
    """`value` as a float, refused (ValueError with `what`) unless finite and within +-`limit`."""
    v = float(value)
    if not (math.isfinite(v) and abs(v) <= limit):
        raise ValueError(f"{what} is {v:g}, expected a finite number" + ("" if limit == math.inf else
                                                                           f" within +-{limit:g}"))
    return v


class _Bytes:
    """A cursor over bytes with the reads MCAP records need (refusing reads past the end)."""

    def __init__(self, data: bytes | memoryview) -> None:
        self.data, self.pos = memoryview(data), 0

    def left(self) -> int:
        return len(self.data) - self.pos

    def take(self, n: int) -> memoryview:
        if n < 0 or n > self.left():
            raise ValueError(f"a record runs past its end ({n} bytes wanted, {self.left()} left)")
        out = self.data[self.pos:self.pos + n]
        self.pos += n
        return out

    def u16(self) -> int:
        return int(struct.unpack("<H", self.take(2))[0])

    def u32(self) -> int:
        return int(struct.unpack("<I", self.take(4))[0])

    def u64(self) -> int:
        return int(struct.unpack("<Q", self.take(8))[0])

    def string(self) -> str:
        return bytes(self.take(self.u32())).decode("utf-8")

    def bytes32(self) -> bytes:
        return bytes(self.take(self.u32()))

    def string_map(self) -> dict[str, str]:
        body = _Bytes(self.take(self.u32()))
        out: dict[str, str] = {}
        while body.left():
            key = body.string()
            out[key] = body.string()
        return out


def _read_exact(f: IO[bytes], n: int) -> bytes:
    data = f.read(n)
    if len(data) != n:
        raise ValueError(f"the file ends inside a record ({len(data)} of {n} bytes)")
    return data


def _size(f: IO[bytes]) -> int:
    """The size of the open file `f` [bytes]."""
    try:
        return os.fstat(f.fileno()).st_size
    except (OSError, io.UnsupportedOperation, AttributeError):    # not a file on disk (a stream in memory)
        at = f.tell()
        end = f.seek(0, io.SEEK_END)
        f.seek(at)
        return end


def _decompress(compression: str, data: memoryview, size: int) -> bytes:
    """A chunk's records, decompressed to exactly `size` bytes (never more than MAX_CHUNK_BYTES read)."""
    if size > MAX_CHUNK_BYTES:
        raise ValueError(f"a chunk of {size} bytes decompressed (limit {MAX_CHUNK_BYTES} bytes)")
    try:
        if compression == "":
            out = bytes(data)
        elif compression == "zstd":
            import zstandard

            with zstandard.ZstdDecompressor().stream_reader(io.BytesIO(data)) as reader:
                out = reader.read(size + 1)
        elif compression == "lz4":
            import lz4.frame  # type: ignore[import-untyped]

            out = lz4.frame.LZ4FrameDecompressor().decompress(bytes(data), max_length=size + 1)
        else:
            raise ValueError(f"chunk compression {compression!r} is not supported (zstd, lz4 or none)")
    except (ValueError, MemoryError):
        raise
    except Exception as exc:        # zstandard.ZstdError, lz4's RuntimeError: a damaged chunk
        raise ValueError(f"a {compression} chunk does not decompress ({exc})") from None
    if len(out) != size:
        raise ValueError(f"a chunk decompresses to {'more than ' if len(out) > size else ''}{min(len(out), size + 1)}"
                         f" bytes, not the {size} its header says")
    return out


class _Reader:
    """One pass over the records of a file (see the module's docstring)."""

    def __init__(self, wanted: dict[str, str]) -> None:
        from mcap_ros2.decoder import DecoderFactory

        self.wanted = wanted
        self.schemas: dict[int, tuple[str, str, bytes]] = {}
        self.channels: dict[int, tuple[str, str, int]] = {}
        self.decoders: dict[int, Callable[[bytes], Any]] = {}
        self.counts: dict[int, int] = {}     # messages decoded, per channel
        self.factory = DecoderFactory()
        self.total = 0
        self.cut_at: int | None = None      # where the file ends inside a record or without its footer

    def records(self, f: IO[bytes]) -> Iterator[Record]:
        if _read_exact(f, 8) != _MAGIC:
            raise ValueError("no MCAP magic at its start")
        file_size = _size(f)
        while True:
            at = f.tell()
            head = f.read(9)
            if len(head) < 9:
                self.cut_at = at    # a file cut short (a run that was killed) ends after its last whole record
                return
            op, length = head[0], int.from_bytes(head[1:], "little")
            if op in (_OP_FOOTER, _OP_DATA_END):
                return
            if op not in (_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK, _OP_METADATA):
                if length > file_size - f.tell():   # a record said to run past the end (or a length damaged)
                    self.cut_at = at
                    return
                f.seek(length, io.SEEK_CUR)
                continue
            if length > MAX_RECORD_BYTES:
                raise ValueError(f"a record of {length} bytes (limit {MAX_RECORD_BYTES} bytes)")
            data = f.read(length)
            if len(data) < length:
                self.cut_at = at
                return
            body = _Bytes(data)
            if op == _OP_CHUNK:
                body.take(16)                       # message start and end times
                size = body.u64()
                crc = body.u32()                    # of the records once decompressed; 0: not computed
                compression = body.string()
                n = body.u64()
                records = _decompress(compression, body.take(n), size)
                if crc and zlib.crc32(records) != crc:
                    raise ValueError(f"the chunk at byte {at} fails its checksum (CRC-32 {zlib.crc32(records):#010x}, "
                                     f"stored {crc:#010x}): the file is damaged")
                inner = _Bytes(records)
                while inner.left():
                    if inner.left() < 9:
                        raise ValueError("a chunk ends inside a record")
                    iop = inner.take(1)[0]
                    ilen = inner.u64()
                    rec = self._record(iop, _Bytes(inner.take(ilen)), ilen)
                    if rec is not None:
                        yield rec
            else:
                rec = self._record(op, body, length)
                if rec is not None:
                    yield rec

    def _record(self, op: int, body: _Bytes, length: int) -> Record | None:
        if op == _OP_SCHEMA:
            sid = body.u16()
            name = body.string()
            encoding = body.string()
            self.schemas[sid] = (name, encoding, body.bytes32())
        elif op == _OP_CHANNEL:
            cid = body.u16()
            sid = body.u16()
            topic = body.string()
            encoding = body.string()
            self.channels[cid] = (topic, encoding, sid)
        elif op == _OP_METADATA:
            name = body.string()
            return Record(None, name=name, metadata=body.string_map())
        elif op == _OP_MESSAGE:
            cid = body.u16()
            body.take(4)                            # sequence
            t = body.u64()
            body.take(8)                            # publish time
            channel = self.channels.get(cid)
            if channel is None or channel[0] not in self.wanted:
                return None
            topic = channel[0]
            size = body.left()
            limit = MAX_MAP_BYTES if topic in _MAPS else MAX_MESSAGE_BYTES
            if size > limit:
                raise ValueError(f"a {topic} message of {size} bytes (limit {limit} bytes)")
            self.total += size
            if self.total > MAX_READ_BYTES:
                raise ValueError(f"its messages hold more than {MAX_READ_BYTES} bytes (the limit of a replay)")
            decode = self._decoder(cid, channel)
            try:
                msg = decode(bytes(body.take(size)))
            except decode_errors():         # the schema parsed, but a message does not fit it (or it names types
                # it never defines): the parser's own words say little here
                name = self.schemas[channel[2]][0]
                raise ValueError(f"{topic}: its message {self.counts.get(cid, 0) + 1} does not decode as its {name} "
                                 "schema says: the message or the schema is damaged") from None
            self.counts[cid] = self.counts.get(cid, 0) + 1
            return Record(topic, t, msg)
        return None

    def _decoder(self, cid: int, channel: tuple[str, str, int]) -> Callable[[bytes], Any]:
        decoder = self.decoders.get(cid)
        if decoder is not None:
            return decoder
        topic, encoding, sid = channel
        schema = self.schemas.get(sid)
        want = self.wanted[topic]
        if schema is None:
            raise ValueError(f"{topic} has no schema (expected {want})")
        name, schema_encoding, text = schema
        if name.replace("/msg/", "/") != want.replace("/msg/", "/"):
            raise ValueError(f"{topic} is a {name or 'message without a type'}, expected {want}")
        if encoding != "cdr" or schema_encoding != "ros2msg":
            raise ValueError(f"{topic} is encoded as {encoding!r} with a {schema_encoding!r} schema, expected "
                             "'cdr' with 'ros2msg'")
        from mcap.records import Schema

        try:
            # the schema parser prints what it refuses; a Ctrl-C meanwhile acts once sys.stderr is back (held)
            with held(), contextlib.redirect_stderr(io.StringIO()):
                made = self.factory.decoder_for(encoding, Schema(id=sid, name=name, encoding=schema_encoding,
                                                                 data=text))
        except Exception as exc:        # the vendored rosidl parser raises several kinds of its own
            raise ValueError(f"{topic}: its {name} schema does not parse ({exc})") from None
        if made is None:
            raise ValueError(f"{topic}: no decoder for {encoding!r}")
        decoder = self.decoders[cid] = made
        return decoder


def read_records(f: IO[bytes], wanted: dict[str, str] | None = None,
                 cut: list[int] | None = None) -> Iterator[Record]:
    """The metadata records and the decoded messages of the topics in `wanted` (topic -> type, default
    TOPIC_TYPES and a team's TEAM_TOPIC_TYPES) of an open MCAP file, in file order. A file cut short (no
    footer, or its end inside a record) ends after its last whole record; `cut`, when given, then gets the byte
    where its whole records end.

    Raises:
        ValueError: a record, chunk or message over its limit, a chunk failing its checksum, a message of the
            wrong type or one that does not decode, a malformed record (the message says which).
    """
    reader = _Reader(TOPIC_TYPES | TEAM_TOPIC_TYPES if wanted is None else wanted)
    for rec in reader.records(f):
        yield rec
    if cut is not None and reader.cut_at is not None:
        cut.append(reader.cut_at)


def decode_errors() -> tuple[type[BaseException], ...]:
    """What decoding a malformed record can raise (turned into ConfigError by the caller)."""
    from mcap.exceptions import McapError

    return (McapError, ValueError, struct.error, IndexError, KeyError, TypeError, AttributeError, RuntimeError,
            UnicodeDecodeError, OverflowError, RecursionError, EOFError)


def refuse(path: Any, exc: BaseException) -> ConfigError:
    """The one-line error for a recording that cannot be read."""
    what = str(exc) or type(exc).__name__
    return ConfigError(f"{path}: not a readable MCAP recording: {what}")
