"""A torn tail of a results file is moved aside and a results file is read in bounded memory: a
96 MB last line (a sparse file: no disk for it) under a 64 MB address-space limit."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

TAIL = 96 * 2**20           # [bytes] the torn last line
LIMIT_AS = 64 * 2**20       # [bytes] the process's address space

_RUN = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, ({limit}, {limit}))
from pathlib import Path
from robotexp.output.safefile import append_line, read_records
path = Path(sys.argv[2])
if sys.argv[1] == "read":
    print(len(read_records(path, note=lambda text: print("note:", text))))
else:
    append_line(path, {{"run": "b"}}, note=lambda text: print("note:", text))
"""


def _file(tmp_path: Path) -> Path:
    path = tmp_path / "results.jsonl"
    path.write_bytes(json.dumps({"run": "a"}).encode() + b"\n")
    with open(path, "r+b") as f:
        f.truncate(path.stat().st_size + TAIL)        # a hole of zeros: a torn line of TAIL bytes
    return path


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", _RUN.format(limit=LIMIT_AS), *args], capture_output=True,
                          text=True, timeout=60, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})


def test_huge_torn_line_is_read_past(tmp_path: Path) -> None:
    path = _file(tmp_path)
    done = _run("read", str(path))
    assert done.returncode == 0, done.stderr[-1500:]
    assert done.stdout.splitlines() == [f"note: {path}:2: line of {TAIL} bytes skipped (a record is at most "
                                        f"{16 * 2**20} bytes)", "1"]


def test_huge_torn_tail_is_moved_aside_in_blocks(tmp_path: Path) -> None:
    path = _file(tmp_path)
    done = _run("append", str(path))
    assert done.returncode == 0, done.stderr[-1500:]
    assert f"a torn last line ({TAIL} bytes" in done.stdout
    lines = path.read_bytes().splitlines()
    assert [json.loads(x)["run"] for x in lines] == ["a", "b"]
    torn = Path(f"{path}.torn")
    assert torn.stat().st_size == TAIL + 1
    torn.unlink()
