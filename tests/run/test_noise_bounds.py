"""Laser noise is bounded (0..1000 mm, NaN and inf refused) in the one place a run's settings are
checked (RunSpec.validate), so the CLI, a campaign file and a Lua script all refuse it before a run."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from robotexp.campaign.spec import load_campaign
from robotexp.cli import main
from robotexp.errors import ConfigError, ScriptError
from robotexp.run.spec import RunSpec


@pytest.mark.parametrize("option", ["--noise-uniform", "--noise-sigma"])
@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "1e300", "1000.5", "-1"])
def test_cli_noise_out_of_range_is_one_line(option: str, value: str, tmp_path: Path) -> None:
    res = CliRunner().invoke(main, ["explore", "-w", "ufmg-static", "--max-time", "1", option, value,
                                    "-o", str(tmp_path / "out")])
    assert res.exit_code == 2, (res.output, res.exception)
    lines = [x for x in res.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and "laser noise" in lines[0] and "within 0..1000 mm" in lines[0], res.output
    assert not (tmp_path / "out" / "results.jsonl").exists()


def test_bound_itself_is_accepted() -> None:
    RunSpec(world="ufmg-static", method="frontier", laser_sigma=1.0, laser_uniform=1.0).validate()
    with pytest.raises(ConfigError, match="sigma"):
        RunSpec(world="ufmg-static", method="frontier", laser_sigma=float("nan")).validate()


@pytest.mark.parametrize("key, value", [("laser_uniform_mm", "nan"), ("laser_uniform_mm", "inf"),
                                        ("laser_sigma_mm", "nan"), ("laser_sigma_mm", "1e300")])
def test_campaign_noise_out_of_range(key: str, value: str, tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text(f'[campaign]\nname = "c"\n{key} = {value}\n[[set]]\nworld = "ufmg-static"\n'
                    'poses = ["path1"]\nmethods = ["frontier"]\n')
    with pytest.raises(ConfigError, match=r"laser noise .* within 0\.\.1000 mm"):
        load_campaign(path)


@pytest.mark.parametrize("args, says", [("1e300", "within 0..1000 mm"), ("0, 1001", "within 0..1000 mm"),
                                        ("0, 0/0", "finite"), ("1/0", "finite")])
def test_lua_noise_out_of_range(args: str, says: str, tmp_path: Path) -> None:
    from robotexp.lua import run_script

    script = tmp_path / "s.lua"
    script.write_text(f"robot.setLaserNoise({args})\n")
    with pytest.raises(ScriptError, match=r"robot\.setLaserNoise") as err:
        run_script(script, out=tmp_path / "out", emit=lambda _: None, notice=lambda _: None)
    assert says in str(err.value)
