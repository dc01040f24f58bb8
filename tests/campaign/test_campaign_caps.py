"""A campaign whose sweep or product of lists would expand into too many runs is refused with one
line (exit 2) before any list of them is made: 3 x 9001 swept values (7.3e11 runs) under a 1 GB
address-space limit."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from robotexp.campaign.spec import MAX_RUNS, load_campaign
from robotexp.errors import ConfigError

_RUN = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (2**30, 2**30))
from robotexp.cli import main
sys.argv = ["robotexp"] + sys.argv[1:]
main()
"""

HEAD = """
[campaign]
name = "big"
max_time_s = 8
[[set]]
world = "ufmg-static"
poses = ["path1"]
methods = ["frontier"]
"""


def test_huge_sweep_is_one_line(tmp_path: Path) -> None:
    path = tmp_path / "big.toml"
    path.write_text(HEAD + "[set.sweep.frontier]\n"
                    "clearance = {start = 0.1, stop = 1.0, step = 0.0001}\n"
                    "replan_period = {start = 1.0, stop = 1.9, step = 0.0001}\n"
                    "goal_timeout = {start = 10.0, stop = 10.9, step = 0.0001}\n")
    done = subprocess.run([sys.executable, "-c", _RUN, "campaign", "run", str(path), "-o", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=120,
                          env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    lines = [x for x in done.stderr.splitlines() if x.strip()]
    assert done.returncode == 2, done.stderr[-1500:]
    assert len(lines) == 1 and "9001 x 9001 x 9001 values give 7.29e+11 combinations" in lines[0], lines
    assert f"at most {MAX_RUNS} runs" in lines[0] and str(path) in lines[0]


def test_product_of_lists_is_capped(tmp_path: Path) -> None:
    seeds = ", ".join(str(i) for i in range(400))
    speeds = ", ".join(str(100 + i) for i in range(300))
    path = tmp_path / "many.toml"
    path.write_text(HEAD + f"seeds = [{seeds}]\nspeeds_mm_s = [{speeds}]\n")
    with pytest.raises(ConfigError, match=r"1.2e\+05 runs .* at most 100000 runs"):
        load_campaign(path)


def test_many_worlds_are_counted_before_any_is_loaded(tmp_path: Path) -> None:
    """Two ranges of 100000 generated worlds: refused at once (loading them would take minutes)."""
    path = tmp_path / "worlds.toml"
    path.write_text('[campaign]\nname = "w"\n[[set]]\n'
                    'worlds = ["generated:office:0-99999", "generated:office:0-99999"]\nmethods = ["frontier"]\n')
    t0 = time.process_time()
    with pytest.raises(ConfigError, match=r"200000 worlds x at least 1 runs each.* at most 100000 runs"):
        load_campaign(path)
    assert time.process_time() - t0 < 5.0


def test_a_team_axis_value_given_twice_and_a_bad_generated_world_name_the_key(tmp_path: Path) -> None:
    base = '[campaign]\nname = "t"\n[[set]]\nworld = "dense"\nmethods = ["frontier"]\n'
    for extra, key, what in (("teams = [2, 2]\n", "teams", "2 is given twice"),
                             ('teams = [2]\ncoordinators = ["burgard", "burgard"]\n', "coordinators",
                              "'burgard' is given twice")):
        path = tmp_path / f"{key}.toml"
        path.write_text(base + extra)
        with pytest.raises(ConfigError, match=rf"^{path}: \[\[set\]\] #1\.{key}: {what}; give each once$"):
            load_campaign(path)
    path = tmp_path / "gen.toml"
    path.write_text(base.replace('"dense"', '"generated:office:0:100000x100000"'))
    with pytest.raises(ConfigError, match=rf"^{path}: \[\[set\]\] #1\.world: generated world: size 100000 x 100000"):
        load_campaign(path)


def test_jobs_below_one_is_refused_before_anything_is_said(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from robotexp.cli import main

    path = tmp_path / "c.toml"
    path.write_text(HEAD)
    res = CliRunner().invoke(main, ["campaign", "run", str(path), "-j", "0", "-o", str(tmp_path / "out")])
    assert res.exit_code == 2 and res.output == "robotexp: error: --jobs must be >= 1, got 0\n"
    assert not (tmp_path / "out").exists()
