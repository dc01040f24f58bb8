"""Campaigns on Dask when the cluster fails: a scheduler killed mid-campaign, an address that is not
one, a port where nothing listens. One line each, the records kept, never a traceback."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from robotexp.cli import main
from dask_ports import free_port, wait_port


# runs of a few seconds each: the first comes back while the others are still running
SHORT = """
[campaign]
name = "short"
max_time_s = 60
[[set]]
world = "generated:office:0"
methods = ["frontier"]
speeds_mm_s = [300]
seeds = [0, 1, 2, 3, 4, 5]
"""

SCHEDULER = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
WORKER = [sys.executable, "-m", "distributed.cli.dask_worker"]
ROBOTEXP = [sys.executable, "-m", "robotexp.cli"]


def _records(path: Path) -> list[dict[str, Any]]:
    return [json.loads(x) for x in path.read_text().splitlines()] if path.exists() else []


def test_scheduler_killed_mid_campaign_is_one_line_and_the_records_stay(tmp_path: Path, cpu_wait: Any) -> None:
    camp_file, out = tmp_path / "short.toml", tmp_path / "out"
    camp_file.write_text(SHORT, encoding="utf-8")
    port = free_port()
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}
    address = f"tcp://127.0.0.1:{port}"
    procs: list[subprocess.Popen[bytes]] = []
    try:
        scheduler = subprocess.Popen([*SCHEDULER, "--host", "127.0.0.1", "--port", str(port),
                                      "--no-dashboard"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        procs.append(scheduler)
        procs.append(subprocess.Popen([*WORKER, address, "--nthreads", "1", "--no-nanny",
                                       "--no-dashboard", "--host", "127.0.0.1"], env=env,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        wait_port(port, 30)
        campaign = subprocess.Popen([*ROBOTEXP, "campaign", "run", str(camp_file), "--out", str(out),
                                     "--cluster", address], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        procs.append(campaign)
        end = time.monotonic() + 90
        while not _records(out / "results.jsonl") and time.monotonic() < end and campaign.poll() is None:
            time.sleep(0.05)
        written = _records(out / "results.jsonl")
        assert written and campaign.poll() is None, "no run came back"
        scheduler.send_signal(signal.SIGKILL)
        t0, mark = time.monotonic(), cpu_wait.total()
        _, stderr = campaign.communicate(timeout=60)
        took, waited = time.monotonic() - t0, cpu_wait.since(mark)
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
    assert campaign.returncode == 1 and "Traceback" not in stderr, stderr[-3000:]
    assert took < 5 + 5 + waited, (took, waited)    # the client waits 5 s for the scheduler to come back
    kept = _records(out / "results.jsonl")
    assert len(kept) >= len(written) and len(kept) < 6
    (line,) = [x for x in stderr.splitlines() if x.startswith("robotexp: error:")]
    assert f"--cluster {address}: the Dask scheduler went away mid-campaign" in line
    assert f"the {len(kept)} run(s) written are kept in {out / 'results.jsonl'}" in line
    assert "--resume" in line


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:99999", "tcp://[::1", "tcp://[zz::1]:8786", "tcp://:8786",
                                     "tcp://127.0.0.1:0"])
def test_an_impossible_address_is_one_line_at_once(tmp_path: Path, address: str, cpu_wait: Any) -> None:
    camp_file = tmp_path / "short.toml"
    camp_file.write_text(SHORT, encoding="utf-8")
    t0, mark = time.monotonic(), cpu_wait.total()
    result = CliRunner().invoke(main, ["campaign", "run", str(camp_file), "--out", str(tmp_path / "out"),
                                       "--cluster", address])
    assert result.exit_code == 2 and time.monotonic() - t0 < 2 + cpu_wait.since(mark), result.output
    assert result.output.startswith(f"robotexp: error: --cluster {address!r}: expected a Dask scheduler address")
    assert result.output.count("\n") == 1 and not (tmp_path / "out" / "results.jsonl").exists()


def test_a_refused_connection_fails_fast(tmp_path: Path, cpu_wait: Any) -> None:
    camp_file = tmp_path / "short.toml"
    camp_file.write_text(SHORT, encoding="utf-8")
    address = f"tcp://127.0.0.1:{free_port()}"       # nothing listens there
    t0, mark = time.monotonic(), cpu_wait.total()
    result = CliRunner().invoke(main, ["campaign", "run", str(camp_file), "--out", str(tmp_path / "out"),
                                       "--cluster", address])
    assert result.exit_code == 2 and time.monotonic() - t0 < 3 + cpu_wait.since(mark), result.output
    (line,) = [x for x in result.output.splitlines() if x.startswith("robotexp:")]
    assert line == (f"robotexp: error: --cluster {address}: no Dask scheduler answers there (Connection refused "
                    "within 3 s); start one with `dask scheduler` and workers with `dask worker ADDRESS`")
