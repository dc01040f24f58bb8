"""exploration.setRecordFolder: each run of a script is recorded as a ROS 2 bag that replays to its record."""

from __future__ import annotations

import json

from robotexp.bag.replay import read_bag, replay_bag


def test_each_run_recorded_and_replayed(lua):
    lua("""exploration.setWorld("ufmg-static")
exploration.setMaxTime(5000)
exploration.setRecordFolder("bags")
exploration.start()
exploration.wait()
exploration.setMaxTime(3000)
exploration.start()
exploration.wait()
exploration.setRecordFolder(nil)
exploration.start()
exploration.wait()
""")
    recs = [json.loads(line) for line in (lua.out / "results.jsonl").read_text().splitlines()]
    assert len(recs) == 3
    bags = sorted((lua.out / "bags").glob("*.mcap"))
    assert [b.stem for b in bags] == sorted(r["run"] for r in recs[:2])
    for rec in recs[:2]:
        bag = read_bag(lua.out / "bags" / f"{rec['run']}.mcap")
        assert bag.record is not None and bag.record["run"] == rec["run"]
        again = replay_bag(bag, None).record
        assert again is not None
        assert (again.coverage, again.path_length_m, again.robot_time_s) == \
            (rec["coverage"], rec["path_length_m"], rec["robot_time_s"])


def test_run_record_option(tmp_path):
    """`robotexp run SCRIPT --record DIR`: the supervised child records each run of the script."""
    from click.testing import CliRunner

    from robotexp.cli import main

    script = tmp_path / "s.lua"
    script.write_text('exploration.setWorld("ufmg-static")\nexploration.setMaxTime(3000)\n'
                      'exploration.start()\nexploration.wait()\n')
    res = CliRunner().invoke(main, ["run", str(script), "--out", str(tmp_path / "out"), "--record",
                                    str(tmp_path / "bags")])
    assert res.exit_code == 0, res.output
    (rec,) = [json.loads(line) for line in (tmp_path / "out" / "results.jsonl").read_text().splitlines()]
    again = replay_bag(read_bag(tmp_path / "bags" / f"{rec['run']}.mcap"), None).record
    assert again is not None and (again.coverage, again.path_length_m) == (rec["coverage"], rec["path_length_m"])
