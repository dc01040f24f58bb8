"""A full disk (a file-size limit, RLIMIT_FSIZE, with SIGXFSZ ignored: writes fail with EFBIG as they
would with ENOSPC) ends `robotexp explore` with one line that says whether the run's record was
written, and no observer traceback before it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

# the same run once without the limit first, into another folder: numba's cache files are written
# then (a fresh checkout compiles the kernels, and a cache file over the limit would end the run early)
_RUN = """
import contextlib, io, resource, signal, sys
from robotexp.cli import main
args = sys.argv[1:]
with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
    main(args[:-1] + [args[-1] + ".warm"], standalone_mode=False)
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, ({limit}, {limit}))
sys.argv = ["robotexp"] + args
main()
"""


@pytest.mark.parametrize("limit, says, records", [
    (300, "was not written to", 0),                     # the record itself does not fit
    (20000, "is in", 1),                                # the record fits, the map image does not
])
def test_disk_full_is_one_honest_line(limit: int, says: str, records: int, tmp_path: Path) -> None:
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-c", _RUN.format(limit=limit), "explore", "-w", "ufmg-static",
                           "--max-time", "1", "-o", str(out)], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    lines = [x for x in done.stderr.splitlines() if x.strip() and not x.startswith("robotexp: start ")]
    assert done.returncode == 1, done.stderr[-2000:]
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr[-2000:]
    assert lines[0].startswith("robotexp: error: File too large: the record of run ") and says in lines[0], lines
    text = (out / "results.jsonl").read_text()
    assert text.endswith("\n") or not text                           # never half a record
    assert len([json.loads(x) for x in text.splitlines()]) == records
