"""Bad input is one line and exit 2, checked before any run starts: no traceback, no
results written."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from robotexp.cli import main

CAMPAIGN = """
[campaign]
name = "bad"
max_time_s = 5
[[set]]
world = "dense"
poses = ["1"]
methods = ["frontier"]
speeds_mm_s = [300]
seeds = [0]
"""


def _one_line_exit_2(args: list[str], *words: str) -> None:
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    lines = [x for x in result.output.splitlines() if x.strip() and not x.startswith("campaign ")]
    assert len(lines) == 1 and lines[0].startswith("robotexp: error: "), result.output
    assert "Traceback" not in result.output
    for w in words:
        assert w in lines[0], lines[0]


@pytest.mark.parametrize(("args", "words"), [
    (["--seed", "-1"], ["seed must be an integer 0.."]),
    (["--seed", str(2**64)], ["seed must be an integer 0.."]),
    (["--laser-range", "1e12"], ["laser range", "at most 200000 mm"]),
    (["--speed", "1e300"], ["speed", "at most 10000 mm/s"]),
    (["--pose=-5000,7500,1e300"], ["pose '-5000,7500,1e300'", "theta within +-360"]),
    (["--pose=1e30,7500,0"], ["x and y must be within"]),
    (["--pose=-5000,nan,0"], ["expected a pose name or x,y,theta"]),
    (["-p", "foo=1"], ["unknown parameter(s) foo", "its parameters: ", "min_group_cells"]),
])
def test_explore_bad_values(tmp_path: Path, args: list[str], words: list[str]) -> None:
    out = tmp_path / "out"
    _one_line_exit_2(["explore", "--max-time", "5", "--out", str(out), *args], *words)
    assert not (out / "results.jsonl").exists()


@pytest.mark.parametrize("where", ["file", "proc"])
def test_out_that_cannot_be_written_is_found_before_the_run(tmp_path: Path, where: str) -> None:
    (tmp_path / "afile").write_text("x")
    out = str(tmp_path / "afile" / "sub") if where == "file" else "/proc/robotexp-test/out"
    _one_line_exit_2(["explore", "--max-time", "5", "--out", out], f"--out {out}: cannot write there")
    camp = tmp_path / "c.toml"
    camp.write_text(CAMPAIGN)
    _one_line_exit_2(["campaign", str(camp), "--out", out], "cannot write there")
    script = tmp_path / "s.lua"
    script.write_text("print(1)")
    _one_line_exit_2(["run", str(script), "--out", out], "cannot write there")


@pytest.mark.parametrize(("change", "words"), [
    (("seeds = [0]", "seeds = [-1]"), ["seed must be an integer 0.."]),
    (("seeds = [0]", "seeds = [0, 0]"), ["two runs share the key"]),
    (("speeds_mm_s = [300]", "speeds_mm_s = [300, 300.4]"), ["two runs share the key"]),
    (('name = "bad"', 'name = "../../escape"'), ["not a folder name"]),
    (("max_time_s = 5", "max_time_s = 5\nx = " + "[" * 50000 + "]" * 50000), ["nested too deeply"]),
])
def test_campaign_bad_files(tmp_path: Path, change: tuple[str, str], words: list[str]) -> None:
    camp = tmp_path / "c.toml"
    camp.write_text(CAMPAIGN.replace(*change))
    out = tmp_path / "out"
    _one_line_exit_2(["campaign", str(camp), "--out", str(out)], *words)
    assert not (out / "results.jsonl").exists()
    assert not (tmp_path.parent / "escape").exists()


def test_emulate_port_out_of_range() -> None:
    _one_line_exit_2(["emulate", "p3dx", "--port", "70000"], "--port must be within 0..65535, got 70000")


def test_lua_syntax_error_is_bad_input(tmp_path: Path) -> None:
    """A script that does not compile is refused before anything runs: one line with script:line, exit 2."""
    import subprocess
    import sys

    script = tmp_path / "bad.lua"
    script.write_text('print("ran")\nx = = 1\n')
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, "-m", "robotexp.cli", "run", str(script), "--out", str(out)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    assert "ran" not in done.stdout
    lines = [x for x in done.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("robotexp: error: bad.lua:2: "), done.stderr
    assert "does not compile" in lines[0]
    assert not (out / "results.jsonl").exists()
