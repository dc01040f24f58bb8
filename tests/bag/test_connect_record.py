"""`robotexp connect --record`: a real protocol robot (the P3-DX emulator over TCP, with its laser)
watched while it drives, its states written as a ROS 2 bag that `robotexp replay` maps."""

from __future__ import annotations

import json
from pathlib import Path

from click.testing import CliRunner
from mcap.reader import make_reader

from robotexp.bag.replay import read_bag
from robotexp.cli import main
from robotexp.sim import LaserConfig
from robotexp_drivers.p3dx.emulator import P3DXEmulator


def test_connect_records_a_bag_that_replays(tmp_path: Path) -> None:
    bag = tmp_path / "p3dx.mcap"
    with P3DXEmulator("ufmg-static", pose="path1", port=0, speedup=4.0, laser=LaserConfig(range_max=3.0)) as emu:
        res = CliRunner().invoke(main, ["connect", "p3dx", emu.address, "--drive", "200,10", "--for", "1.5",
                                        "--record", str(bag)])
        assert res.exit_code == 0, res.output
    with open(bag, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    topics = {c.topic for c in summary.channels.values()}
    assert {"/odom", "/tf", "/scan", "/robotexp/scan"} <= topics
    data = read_bag(bag)
    assert data.meta is None and len(data.ticks) >= 5          # replayed as a robot's bag: a tick per scan
    xs = [t.pose.x for t in data.ticks]
    assert max(xs) - min(xs) > 0.05                            # it drove
    res = CliRunner().invoke(main, ["replay", str(bag), "-o", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    rec = json.loads((tmp_path / "out" / "results.jsonl").read_text().splitlines()[-1])
    assert rec["coverage"] is None and rec["path_length_m"] > 0.05
    # a bad file name is one line before connecting
    res = CliRunner().invoke(main, ["connect", "p3dx", "127.0.0.1:1", "--record", str(tmp_path / "x.bag")])
    assert res.exit_code == 2 and "FILE.mcap" in res.output
