"""A recording cannot make a replay allocate beyond its limits: a zstd chunk of zeros that claims (or
hides) 768 MB decompressed, or a message past the message limit, is refused with one line before it
is decompressed or decoded. The commands run in a subprocess under a 1 GB address-space limit, so
reading the bomb whole would fail with MemoryError there."""

from __future__ import annotations

import struct
import subprocess
import sys
from pathlib import Path

import pytest
import zstandard

from robotexp.bag.reading import MAX_CHUNK_BYTES, MAX_MESSAGE_BYTES
from robotexp.bag.schemas import ODOMETRY

BOMB = 768 * 2**20              # [bytes] of zeros in the bomb's one message
LIMIT_AS = 2**30                # [bytes] the replay's address space

_RUN = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, ({limit}, {limit}))
from robotexp.cli import main
sys.argv = ["robotexp"] + sys.argv[1:]
main()
"""


def _record(op: int, body: bytes) -> bytes:
    return bytes([op]) + struct.pack("<Q", len(body)) + body


def _str(s: str) -> bytes:
    b = s.encode()
    return struct.pack("<I", len(b)) + b


def _zeros_zstd(n: int) -> bytes:
    """zstd of a /odom message record with `n` zero bytes of data (no content size in the frame)."""
    c = zstandard.ZstdCompressor(level=1).compressobj()
    head = _record(0x05, b"")[:1] + struct.pack("<Q", 22 + n) + struct.pack("<HIQQ", 1, 0, 1, 1)
    parts = [c.compress(head)]
    block = bytes(1 << 22)
    left = n
    while left:
        k = min(left, len(block))
        parts.append(c.compress(block[:k]))
        left -= k
    parts.append(c.flush())
    return b"".join(parts), len(head) + n


def _bomb(path: Path, n: int, claimed: int | None = None, damage: bool = False) -> Path:
    """An MCAP file: header, the /odom schema and channel, one zstd chunk holding a message of `n` zero
    bytes whose header claims `claimed` bytes decompressed (None: the truth), footer; `damage`: the
    compressed data's middle overwritten."""
    data, size = _zeros_zstd(n)
    if damage:
        data = data[:len(data) // 2] + b"\xff" * 64 + data[len(data) // 2 + 64:]
    name, text = ODOMETRY
    chunk = struct.pack("<QQQI", 1, 1, size if claimed is None else claimed, 0) + _str("zstd") + \
        struct.pack("<Q", len(data)) + data
    out = b"\x89MCAP0\r\n" + _record(0x01, _str("ros2") + _str("robotexp")) + \
        _record(0x03, struct.pack("<H", 1) + _str(name) + _str("ros2msg") + _str(text)) + \
        _record(0x04, struct.pack("<HH", 1, 1) + _str("/odom") + _str("cdr") + struct.pack("<I", 0)) + \
        _record(0x06, chunk) + _record(0x0F, struct.pack("<I", 0)) + \
        _record(0x02, struct.pack("<QQI", 0, 0, 0)) + b"\x89MCAP0\r\n"
    path.write_bytes(out)
    assert path.stat().st_size < 100_000
    return path


@pytest.fixture(scope="module")
def bombs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    tmp = tmp_path_factory.mktemp("bombs")
    return {"honest": _bomb(tmp / "honest.mcap", BOMB), "lying": _bomb(tmp / "lying.mcap", BOMB, 1000),
            "message": _bomb(tmp / "message.mcap", MAX_MESSAGE_BYTES + 1000),
            "damaged": _bomb(tmp / "damaged.mcap", 4 * 2**20, damage=True)}


@pytest.mark.parametrize("kind, says, command", [("honest", f"limit {MAX_CHUNK_BYTES} bytes", "replay"),
                                                 ("honest", f"limit {MAX_CHUNK_BYTES} bytes", "figure"),
                                                 ("lying", "not the 1000 its header says", "replay"),
                                                 ("message", f"limit {MAX_MESSAGE_BYTES} bytes", "video"),
                                                 ("damaged", "a zstd chunk does not decompress", "replay")])
def test_bomb_refused_in_bounded_memory(bombs: dict[str, Path], kind: str, says: str, command: str,
                                        tmp_path: Path) -> None:
    bag = bombs[kind]
    out = tmp_path / ("out.gif" if command == "video" else "out")
    done = subprocess.run([sys.executable, "-c", _RUN.format(limit=LIMIT_AS), command, str(bag), "-o", str(out)],
                          capture_output=True, text=True, timeout=60,
                          env={"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"})
    lines = [x for x in done.stderr.splitlines() if x.strip()]
    assert done.returncode == 2, done.stderr[-2000:]
    assert len(lines) == 1 and str(bag) in lines[0] and says in lines[0], done.stderr


def test_messages_together_are_bounded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Many small messages that each pass are refused together past MAX_READ_BYTES (tiny here)."""
    import crafted_bags

    from robotexp.bag import reading
    from robotexp.bag.replay import read_bag
    from robotexp.errors import ConfigError

    bag = crafted_bags.write(tmp_path / "long.mcap", ticks=20)
    assert len(read_bag(bag).ticks) == 20
    monkeypatch.setattr(reading, "MAX_READ_BYTES", 20_000)
    with pytest.raises(ConfigError, match="more than 20000 bytes"):
        read_bag(bag)
