"""The documented third-party plugin path, end to end: install examples/plugin as a distribution of
its own, see `robotexp plugins` list it, run it with `robotexp explore`.

Everything runs in subprocesses with the installed copy first on PYTHONPATH, exactly as a user's
`pip install` would leave it; nothing is imported from examples/ directly. Whole file: ~5 s.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "plugin"
DIST = "robotexp-wallfollow-example"
TIMEOUT = 40.0      # [s] bound on any one subprocess; the whole file takes a few seconds


def _why_no_offline_build() -> str | None:
    """Why `--no-build-isolation` cannot build the example here, or None when it can: it needs
    setuptools, which builds wheels by itself from 70.1 on and before that needs `wheel`."""
    try:
        import setuptools
    except ImportError:
        return "setuptools is not installed (Python >= 3.12 venvs have none): install setuptools>=70.1"
    major, minor = (int(p) for p in setuptools.__version__.split(".")[:2])
    if (major, minor) < (70, 1) and importlib.util.find_spec("wheel") is None:
        return (f"setuptools {setuptools.__version__} cannot build a wheel without the `wheel` package: "
                "install `wheel` (or setuptools>=70.1) in this environment")
    return None


def _run(argv: list[str], env: dict[str, str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(argv, capture_output=True, text=True, timeout=TIMEOUT, env=env, cwd=cwd)


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, str], Path]:
    """Install the example into a private site dir; return the environment that sees it, and a cwd."""
    reason = _why_no_offline_build()
    if reason is not None:
        pytest.skip(reason)
    tmp = tmp_path_factory.mktemp("example_plugin")
    # build from a copy: setuptools writes build/ and *.egg-info next to the sources
    src = shutil.copytree(EXAMPLE, tmp / "src",
                          ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    site = tmp / "site"
    pip = _run([sys.executable, "-m", "pip", "install", "--no-deps", "--no-build-isolation", "--no-index",
                "--disable-pip-version-check", "--target", str(site), str(src)], dict(os.environ), tmp)
    assert pip.returncode == 0, f"pip install failed:\n{pip.stdout}\n{pip.stderr}"
    assert (site / "robotexp_wallfollow.py").is_file()
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site), *filter(None, [env.get("PYTHONPATH")])])
    return env, tmp


def test_plugins_lists_the_example_with_its_distribution(installed: tuple[dict[str, str], Path]) -> None:
    env, cwd = installed
    result = _run([sys.executable, "-m", "robotexp.cli", "plugins"], env, cwd)
    assert result.returncode == 0, result.stderr
    lines = [line.split() for line in result.stdout.splitlines()]
    rows = [fields for fields in lines if fields and fields[0] == "wall-follow"]
    assert len(rows) == 1, result.stdout
    assert rows[0][1:4] == ["robotexp_wallfollow:WallFollowExplorer", DIST, "0.1.0"]
    assert "ExplorationMethod.WALL_FOLLOW" in rows[0]
    # the built-in explorer is still there next to it
    assert any(fields and fields[0] == "frontier" for fields in lines)


def test_explore_with_the_example_writes_its_results(installed: tuple[dict[str, str], Path]) -> None:
    env, cwd = installed
    out = cwd / "run"
    result = _run([sys.executable, "-m", "robotexp.cli", "explore", "--world", "ufmg-static",
                   "--method", "wall-follow", "--param", "duration=20", "--out", str(out)], env, cwd)
    assert result.returncode == 0, f"{result.stdout}\n{result.stderr}"
    records = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert len(records) == 1
    rec = records[0]
    assert rec["method"] == "wall-follow"
    assert rec["world"] == "ufmg-static"
    assert rec["collisions"] == 0
    # it ended on its own budget (the parameter reached it), not on the run's time limit
    assert rec["completed"] is True
    assert rec["reason"] == "time budget of 20 s used"
    assert 20.0 <= rec["robot_time_s"] < 20.5
    assert rec["path_length_m"] > 2.0          # it moved: ~0.3 m/s for most of 20 s
    assert "collisions 0" in result.stdout


def test_a_bad_parameter_of_the_example_is_a_config_error(installed: tuple[dict[str, str], Path]) -> None:
    env, cwd = installed
    result = _run([sys.executable, "-m", "robotexp.cli", "explore", "--world", "ufmg-static",
                   "--method", "wall-follow", "--param", "duration=-5", "--out", str(cwd / "bad")], env, cwd)
    assert result.returncode == 2, f"{result.stdout}\n{result.stderr}"
    assert "wall-follow: duration must be a number > 0, got -5" in result.stderr
    assert not (cwd / "bad" / "results.jsonl").exists()
