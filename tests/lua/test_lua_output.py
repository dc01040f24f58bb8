"""The supervisor relays a script's output in bounded chunks and never hides a failure to write it."""

from __future__ import annotations

import subprocess
import sys

# the supervisor in a process of its own: what it printed goes to a file; its peak memory to stderr
# (VmHWM, its own high-water mark: ru_maxrss would include the test process it was forked from)
SUPERVISOR = """
import re, sys
from pathlib import Path
from robotexp.lua.supervise import supervise
code = supervise([sys.argv[1], "--out", sys.argv[2]], script="s.lua", out=Path(sys.argv[2]), timeout=None)
status = Path("/proc/self/status").read_text()
print("peak", re.search(r"VmHWM:\\s*(\\d+) kB", status).group(1), file=sys.stderr)
sys.exit(code)
"""


def test_output_without_newlines_is_relayed_in_bounded_memory(tmp_path):
    script, printed = tmp_path / "s.lua", tmp_path / "printed.bin"
    script.write_text('local s = ("x"):rep(2^20) .. "y"\nfor i = 1, 200 do io.write(s) end')
    with open(printed, "wb") as stdout:
        proc = subprocess.run([sys.executable, "-c", SUPERVISOR, str(script), str(tmp_path / "out")],
                              stdout=stdout, stderr=subprocess.PIPE, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert printed.stat().st_size == 200 * (2**20 + 1)
    peak_mb = int(proc.stderr.split("peak ")[1]) / 1024
    assert peak_mb < 100, peak_mb         # the old line-by-line relay held the 200 MB "line" (and a copy)


def test_output_that_cannot_be_written_is_an_error(tmp_path):
    script = tmp_path / "s.lua"
    script.write_text('io.write(("x"):rep(2^20)); print("end")')
    with open("/dev/full", "wb") as full:
        proc = subprocess.run([sys.executable, "-m", "robotexp.cli", "run", str(script), "--out", str(tmp_path / "o")],
                              stdout=full, stderr=subprocess.PIPE, text=True, timeout=60)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "robotexp: error: s.lua: the script's output could not be written (No space left on device)" in proc.stderr
