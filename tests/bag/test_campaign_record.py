"""A campaign with `record = true` writes each run's bag in <out>/bags, replaying to its record."""

from __future__ import annotations

from pathlib import Path

import pytest

from robotexp.bag.replay import read_bag, replay_bag
from robotexp.campaign.spec import load_campaign
from robotexp.campaign.runner import run_campaign
from robotexp.errors import ConfigError

CAMPAIGN = """
[campaign]
name = "rec"
max_time_s = 8
record = true
[[set]]
world = "ufmg-static"
poses = ["path1", "path2"]
methods = ["frontier"]
"""


def test_campaign_records_each_run(tmp_path: Path) -> None:
    src = tmp_path / "c.toml"
    src.write_text(CAMPAIGN, encoding="utf-8")
    camp = load_campaign(src)
    assert camp.record
    records = run_campaign(camp, tmp_path / "out", jobs=1)
    assert len(records) == 2
    for rec in records:
        bag = read_bag(tmp_path / "out" / "bags" / f"{rec.run}.mcap")
        again = replay_bag(bag, None).record
        assert again is not None
        assert (again.coverage, again.path_length_m, again.robot_time_s) == \
            (rec.coverage, rec.path_length_m, rec.robot_time_s)


def test_record_key_checked(tmp_path: Path) -> None:
    src = tmp_path / "c.toml"
    src.write_text(CAMPAIGN.replace("record = true", 'record = "yes"'), encoding="utf-8")
    with pytest.raises(ConfigError, match="record"):
        load_campaign(src)
    src.write_text(CAMPAIGN.replace("record = true\n", "").replace('methods = ["frontier"]',
                                                                  'methods = ["frontier"]\nrecord = true'))
    with pytest.raises(ConfigError, match="unknown key 'record'"):
        load_campaign(src)
