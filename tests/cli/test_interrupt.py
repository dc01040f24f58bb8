"""Ctrl-C during `robotexp explore`: exit status 130, and the partial run is written first."""

from __future__ import annotations

import json
import os
import pty
import re
import select
import signal
import subprocess
import sys
import time
from pathlib import Path


def _default_sigint() -> None:
    """In the child: SIGINT back to its default (see the test)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


MOVED_S = 20.0       # [s] robot time after which the robot has surely left its start
DEADLINE_S = 60.0    # [s] wall time bound of the whole test


def test_sigint_writes_partial_result_and_exits_130(tmp_path: Path) -> None:
    out = tmp_path / "out"
    # stderr on a pseudo-terminal turns on the progress line, which tells the robot time
    master, slave = pty.openpty()
    # 40 mm/s: about 20 s of wall time, so the signal always lands inside the run
    # preexec_fn: a Ctrl-C from a terminal; when these tests run in the background (SIGINT ignored, which
    # children inherit) Python would install no KeyboardInterrupt handler and the signal would do nothing
    proc = subprocess.Popen([sys.executable, "-m", "robotexp.cli", "explore", "--world", "dense", "--speed", "40",
                             "--out", str(out)],
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=slave, text=True,
                            preexec_fn=_default_sigint)
    os.close(slave)
    deadline = time.monotonic() + DEADLINE_S
    shown = b""
    robot_time = 0.0
    sent = False
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 0.1)
            if ready:
                try:
                    chunk = os.read(master, 4096)
                except OSError:          # EIO: the child closed the terminal
                    chunk = b""
                if not chunk:
                    break
                shown += chunk
                times = re.findall(rb"robot time\s+(\d+) s", shown[-400:])
                if times:
                    robot_time = float(times[-1])
            if not sent and robot_time >= MOVED_S:
                proc.send_signal(signal.SIGINT)
                sent = True
            if proc.poll() is not None and not ready:
                break
        assert sent, f"the robot never reached {MOVED_S} s of robot time: {shown[-300:]!r}"
        stdout, _ = proc.communicate(timeout=max(1.0, deadline - time.monotonic()))
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(master)
    assert proc.returncode == 130, (stdout, shown[-500:])
    assert b"Traceback" not in shown
    records = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert len(records) == 1
    r = records[0]
    assert r["completed"] is False
    assert "interrupted" in r["reason"]
    assert r["world"] == "dense"
    assert r["robot_time_s"] >= MOVED_S and r["path_length_m"] > 0.3        # ~0.6 m in 20 s at 40 mm/s
    assert 0.0 < r["coverage"] < 1.0
    image = out / f"{r['run']}.png"
    assert image.is_file() and image.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / f"{r['run']}.coverage.csv").is_file()
    assert "interrupted" in stdout
