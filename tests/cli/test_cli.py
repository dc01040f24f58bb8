"""The `robotexp` command line: listings, one-line errors with exit status 2, a short run's files."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from click.testing import CliRunner

from robotexp.cli import main

CLI = [sys.executable, "-m", "robotexp.cli"]
TIMEOUT = 60.0      # [s] bound on any subprocess


def test_worlds_lists_builtin_worlds_with_sizes() -> None:
    result = CliRunner().invoke(main, ["worlds"])
    assert result.exit_code == 0, result.output
    lines = {line.split()[0]: line for line in result.output.splitlines() if line.strip() and line[0] != " "}
    # outer walls 0.1 m thick centred on the room's edge: 0.1 m more than the room
    sizes = {"dense": "20.1 x 15.1 m", "sparse": "30.1 x 20.1 m", "ufmg-static": "10.1 x 10.1 m",
             "ufmg-dynamic": "10.1 x 10.1 m"}
    assert set(lines) == set(sizes)
    for name, size in sizes.items():
        assert size in lines[name], lines[name]
    assert "9 start poses" in lines["dense"] and "2 start poses" in lines["ufmg-static"]
    # each world's pose names with where they are, as --pose reads them (mm, mm, deg)
    assert "  poses: path1 (-4200,-4200,45), path2 (4200,4200,-135)" in result.output.splitlines()


def test_plugins_lists_frontier() -> None:
    result = CliRunner().invoke(main, ["plugins"])
    assert result.exit_code == 0, result.output
    frontier = [line.split() for line in result.output.splitlines() if line.split()[:1] == ["frontier"]]
    assert len(frontier) == 1
    name, target, dist, _version, *_ = frontier[0]
    assert (name, target, dist) == ("frontier", "robotexp_plugins.frontier:FrontierExplorer", "robotexp")
    assert "robotexp.explorers" in result.output and "robotexp.robots" in result.output
    assert "robotexp.coordinators" in result.output
    assert any(line.split()[:2] == ["burgard", "robotexp_plugins.coordinators:BurgardCoordinator"]
               for line in result.output.splitlines())


# -- bad input: exit 2 and one line on stderr -------------------------------------------------

BAD_MAP = """\
2D-Map
MinPos: 0 0
MaxPos: 1000 1000
Resolution: abc
LINES
0 0 1000 0
"""

BAD_YAML = """\
image: room.pgm
resolution: fast
origin: [0.0, 0.0, 0.0]
occupied_thresh: 0.65
free_thresh: 0.196
negate: 0
"""

# name -> (arguments after `explore`, fragments the message must contain)
BAD_INPUTS: dict[str, tuple[list[str], list[str]]] = {
    "unknown-world": (["--world", "atlantis"],
                      ["'atlantis'", "dense", "sparse", "ufmg-static", "ufmg-dynamic"]),
    "unknown-method": (["--method", "teleport"], ["'teleport'", "frontier"]),
    "bad-map": (["--world", "{tmp}/bad.map"], ["bad.map:4:", "Resolution"]),
    "bad-yaml": (["--world", "{tmp}/bad.yaml"], ["bad.yaml:2:", "'resolution'"]),
    "pose-in-obstacle": (["--world", "ufmg-static", "--pose", "0,0,0"], ["(0, 0)", "obstacle"]),
    "pose-outside": (["--world", "ufmg-static", "--pose", "50000,0,0"], ["(50, 0)", "outside"]),
    "pose-name": (["--world", "ufmg-static", "--pose", "kitchen"], ["'kitchen'", "path1", "path2"]),
    "pose-garbage": (["--world", "ufmg-static", "--pose", "1,2,3,4"], ["'1,2,3,4'", "mm"]),
    "speed": (["--speed", "-100"], ["--speed", "-100"]),
    "laser-range": (["--laser-range", "0"], ["--laser-range", "0"]),
    "cell": (["--cell", "-5"], ["--cell", "-5"]),
    "param-syntax": (["--param", "nokey"], ["--param", "'nokey'"]),
    "param-unknown": (["--param", "warp_factor=9"], ["warp_factor", "frontier"]),
    "show": (["--show", "sparkles"], ["--show", "sparkles"]),
    "robot": (["--robot", "r2d2"], ["'r2d2'", "p3dx", "kobuki"]),
}


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder holding a malformed .map and a malformed ROS .yaml."""
    tmp = tmp_path_factory.mktemp("bad")
    (tmp / "bad.map").write_text(BAD_MAP)
    (tmp / "bad.yaml").write_text(BAD_YAML)
    return tmp


def _explore_argv(case: str, tmp: Path) -> list[str]:
    args, _ = BAD_INPUTS[case]
    return ["explore", "--out", str(tmp / "out"), "--max-time", "5"] + [a.replace("{tmp}", str(tmp)) for a in args]


def _check_one_line(case: str, code: int | None, stdout: str, stderr: str) -> None:
    assert code == 2, (stdout, stderr)
    assert "Traceback" not in stderr and "Traceback" not in stdout
    lines = stderr.splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith("robotexp: error: ")
    for fragment in BAD_INPUTS[case][1]:
        assert fragment in lines[0], (fragment, lines[0])
    assert stdout == ""


@pytest.mark.parametrize("case", list(BAD_INPUTS))
def test_bad_input_is_one_line_exit_2(case: str, bad_files: Path) -> None:
    result = CliRunner().invoke(main, _explore_argv(case, bad_files))
    _check_one_line(case, result.exit_code, result.stdout, result.stderr)
    assert not (bad_files / "out").exists(), "a rejected run must not write results"


def test_bad_input_in_a_real_process(bad_files: Path) -> None:
    # a fresh process: C-level output of the libraries (pybullet's banner) must not add lines
    cases = ("unknown-world", "bad-map", "pose-in-obstacle")
    procs = {c: subprocess.Popen(CLI + _explore_argv(c, bad_files), stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True) for c in cases}
    try:
        for case, proc in procs.items():
            out, err = proc.communicate(timeout=TIMEOUT)
            _check_one_line(case, proc.returncode, out, err)
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()


def test_help_imports_no_heavy_modules() -> None:
    code = textwrap.dedent("""
        import sys
        import robotexp.cli
        for argv in (["--help"], ["explore", "--help"], ["--version"]):
            try:
                robotexp.cli.main(argv)
            except SystemExit as exc:
                assert exc.code == 0, (argv, exc.code)
        heavy = ("pybullet", "numba", "lupa", "pymavlink")
        print("LOADED:" + ",".join(sorted(m for m in sys.modules if m.split(".")[0] in heavy)))
    """)
    result = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, text=True, timeout=TIMEOUT)
    assert result.returncode == 0, result.stderr
    assert "Usage:" in result.stdout and "--laser-range" in result.stdout
    assert result.stdout.splitlines()[-1] == "LOADED:"


# -- a short successful run ------------------------------------------------------------------

PROMISED_KEYS = (
    "run", "method", "world", "start_pose", "max_speed_m_s", "path_length_m", "robot_time_s", "wall_time_s",
    "coverage", "collisions", "nodes", "visited_cells", "seed", "completed", "map_iou",
    "time_to_coverage_90_s", "time_to_coverage_95_s", "time_to_coverage_99_s",
    "path_to_coverage_90_m", "path_to_coverage_95_m", "path_to_coverage_99_m",
)


def test_short_explore_writes_results(tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["explore", "--world", "ufmg-static", "--max-time", "30", "--speed", "250",
                                       "--seed", "3", "--out", str(out)])
    assert result.exit_code == 0, result.output
    records = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert len(records) == 1
    r = records[0]
    missing = [k for k in PROMISED_KEYS if k not in r]
    assert not missing, missing
    assert r["world"] == "ufmg-static" and r["method"] == "frontier" and r["seed"] == 3
    assert r["max_speed_m_s"] == pytest.approx(0.25)
    # default start: ufmg-static's first named pose, path1 at (-4.2, -4.2) m heading 45 deg
    assert r["start_pose"] == pytest.approx([-4.2, -4.2, 0.7853981633974483])
    assert r["robot_time_s"] == pytest.approx(30.0, abs=0.11)
    assert r["completed"] is False and "time limit" in r["reason"]
    assert 0.5 < r["path_length_m"] <= 0.25 * 30.0 + 1e-6
    assert 0.0 < r["coverage"] < 1.0 and 0.0 < r["map_iou"] <= 1.0
    assert r["collisions"] == 0 and r["visited_cells"] > 5
    name = r["run"]
    for suffix in (".png", ".coverage.csv", ".coverage.png"):
        path = out / f"{name}{suffix}"
        assert path.is_file() and path.stat().st_size > 0, path
    assert (out / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with open(out / f"{name}.coverage.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["robot_time_s", "path_length_m", "coverage"]
    times = [float(row[0]) for row in rows[1:]]
    assert times == sorted(times) and times[0] == 0.0 and times[-1] == pytest.approx(r["robot_time_s"])
    assert float(rows[-1][2]) == pytest.approx(r["coverage"], abs=1e-5)
    assert name in result.output and "results.jsonl" in result.output


def test_an_out_folder_removed_by_a_concurrent_check_is_made_again(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    # two robotexp processes checking the same new --out at once: the other one's clean-up can remove the folder
    # between this one's mkdir and its probe file (the clean-clone CI met it once: "cannot write there (No such
    # file or directory)" for a folder that could be written)
    import tempfile

    from robotexp.output.safefile import writable_folder

    out = tmp_path / "new" / "out"
    real = tempfile.NamedTemporaryFile
    calls = []

    def probe(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(1)
        if len(calls) == 1:
            out.rmdir()                       # the other process's clean-up, at the worst moment
        return real(*args, **kwargs)
    monkeypatch.setattr(tempfile, "NamedTemporaryFile", probe)
    writable_folder(out)
    assert len(calls) == 2 and not out.exists() and not out.parent.exists()   # checked, nothing left behind
