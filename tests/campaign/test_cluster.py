"""Campaigns on Dask: a real scheduler and two workers on 127.0.0.1 (processes of the test), one of
them killed mid-campaign; `--cluster local:2`; --resume; bad addresses."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from robotexp.campaign.spec import load_campaign, record_key, run_key
from robotexp.cli import main
from dask_ports import free_port, wait_port
from procs import cpu_seconds, descendants

TINY = """
[campaign]
name = "tiny"
max_time_s = 15
[[set]]
world = "ufmg-static"
poses = ["path1", "path2"]
methods = ["frontier"]
speeds_mm_s = [300, 200]
seeds = [0, 1]
"""

# runs of about 20 s wall each here (a generated office at 40 mm/s, up to an hour of robot time)
LONG = """
[campaign]
name = "long"
max_time_s = 3600
[[set]]
world = "generated:office:0"
methods = ["frontier"]
speeds_mm_s = [40]
seeds = [0, 1, 2]
"""

DASK = str(Path(sys.executable).parent / "dask")


def _lines(results: Path) -> list[dict[str, object]]:
    if not results.exists():
        return []
    return [json.loads(x) for x in results.read_text(encoding="utf-8").splitlines() if x.strip()]


def _start_and_wait_first(camp_file: Path, out: Path, address: str,
                          procs: list[subprocess.Popen[bytes]]) -> subprocess.Popen[bytes]:
    """Start `robotexp campaign run --cluster` as a process; return once its first run is in results.jsonl."""
    campaign = subprocess.Popen([str(Path(sys.executable).parent / "robotexp"), "campaign", "run", str(camp_file),
                                 "--out", str(out), "--cluster", address],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    procs.append(campaign)
    end = time.monotonic() + 60
    while not _lines(out / "results.jsonl") and time.monotonic() < end and campaign.poll() is None:
        time.sleep(0.05)
    assert _lines(out / "results.jsonl"), "no run came back"
    return campaign


def _stop(procs: list[subprocess.Popen[bytes]]) -> None:
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def test_scheduler_two_workers_one_killed_mid_run_every_run_once(tmp_path: Path, cpu_wait: Any) -> None:
    camp_file = tmp_path / "tiny.toml"
    camp_file.write_text(TINY, encoding="utf-8")
    camp = load_campaign(camp_file)
    port = free_port()
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}
    procs: list[subprocess.Popen[bytes]] = []
    try:
        procs.append(subprocess.Popen([DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                                       "--no-dashboard"], env=env, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL))
        wait_port(port, 30)
        address = f"tcp://127.0.0.1:{port}"
        workers = [subprocess.Popen([DASK, "worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                                     "--host", "127.0.0.1", "--name", f"w{i}"], env=env, stdout=subprocess.DEVNULL,
                                    stderr=subprocess.DEVNULL) for i in range(2)]
        procs += workers
        out = tmp_path / "out"
        # as soon as the first run has streamed back, kill (SIGKILL, no goodbye) a worker in the middle of a run
        from distributed import Client

        campaign = _start_and_wait_first(camp_file, out, address, procs)
        with Client(address, timeout="10s") as client:
            names = {addr: w["name"] for addr, w in client.scheduler_info()["workers"].items()}
            busy = [names[addr] for addr, keys in client.processing().items() if keys]
        assert busy and len(_lines(out / "results.jsonl")) < len(camp.runs), "no run left to cut"
        workers[int(str(busy[0])[1:])].send_signal(signal.SIGKILL)
        stdout, stderr = campaign.communicate(timeout=120)
        assert campaign.returncode == 0, stderr.decode()[-2000:]
        # Ctrl-C on the client, in the middle of long runs: every run is cancelled on the scheduler, the
        # run executing on the worker ends within about a second (Dask alone would let it finish), exit 130
        long_file = tmp_path / "long.toml"
        long_file.write_text(LONG, encoding="utf-8")
        campaign = subprocess.Popen([str(Path(sys.executable).parent / "robotexp"), "campaign", "run", str(long_file),
                                     "--out", str(tmp_path / "out2"), "--cluster", address],
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        procs.append(campaign)

        def executing(dask_worker: Any) -> int:      # local: pickled by value for the workers
            return len(dask_worker.state.executing)

        def scheduler_tasks(dask_scheduler: Any) -> int:
            return len(dask_scheduler.tasks)

        with Client(address, timeout="10s") as client:
            end = time.monotonic() + 30
            while not sum(client.run(executing).values()) and time.monotonic() < end:
                time.sleep(0.1)
            assert sum(client.run(executing).values()) == 1      # the surviving worker is making a run
            time.sleep(1.0)
            campaign.send_signal(signal.SIGINT)
            t0, mark = time.monotonic(), cpu_wait.total()
            campaign.communicate(timeout=30)
            # the bounds below: plus what a loaded machine kept this test's processes waiting for a CPU
            assert campaign.returncode == 130 and time.monotonic() - t0 < 10 + cpu_wait.since(mark)
            end = time.monotonic() + 10
            while (client.run_on_scheduler(scheduler_tasks) or sum(client.run(executing).values())) \
                    and time.monotonic() < end:
                time.sleep(0.1)
            stopped, waited = time.monotonic() - t0, cpu_wait.since(mark)
            assert client.run_on_scheduler(scheduler_tasks) == 0     # nothing queued or kept
            assert sum(client.run(executing).values()) == 0 and stopped < 5 + waited, (stopped, waited)
        assert _lines(tmp_path / "out2" / "results.jsonl") == []     # a cancelled run is not recorded
    finally:
        _stop(procs)
    records = _lines(out / "results.jsonl")
    counts = Counter(record_key(r) for r in records)
    assert set(counts) == {run_key(s, s.pose or "default") for s in camp.runs}
    assert all(n == 1 for n in counts.values()), counts       # every run exactly once
    assert all((out / f"{r['run']}.png").exists() and (out / f"{r['run']}.path.csv").exists() for r in records)
    assert f"{len(camp.runs)} runs made" in stdout.decode()


def test_local_cluster_runs_the_campaign_and_resume_adds_nothing(tmp_path: Path) -> None:
    camp_file = tmp_path / "tiny.toml"
    camp_file.write_text(TINY.replace("seeds = [0, 1]", "seeds = [0]").replace('name = "tiny"',
                                                                                'name = "tiny"\nrecord = true'),
                         encoding="utf-8")
    camp = load_campaign(camp_file)
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["campaign", "run", str(camp_file), "--out", str(out), "--cluster", "local:2"])
    assert r.exit_code == 0, r.output
    records = _lines(out / "results.jsonl")
    assert sorted(record_key(x) for x in records) == sorted(run_key(s, s.pose or "default") for s in camp.runs)
    # `record = true`: each run's ROS 2 bag came back from its worker into out/bags
    assert all((out / "bags" / f"{x['run']}.mcap").stat().st_size > 0 for x in records)
    # resume: drop one record, resume on the cluster, get exactly that one back (its files renamed _2)
    lines = (out / "results.jsonl").read_text(encoding="utf-8").splitlines()
    (out / "results.jsonl").write_text("\n".join(lines[1:]) + "\n", encoding="utf-8")
    r = CliRunner().invoke(main, ["campaign", "run", str(camp_file), "--out", str(out), "--cluster", "local:1",
                                  "--resume"])
    assert r.exit_code == 0, r.output
    again = _lines(out / "results.jsonl")
    assert len(again) == len(camp.runs) and record_key(again[-1]) == record_key(records[0])
    name = str(again[-1]["run"])
    assert name == f"{records[0]['run']}_2" and (out / f"{name}.png").exists()
    assert f"image: {name}.map.pgm" in (out / f"{name}.map.yaml").read_text(encoding="utf-8")


@pytest.mark.parametrize("address, words", [("local:0", "at least 1 worker"), ("8786", "tcp://HOST:PORT"),
                                            ("http://x:1", "tcp://HOST:PORT")])
def test_bad_cluster_address_one_line_exit_2(tmp_path: Path, address: str, words: str) -> None:
    camp_file = tmp_path / "tiny.toml"
    camp_file.write_text(TINY, encoding="utf-8")
    r = CliRunner().invoke(main, ["campaign", "run", str(camp_file), "--out", str(tmp_path / "o"),
                                  "--cluster", address])
    assert r.exit_code == 2 and words in r.output and "Traceback" not in r.output
    assert not (tmp_path / "o").exists()


def test_no_scheduler_there_is_one_line_exit_2(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("robotexp.campaign.cluster.CONNECT_TIMEOUT", "2s")
    camp_file = tmp_path / "tiny.toml"
    camp_file.write_text(TINY, encoding="utf-8")
    r = CliRunner().invoke(main, ["campaign", "run", str(camp_file), "--out", str(tmp_path / "o"),
                                  "--cluster", f"tcp://127.0.0.1:{free_port()}"])
    assert r.exit_code == 2 and "no Dask scheduler answers there" in r.output, r.output
    assert not (tmp_path / "o" / "results.jsonl").exists()


def _worker_settings(dask_worker: Any) -> tuple[str | None, bool, bool]:
    import dask

    return (os.environ.get("MALLOC_TRIM_THRESHOLD_"), bool(dask.config.get("distributed.worker.profile.enabled")),
            "profile" in dask_worker.periodic_callbacks)


def test_local_cluster_workers_run_lean_and_time_their_runs(tmp_path: Path) -> None:
    from robotexp.campaign.jobs import RunTiming
    from robotexp.campaign.runner import run_campaign
    from robotexp.campaign.cluster import _client

    # no trim threshold from the nanny (it froze glibc's mmap threshold: page faults in every step), no
    # stack sampling of the running task every 10 ms
    with _client("local:1") as client:
        assert list(client.run(_worker_settings).values()) == [(None, False, False)]
    camp_file = tmp_path / "one.toml"
    camp_file.write_text(TINY.replace("seeds = [0, 1]", "seeds = [0]").replace('poses = ["path1", "path2"]',
                                                                                'poses = ["path1"]'), encoding="utf-8")
    camp = load_campaign(camp_file)
    timings: list[RunTiming] = []
    records = run_campaign(camp, tmp_path / "out", jobs=1, cluster="local:2", timings=timings)
    assert sorted(t.run for t in timings) == sorted(r.run for r in records) and len(records) == 2
    by_run = {r.run: r for r in records}
    for t in timings:
        assert t.worker.startswith("tcp://127.0.0.1:") and t.loop_s == by_run[t.run].wall_time_s
        assert 0 < t.loop_s < t.wall_s and t.cpu_s > 0


def test_ctrl_c_from_a_terminal_stops_a_local_cluster_with_one_line(tmp_path: Path, cpu_wait: Any) -> None:
    # a terminal's Ctrl-C goes to every process of its group, the local cluster's worker processes included:
    # they do not take it (Dask's event loop printed a traceback each); the campaign cancels the runs, closes
    # the cluster and says one line
    long_file = tmp_path / "long.toml"
    long_file.write_text(LONG, encoding="utf-8")
    campaign = subprocess.Popen([sys.executable, "-m", "robotexp.cli", "campaign", "run", str(long_file), "--out",
                                 str(tmp_path / "out"), "--cluster", "local:2"], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, start_new_session=True,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        end = time.monotonic() + 90
        while time.monotonic() < end and campaign.poll() is None:
            busy = [k for k in descendants(campaign.pid) if cpu_seconds(k) > 3.0]
            if len(busy) == 2:                  # both worker processes inside a run
                break
            time.sleep(0.1)
        workers = descendants(campaign.pid)
        assert len(busy) == 2, "the workers did not start their runs"
        os.killpg(campaign.pid, signal.SIGINT)
        t0, mark = time.monotonic(), cpu_wait.total()
        _, stderr = campaign.communicate(timeout=60)
        took, waited = time.monotonic() - t0, cpu_wait.since(mark)
    finally:
        if campaign.poll() is None:
            os.killpg(campaign.pid, signal.SIGKILL)
            campaign.wait()
    assert campaign.returncode == 130, stderr
    lines = stderr.strip().splitlines()
    assert "Traceback" not in stderr and "Error" not in stderr and lines[-1] == "robotexp: interrupted", stderr
    assert took < 15 + waited, (took, waited)
    assert _lines(tmp_path / "out" / "results.jsonl") == []         # the runs cut short are not recorded
    gone = time.monotonic() + 30
    while [w for w in workers if Path(f"/proc/{w}").exists()] and time.monotonic() < gone:
        time.sleep(0.1)
    assert not [w for w in workers if Path(f"/proc/{w}").exists()], "processes outlived the campaign"
