"""Speeds the view takes are 0.01x..1000x or max (the CLI refuses others in one line, exit 2; the page's
command is refused); the pacing waits on what Stop, resume and a speed change wake; and a run whose view port
is flooded with idle connections still ends and writes its record."""

from __future__ import annotations

import re
import resource
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.errors import ConfigError
from robotexp.experiment import RunOutput, run_experiment
from robotexp.run.spec import RunSpec
from robotexp.run.record import EndReason
from robotexp.output.results import read_records
from robotexp.view.feed import ViewHub
from robotexp.view.live import parse_speed
from robotexp.view.observer import STOP_REASON, Pacer, ViewObserver


@pytest.mark.untimed
def test_view_speed_out_of_range_is_one_line_exit_2(tmp_path: Path) -> None:
    for text in ("1e-6", "1e-300", "0.009", "1001", "1e308", "0", "-1", "nan", "inf", "fast", ""):
        with pytest.raises(ConfigError, match=r"0\.01.*1000.*max"):
            parse_speed(text)
    for text in ("1e-6", "1e-300"):
        res = CliRunner().invoke(main, ["explore", "--view", "--view-speed", text, "--max-time", "1",
                                        "-o", str(tmp_path / "out")])
        assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1, res.output
        assert "--view-speed" in res.output and not (tmp_path / "out").exists()


def test_speed_bounds_are_taken() -> None:
    assert parse_speed("0.01") == 0.01 and parse_speed("1000") == 1000 and parse_speed("MAX") is None
    pacer = Pacer(10.0)
    for bad in (1e-6, 1e-300, 1e9, 0.0):
        with pytest.raises(ValueError):
            pacer.set_speed(bad)
    assert pacer.speed == 10.0
    hub = ViewHub()
    observer = ViewObserver(hub, speed=10.0)
    observer.command({"cmd": "speed", "value": 1e-300})
    observer.command({"cmd": "speed", "value": "1e-6"})
    assert observer.pacer.speed == 10.0 and hub.status["speed"] == 10.0


def _run_in_thread(spec: RunSpec, observer: ViewObserver, out: Path) -> tuple[threading.Thread, list[RunOutput]]:
    result: list[RunOutput] = []
    thread = threading.Thread(target=lambda: result.append(run_experiment(spec, out, observers=[observer],
                                                                          image=False)), daemon=True)
    thread.start()
    return thread, result


def _wait(pred: Any, timeout: float = 30.0) -> None:
    end = time.monotonic() + timeout
    while not pred():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.01)


def test_slowest_speed_then_stop_ends_at_once(tmp_path: Path) -> None:
    """At 0.01x a 0.1 s tick is 10 s of wall time; a faster speed and then Stop end the wait at once."""
    hub = ViewHub()
    observer = ViewObserver(hub, speed=10.0)
    thread, result = _run_in_thread(RunSpec(world="ufmg-static", method="frontier", max_time=600.0), observer,
                                    tmp_path)
    _wait(lambda: hub.time > 0.5)
    observer.command({"cmd": "speed", "value": 1e-6})          # refused
    observer.command({"cmd": "speed", "value": 0.01})
    time.sleep(0.5)
    held = hub.time
    observer.command({"cmd": "speed", "value": 100})            # wakes the wait: the run goes on
    _wait(lambda: hub.time > held + 1.0, timeout=5.0)
    observer.command({"cmd": "speed", "value": 0.01})
    time.sleep(0.5)
    t0 = time.monotonic()
    observer.command({"cmd": "stop"})
    thread.join(10)
    assert not thread.is_alive() and time.monotonic() - t0 < 2.0
    record = result[0].record
    assert record.end is EndReason.STOPPED and record.reason == STOP_REASON
    assert [r.run for r in read_records(tmp_path / "results.jsonl")] == [record.run]


CHILD = """import resource, sys
resource.setrlimit(resource.RLIMIT_NOFILE, (80, 80))
from robotexp.cli import main
main(sys.argv[1:])
"""


def test_idle_connections_never_cost_the_record(tmp_path: Path) -> None:
    """300 idle connections to the view port of a run whose process may open 80 files (the run alone keeps
    about a dozen open, the view at most its 32 connections and the few it is closing): the view holds a few
    of them, refuses or closes the rest, and the run ends and writes its record. A server that accepted a
    burst whole before refusing it would hold ~100 descriptors at once."""
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-c", CHILD, "explore", "-w", "ufmg-static", "--max-time", "10",
                             "--view", "--view-speed", "10", "-o", str(out)], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    socks: list[socket.socket] = []
    lines: list[str] = []
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        match = re.fullmatch(r"view: http://127\.0\.0\.1:(\d+)/\n", line)
        assert match, line
        port = int(match.group(1))
        for _ in range(300):
            try:
                socks.append(socket.create_connection(("127.0.0.1", port), timeout=2))
            except OSError:
                pass
        while True:
            line = proc.stdout.readline()
            assert line, "".join(lines)
            lines.append(line)
            if line.startswith("results:"):
                break
        proc.send_signal(signal.SIGINT)
        rest, _ = proc.communicate(timeout=20)
        lines.append(rest)
    finally:
        for s in socks:
            s.close()
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        if proc.stdout is not None:         # a child that ended early leaves its pipe to this test, not the next
            proc.stdout.close()
    text = "".join(lines)
    assert "Traceback" not in text, text
    records = read_records(out / "results.jsonl")
    assert len(records) == 1 and records[0].end is EndReason.TIME_LIMIT, text
    assert (out / f"{records[0].run}.map.yaml").is_file()
    assert resource.getrlimit(resource.RLIMIT_NOFILE)[0] >= 400       # this process could open them all
