"""Results survive faults: a failed append leaves no half line, a torn line is repaired
before the next append and skipped by readers, one campaign per output folder, workers die with the
campaign, Ctrl-C drops queued runs, --resume never duplicates, run keys are unique."""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from robotexp.campaign.spec import load_campaign
from robotexp.cli import main
from robotexp.campaign.compare import load_results
from robotexp.errors import ConfigError
from robotexp.output.results import read_jsonl, read_records as read_run_records
from robotexp.output.safefile import append_line, folder_lock, read_records
from robotexp.run.loop import TERMINATED_REASON
from robotexp.run.record import record_problem
from procs import alive, children, cmdline, cpu_seconds, importing

REC = {"run": "a", "method": "frontier", "world": "dense", "path_length_m": 1.0}


def _append_in_child(path: Path, record: dict, fsize: int) -> subprocess.CompletedProcess:
    """append_line in a process whose files cannot grow past `fsize` bytes (a full disk, for real)."""
    def limit() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)      # EFBIG instead of a signal
        resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))
    code = ("import json, sys; from pathlib import Path; from robotexp.output.safefile import append_line\n"
            "append_line(Path(sys.argv[1]), json.loads(sys.argv[2]))")
    return subprocess.run([sys.executable, "-c", code, str(path), json.dumps(record)], preexec_fn=limit,
                          capture_output=True, text=True, timeout=60)


def test_a_write_cut_by_a_full_disk_leaves_no_half_line(tmp_path):
    path = tmp_path / "results.jsonl"
    append_line(path, REC)
    before = path.read_bytes()
    big = dict(REC, run="b", pad="x" * 5000)
    done = _append_in_child(path, big, len(before) + 1000)   # room for 1000 bytes of a 5 kB line
    assert done.returncode != 0 and "File too large" in done.stderr
    assert path.read_bytes() == before                      # cut back: no torn line
    append_line(path, dict(REC, run="c"))
    assert [r["run"] for r in read_records(path)] == ["a", "c"]


def test_a_torn_line_is_repaired_before_the_next_append_and_said(tmp_path):
    path = tmp_path / "results.jsonl"
    append_line(path, REC)
    with open(path, "ab") as f:                 # what a killed writer (or an older version) left
        f.write(b'{"run": "torn", "meth')
    notes: list[str] = []
    append_line(path, dict(REC, run="next"), note=notes.append)
    assert [r["run"] for r in read_records(path)] == ["a", "next"]
    assert len(notes) == 1 and "results.jsonl:2: a torn last line (21 bytes" in notes[0]
    assert (tmp_path / "results.jsonl.torn").read_bytes() == b'{"run": "torn", "meth\n'


def test_readers_skip_and_report_torn_lines(tmp_path):
    path = tmp_path / "results.jsonl"
    rec = {"run": "r1", "method": "frontier", "world": "dense", "start_pose": [0, 0, 0], "max_speed_m_s": 0.3,
           "path_length_m": 1.0, "robot_time_s": 1.0, "wall_time_s": 1.0, "coverage": 0.5, "collisions": 0,
           "nodes": None, "visited_cells": 1, "seed": 0, "completed": True, "reason": "done", "map_iou": None}
    path.write_text(json.dumps(rec) + "\n" + '{"run": "r2", "meth{"run": "r3"}\n' + json.dumps(dict(rec, run="r4"))
                    + "\n" + '{"tor')
    notes: list[str] = []
    assert [r["run"] for r in read_records(path, note=notes.append)] == ["r1", "r4"]
    assert [n.split(": ", 1)[0] for n in notes] == [f"{path}:2", f"{path}:4"] and "torn last line" in notes[1]
    result = CliRunner().invoke(main, ["campaign", "report", str(path)])
    assert result.exit_code == 0, result.output
    assert "skipped 2 line(s)" in result.output and "Traceback" not in result.output
    assert len(load_results(path)) == 2


@pytest.mark.parametrize("field,value,words", [("coverage", "x", "coverage is 'x', expected a number"),
                                               ("path_length_m", {"a": 1}, "path_length_m is {'a': 1}, expected a"),
                                               ("world", ["x"], "world is ['x'], expected a string"),
                                               ("completed", "yes", "completed is 'yes', expected a boolean")])
def test_a_record_with_a_field_of_the_wrong_type_is_skipped_and_said_by_every_reader(tmp_path, field, value, words):
    path = tmp_path / "results.jsonl"
    rec = {"run": "r1", "method": "frontier", "world": "dense", "start_pose": [0, 0, 0], "max_speed_m_s": 0.3,
           "path_length_m": 1.0, "robot_time_s": 1.0, "wall_time_s": 1.0, "coverage": 0.5, "collisions": 0,
           "nodes": None, "visited_cells": 1, "seed": 0, "completed": True, "reason": "explored", "map_iou": None}
    lines = [dict(rec, run=f"r{i}", coverage=0.1 * i) for i in range(1, 7)]
    lines[2][field] = value
    path.write_text("".join(json.dumps(r) + "\n" for r in lines))
    notes: list[str] = []
    assert [r["run"] for r in read_records(path, note=notes.append, check=record_problem)] == \
        ["r1", "r2", "r4", "r5", "r6"]
    assert len(notes) == 1 and notes[0].startswith(f"{path}:3: record skipped: {words}")
    assert [r.run for r in read_run_records(path)] == ["r1", "r2", "r4", "r5", "r6"]
    assert len(read_jsonl(path)) == 5
    assert [r.run for r in load_results(path)] == ["r1", "r2", "r4", "r5", "r6"]
    commands = (["figure", str(path), "--format", "png", "-o", str(tmp_path / "fig")],
                ["campaign", "report", str(path)])
    for args in commands:
        result = CliRunner().invoke(main, args)
        assert result.exit_code == 0, result.output
        assert "Traceback" not in result.output and result.output.count(f"{path}:3: record skipped: {words}") == 1
    # nothing usable left: one line per record skipped, then exit 2
    path.write_text("".join(json.dumps(dict(r, **{field: value})) + "\n" for r in lines))
    for args in commands:
        result = CliRunner().invoke(main, args)
        assert result.exit_code == 2 and "no usable record" in result.output, result.output
        assert result.output.count("record skipped") == 6 and "Traceback" not in result.output


MINI = """
[campaign]
name = "mini"
max_time_s = 6
[[set]]
world = "dense"
poses = ["1", "2", "3", "4"]
methods = ["frontier"]
speeds_mm_s = [300]
seeds = [0]
"""


def test_two_campaigns_cannot_share_an_output_folder(tmp_path):
    camp = tmp_path / "c.toml"
    camp.write_text(MINI)
    out = tmp_path / "out"
    with folder_lock(out, "campaign other"):
        result = CliRunner().invoke(main, ["campaign", str(camp), "--out", str(out)])
    assert result.exit_code == 2
    (line,) = [x for x in result.output.splitlines() if x.startswith("robotexp:")]
    assert f"in use by campaign other (pid {os.getpid()})" in line
    assert not (out / "results.jsonl").exists()


@pytest.mark.parametrize(("change", "words"), [
    ("seeds = [0]", ["seeds = [0, 0]", "seed 0"]),
    ("speeds_mm_s = [300]", ["speeds_mm_s = [300, 300.4]", "speeds 300 and 300.4"]),
    ('name = "mini"', ['name = "../../escape"', "not a folder name"]),
])
def test_campaign_keys_and_names_are_checked(tmp_path, change, words):
    path = tmp_path / "c.toml"
    path.write_text(MINI.replace(change, words[0]))
    with pytest.raises(ConfigError, match=words[1].replace(".", r"\.")):
        load_campaign(path)


def test_kill_9_of_the_campaign_kills_its_workers_and_resume_does_not_duplicate(tmp_path):
    camp, out = tmp_path / "c.toml", tmp_path / "out"
    camp.write_text(MINI)
    cmd = [sys.executable, "-m", "robotexp.cli", "campaign", str(camp), "--out", str(out), "-j", "2"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not (out / "results.jsonl").exists():
            time.sleep(0.05)
        workers = [k for k in children(proc.pid)]
        assert workers, "no worker process found"
        proc.kill()
        proc.wait()
        deadline = time.monotonic() + 30          # they go at once; a loaded machine may take a while to run them
        while [w for w in workers if alive(w)] and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not [w for w in workers if alive(w)], "workers outlived their campaign"
    finally:
        if proc.poll() is None:
            proc.kill()
    n = len(read_records(out / "results.jsonl"))
    assert 1 <= n < 4
    result = CliRunner().invoke(main, ["campaign", str(camp), "--out", str(out), "--resume", "-j", "2"])
    assert result.exit_code == 0, result.output
    runs = [r["pose_spec"] for r in read_records(out / "results.jsonl")]
    assert sorted(runs) == ["1", "2", "3", "4"]


@pytest.mark.parametrize(("sig", "status", "reason"), [(signal.SIGINT, 130, "interrupted (Ctrl-C)"),
                                                        (signal.SIGTERM, 143, TERMINATED_REASON)])
def test_ctrl_c_on_a_campaign_drops_the_queued_runs(tmp_path, cpu_wait, sig, status, reason):
    # a SIGTERM is passed on as a SIGTERM: the run in progress is recorded as terminated, not as a Ctrl-C
    camp, out = tmp_path / "c.toml", tmp_path / "out"
    camp.write_text(MINI.replace("max_time_s = 6", "max_time_s = 14400").replace("[300]", "[40]"))   # ~10 s of CPU each
    proc = subprocess.Popen([sys.executable, "-m", "robotexp.cli", "campaign", str(camp), "--out", str(out),
                             "-j", "1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline and not any(cpu_seconds(k) > 5.0 for k in children(proc.pid)):
            time.sleep(0.1)                 # the worker is inside its first (long) run: past its imports
        t0, mark = time.monotonic(), cpu_wait.total()
        proc.send_signal(sig)               # to the campaign alone: it passes it on
        _, stderr = proc.communicate(timeout=60)
        took, waited = time.monotonic() - t0, cpu_wait.since(mark)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == status, stderr
    records = read_records(out / "results.jsonl")
    assert len(records) == 1 and records[0]["reason"] == reason
    assert took < 15 + waited           # (a loaded machine: plus what the processes waited for a CPU)


def test_ctrl_c_while_the_workers_still_import_stops_the_campaign_with_one_line(tmp_path):
    # a terminal's Ctrl-C goes to every process of the group, workers that are still importing included: they
    # take it once their handlers are in, as a worker waiting for work does (no traceback from their imports,
    # no run made), and the campaign ends with its one line
    camp, out = tmp_path / "c.toml", tmp_path / "out"
    camp.write_text(MINI)
    proc = subprocess.Popen([sys.executable, "-m", "robotexp.cli", "campaign", str(camp), "--out", str(out),
                             "-j", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline, workers = time.monotonic() + 60, []
        while time.monotonic() < deadline and proc.poll() is None:
            workers = [k for k in children(proc.pid) if b"spawn_main" in cmdline(k)]
            if len(workers) == 2 and all(importing(k) for k in workers):
                break
            time.sleep(0.002)
        assert len(workers) == 2 and not (out / "results.jsonl").exists(), "the workers were not caught importing"
        os.killpg(proc.pid, signal.SIGINT)
        _, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, stderr
    lines = stderr.strip().splitlines()
    assert "Traceback" not in stderr and lines[-1] == "robotexp: interrupted" and len(lines) == 2, stderr
    assert not (out / "results.jsonl").exists() or read_records(out / "results.jsonl") == []
    deadline = time.monotonic() + 30
    while [w for w in workers if alive(w)] and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not [w for w in workers if alive(w)], "workers outlived their campaign"


def test_report_counts_a_run_recorded_twice_once_and_says_so(tmp_path):
    path = tmp_path / "results.jsonl"
    rec = {"run": "r1", "method": "frontier", "world": "dense", "world_spec": "dense", "pose_spec": "1",
           "start_pose": [0, 0, 0], "max_speed_m_s": 0.3, "path_length_m": 1.0, "robot_time_s": 1.0,
           "wall_time_s": 1.0, "coverage": 0.5, "collisions": 0, "nodes": None, "visited_cells": 1, "seed": 0,
           "completed": True, "reason": "done", "map_iou": None}
    other = dict(rec, run="r2", pose_spec="2")
    path.write_text("".join(json.dumps(r) + "\n" for r in (rec, other, dict(rec, run="r1_2", path_length_m=9.0))))
    assert [r.run for r in load_results(path)] == ["r1", "r2"]
    result = CliRunner().invoke(main, ["campaign", "report", str(path)])
    assert result.exit_code == 0 and "1 run(s) recorded more than once" in result.output and "r1_2" in result.output
