"""The laser parts of the command line: `robotexp emulate LASER` and `emulate ROBOT --laser LASER`
(processes serving on pseudo-terminals, printing `robot:` / `laser:` lines), `explore` and `connect`
with `--laser NAME:ADDRESS --laser-pose X,Y,THETA` against them, and bad input as one line, exit 2."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from click.testing import CliRunner

from robotexp.cli import main
from robotexp_drivers.lasers.rplidar import RPLidarLaser

CLI = [sys.executable, "-m", "robotexp.cli"]


@contextmanager
def _serving(*argv: str, lines: int) -> Iterator[dict[str, str]]:
    """Run `robotexp emulate ARGV` and yield its first `lines` "label: address" lines; Ctrl-C at the end."""
    with subprocess.Popen(CLI + ["emulate", *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                          text=True) as proc:
        try:
            assert proc.stdout is not None
            out = {}
            for _ in range(lines):
                label, _, address = proc.stdout.readline().strip().partition(": ")
                out[label] = address
            yield out
        finally:
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err


def test_emulate_a_laser_alone_on_a_pty() -> None:
    with _serving("rplidar", "--world", "ufmg-static", "--pose", "path1", "--pty", lines=1) as served:
        assert served["laser"].startswith("/dev/")
        with RPLidarLaser(served["laser"]) as laser:
            scan = laser.wait_scan(-1, 10.0).scan
            assert scan.ranges.shape == (360,) and 0.1 < scan.nearest() < 5.0


def test_explore_a_kobuki_with_an_rplidar_from_the_command_line(tmp_path: Path) -> None:
    # speed-up 5, not 10: the emulator process casts an RPLidar's 360 beams ten times a second of robot time,
    # and on a loaded machine at 10x it once fell silent for over a second (the Kobuki link's timeout)
    with _serving("kobuki", "--world", "ufmg-static", "--pose", "path1", "--pty", "--speedup", "5", "--laser",
                  "rplidar", lines=2) as served:
        assert served["robot"].startswith("/dev/") and served["laser"].startswith("/dev/")
        result = CliRunner().invoke(main, [
            "explore", "--robot", "kobuki", "--address", served["robot"], "--laser", f"rplidar:{served['laser']}",
            "--laser-pose", "0,0,0", "--world", "ufmg-static", "--pose", "path1", "--max-time", "15",
            "--out", str(tmp_path)])
        assert result.exit_code == 0, result.output
        record = json.loads((tmp_path / "results.jsonl").read_text().splitlines()[-1])
        assert record["robot"] == "kobuki" and record["coverage"] > 0.1
        result = CliRunner().invoke(main, ["connect", "kobuki", served["robot"], "--laser",
                                           f"rplidar:{served['laser']}", "--for", "0.3"])
        assert result.exit_code == 0, result.output
        assert "laser: rplidar at /dev/" in result.output and "A1 series" in result.output


@pytest.mark.parametrize("argv, message", [
    (["explore", "--laser", "rplidar:/dev/null"], "--laser and --laser-pose attach a laser to a robot at --address"),
    (["explore", "--address", "/dev/null", "--robot", "kobuki", "--laser", "rplidar"], "NAME:ADDRESS"),
    (["explore", "--address", "/dev/null", "--robot", "kobuki", "--laser", "rplidar:/dev/null",
      "--laser-pose", "1,2"], "X,Y,THETA"),
    (["connect", "kobuki", "/dev/null", "--laser-pose", "1,2,3"], "--laser-pose needs --laser"),
    (["emulate", "kobuki", "--laser", "nope"], "no such laser emulator"),
    (["emulate", "rplidar", "--laser", "hokuyo"], "is a laser"),
])
def test_bad_laser_options_are_one_line(argv: list[str], message: str) -> None:
    result = CliRunner().invoke(main, argv)
    assert result.exit_code == 2 and message in result.output and "Traceback" not in result.output
