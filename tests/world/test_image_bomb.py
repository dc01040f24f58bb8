"""A map image is refused from its header when it has more pixels than a map may have cells: a
greyscale PNG of 9400 x 9400 pixels (250 kB; 88 MB a copy once decoded) is never decoded: the
process stays under 200 MB resident (decoding and classifying it took 400 MB) and 512 MB of
address space."""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

SIDE = 9400

_RUN = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (2**29, 2**29))
from robotexp.errors import WorldError
from robotexp.world.rosmap import load_ros_grid
try:
    load_ros_grid(sys.argv[1])
except WorldError as exc:
    print(exc)
    # [kB] this process's peak resident memory (VmHWM: ru_maxrss would count the parent's before exec)
    print(open("/proc/self/status").read().split("VmHWM:")[1].split()[0])
    sys.exit(2)
"""


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def _png_bomb(path: Path) -> None:
    """A greyscale PNG of SIDE x SIDE zero pixels, compressed row by row (never whole in memory)."""
    z = zlib.compressobj(9)
    row = bytes(1 + SIDE)                       # filter byte 0, then the row's pixels
    idat = b"".join(z.compress(row) for _ in range(SIDE)) + z.flush()
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", struct.pack(">IIBBBBB", SIDE, SIDE, 8, 0, 0, 0, 0))
                     + _chunk(b"IDAT", idat) + _chunk(b"IEND", b""))


def test_png_bomb_refused_before_decoding(tmp_path: Path) -> None:
    _png_bomb(tmp_path / "bomb.png")
    assert (tmp_path / "bomb.png").stat().st_size < 400_000
    yaml = tmp_path / "bomb.yaml"
    yaml.write_text("image: bomb.png\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
                    "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    done = subprocess.run([sys.executable, "-c", _RUN, str(yaml)], capture_output=True, text=True, timeout=60,
                          env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    assert done.returncode == 2, done.stderr[-2000:]
    assert int(done.stdout.split()[-1]) < 200_000, done.stdout
    assert f"is {SIDE} x {SIDE} pixels, more than the 2.5e+07 cells a map may have" in done.stdout, done.stdout
