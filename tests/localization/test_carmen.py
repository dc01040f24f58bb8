"""CARMEN logs: the reader against hand-written lines, and `robotexp map` on a log simulated here."""

from __future__ import annotations

import gzip
import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.errors import ConfigError
from robotexp.localization import ate
from robotexp.localization.carmen import CarmenLog, flaser_angles, format_flaser, odometry_at, read_carmen
from robotexp.localization.logmap import OdometryNoise, perturb_path
from robotexp.robot import Pose
from robotexp.world.raycast import RayIndex
from robotexp.world.builtin import builtin_world
from robotexp.world.rosmap import load_ros_grid, load_ros_world

REACH = 8.0


def loop_path() -> list[Pose]:
    """Along the corridor of the built-in `dense` office and back (y = 7.5 m, x from -9 to 9 m), a pose
    every 0.25 m, turning about in place in 30 degree steps."""
    poses: list[Pose] = []
    for x0, x1, th in ((-9.0, 9.0, 0.0), (9.0, -9.0, math.pi)):
        if poses:
            last = poses[-1].theta
            poses += [Pose(x0, 7.5, last + math.radians(30.0 * k)) for k in range(1, 6)]
        n = round(abs(x1 - x0) / 0.25)
        poses += [Pose(x0 + (x1 - x0) * k / n, 7.5, th) for k in range(n + 1)]
    return poses


def simulated_log(path: Path, *, gz: bool = False, junk: bool = False) -> list[Pose]:
    """Write a CARMEN log of 181-beam scans along `loop_path` in `dense` (no echo: 81.91 m)."""
    world = builtin_world("dense")
    index = RayIndex(world.boxes, world.discs, 2.0)
    angles = flaser_angles(181)
    truth = loop_path()
    lines = ["# simulated by the robotexp tests", "PARAM robot_front_laser_max 81.91 nohost 0"]
    for k, p in enumerate(truth):
        frac = index.cast(np.tile([p.x, p.y], (181, 1)), p.theta + angles, REACH, 0.3)
        ranges = np.where(frac >= 1.0, 81.91, frac * REACH)
        lines.append(f"ODOM {p.x:.6f} {p.y:.6f} {p.theta:.6f} 0 0 0 {k:.3f} robotexp {k:.3f}")
        lines.append(format_flaser(ranges, p, p, float(k)))
        if junk and k == 3:
            lines.append("FLASER 181 1.0 2.0 oops")
            lines.append("ODOM 1 2")
    text = "\n".join(lines) + "\n"
    if gz:
        path.write_bytes(gzip.compress(text.encode()))
    else:
        path.write_text(text)
    return truth


def test_reader_parses_flaser_robotlaser_and_odom(tmp_path: Path) -> None:
    log = tmp_path / "hand.log"
    log.write_text(
        "PARAM robot_front_laser_max 50 nohost 0\n"
        "FLASER 4 1.0 2.0 3.0 50.0 1.5 -2.0 0.5 1.4 -2.1 0.6 12.5 host 12.6\n"
        "ROBOTLASER1 0 -1.5708 3.1416 0.7854 30.0 0.01 0 5 1 2 3 4 5 0 1.0 2.0 0.1 0.9 2.0 0.1 "
        "0 0 0 0 0 13.0 host 13.1\n"
        "ODOM 1.0 2.0 0.3 0.1 0.0 0.0 14.0 host 14.1\n"
        "RAWLASER1 0 -1.57 3.14 0.5 30 0.01 0 3 1 2 3 0 15.0 host 15.1\n")
    parsed = read_carmen(log)
    assert parsed.problems == []
    f, r = parsed.scans
    assert np.array_equal(f.ranges, [1.0, 2.0, 3.0, 50.0]) and f.pose == Pose(1.5, -2.0, 0.5)
    assert f.odom == Pose(1.4, -2.1, 0.6) and f.stamp == 12.5 and f.line == 2
    # 4 beams over 180 degrees: -90, -30, 30, 90
    assert np.allclose(np.degrees(f.angles), [-90.0, -30.0, 30.0, 90.0])
    assert np.allclose(r.angles, -1.5708 + 0.7854 * np.arange(5)) and r.range_max == 30.0
    assert r.pose == Pose(1.0, 2.0, 0.1) and r.odom == Pose(0.9, 2.0, 0.1) and r.stamp == 13.0
    assert parsed.odometry == [(14.0, Pose(1.0, 2.0, 0.3))]
    assert parsed.no_echo() == 50.0
    s = f.scan(range_max=2.5, no_echo=parsed.no_echo())
    assert s.ranges[0] == 1.0 and s.ranges[1] == 2.0 and s.ranges[2] == 2.5 and math.isnan(s.ranges[3])
    # CARMEN's beam spacing guesses
    assert np.allclose(np.degrees(flaser_angles(180))[[0, 1, -1]], [-90.0, -89.0, 89.0])
    assert np.allclose(np.degrees(flaser_angles(361))[[0, 1, -1]], [-90.0, -89.5, 90.0])


def _rawlaser(ranges: np.ndarray, stamp: float) -> str:
    """A RAWLASER1 line: 181 beams from -90 deg, 1 deg apart, 8 m, no remissions."""
    values = " ".join(f"{v:.3f}" for v in ranges)
    return (f"RAWLASER1 0 -1.570796 3.141593 0.017453 8.0 0.01 0 {len(ranges)} {values} 0 "
            f"{stamp:.6f} robotexp {stamp:.6f}")


def test_rawlaser_readings_are_placed_by_interpolated_odometry(tmp_path: Path) -> None:
    odom = [(10.0, Pose(0.0, 0.0, 3.0)), (12.0, Pose(2.0, -1.0, -3.0))]
    # halfway: x, y halfway; the heading the short way round (3 -> -3 rad through pi, not through 0)
    mid = odometry_at(odom, 11.0)
    assert mid is not None and (mid.x, mid.y) == (1.0, -0.5)
    assert mid.theta == pytest.approx(math.remainder(3.0 + (2 * math.pi - 6.0) / 2, 2 * math.pi))
    assert odometry_at(odom, 12.0) == odom[1][1] and odometry_at(odom, 9.9) is None and odometry_at([], 1.0) is None
    log = tmp_path / "raw.log"
    log.write_text("PARAM robot_frontlaser_offset 0.2 nohost 0\n"
                   "ODOM 0.0 0.0 0.0 0 0 0 10.0 host 10.0\n"
                   "ODOM 2.0 0.0 1.0 0 0 0 12.0 host 12.0\n"
                   + _rawlaser(np.full(181, 3.0), 11.0) + "\n"
                   + _rawlaser(np.full(181, 3.0), 13.0) + "\n")
    parsed = read_carmen(log)
    (scan,) = parsed.scans                      # the reading at 13 s lies after the last ODOM line
    assert scan.odom == Pose(1.0, 0.0, 0.5) and scan.range_max == 8.0 and scan.stamp == 11.0
    assert scan.pose.x == pytest.approx(1.0 + 0.2 * math.cos(0.5))          # 0.2 m ahead: the laser's offset
    assert scan.pose.y == pytest.approx(0.2 * math.sin(0.5))
    assert np.allclose(np.degrees(scan.angles)[[0, 90, 180]], [-90.0, 0.0, 90.0], atol=0.01)   # 6 decimals
    assert parsed.problems == [f"{log}: 1 of 2 RAWLASER1 readings lie outside the ODOM lines' time span "
                               "(no pose for them): left out"]
    # without ODOM lines nothing can be placed: one line, exit 2, nothing written
    bare = tmp_path / "bare.log"
    bare.write_text(_rawlaser(np.full(181, 3.0), 11.0) + "\n")
    res = CliRunner().invoke(main, ["map", str(bare), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "1 RAWLASER1 readings but no ODOM line to place them" in res.output
    assert not (tmp_path / "o").exists()


def test_map_command_maps_a_rawlaser_log_placed_by_odometry(tmp_path: Path) -> None:
    """RAWLASER1 readings halfway between ODOM lines along the corridor of `dense`: mapped where the world
    has its walls, and scan matching recovers the perturbed path as it does for FLASER logs."""
    world = builtin_world("dense")
    index = RayIndex(world.boxes, world.discs, 2.0)
    angles = flaser_angles(181)
    truth = loop_path()
    lines = []
    for k, p in enumerate(truth):
        lines.append(f"ODOM {p.x:.6f} {p.y:.6f} {p.theta:.6f} 0 0 0 {k:.3f} robotexp {k:.3f}")
        if k + 1 < len(truth):
            q = odometry_at([(float(k), p), (k + 1.0, truth[k + 1])], k + 0.5)
            assert q is not None
            frac = index.cast(np.tile([q.x, q.y], (181, 1)), q.theta + angles, REACH, 0.3)
            lines.append(_rawlaser(np.where(frac >= 1.0, 81.91, frac * REACH), k + 0.5))
    log = tmp_path / "raw-sim.log"
    log.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["map", str(log), "--out", str(out), "--odometry-noise", "0.02,1"])
    assert res.exit_code == 0, res.output
    rec = json.loads((out / "results.jsonl").read_text())
    assert rec["scans"] == len(truth) - 1 and rec["odometry_ate_m"] > 2.0 and rec["ate_m"] < 0.3
    values, geo = load_ros_grid(out / "raw-sim.yaml")
    r, c = geo.cell_of(0.0, 8.5)                                     # the north wall's face at x = 0
    assert (values[r - 3:r + 4, c - 3:c + 4] == 100).any()


def test_malformed_lines_are_reported_with_file_and_line_and_skipped(tmp_path: Path) -> None:
    log = tmp_path / "bad.log.gz"
    simulated_log(log, gz=True, junk=True)
    parsed = read_carmen(log)
    assert len(parsed.scans) == len(loop_path())
    assert len(parsed.problems) == 2
    assert parsed.problems[0].startswith(f"{log}:11: malformed FLASER line skipped")
    assert parsed.problems[1].startswith(f"{log}:12: malformed ODOM line skipped")
    truncated = tmp_path / "cut.log.gz"
    truncated.write_bytes(log.read_bytes()[:300])
    with pytest.raises(ConfigError, match="truncated"):
        read_carmen(truncated)


def test_perturbed_path_drifts_by_the_noise() -> None:
    straight = [Pose(0.1 * k, 0.0, 0.0) for k in range(101)]          # 10 m east
    odom = perturb_path(straight, OdometryNoise(0.02, math.radians(1.0)), seed=0)
    assert odom[0] == straight[0]
    # systematic 1 deg/m over 10 m plus random of the same size per step: about 10 deg
    assert math.degrees(odom[-1].theta) == pytest.approx(10.0, abs=1.5)
    assert perturb_path(straight, OdometryNoise(), 0) == straight


def test_map_command_recovers_the_path_and_writes_a_loadable_map(tmp_path: Path) -> None:
    log = tmp_path / "dense-sim.log"
    truth = simulated_log(log)
    out = tmp_path / "out"
    runner = CliRunner()
    raw = runner.invoke(main, ["map", str(log), "--out", str(out), "--odometry-noise", "0.02,1",
                               "--localize", "none", "--cell", "0.05"])
    assert raw.exit_code == 0, raw.output
    fixed = runner.invoke(main, ["map", str(log), "--out", str(out), "--odometry-noise", "0.02,1",
                                 "--localize", "scan-match", "--cell", "0.05"])
    assert fixed.exit_code == 0, fixed.output
    first, second = (json.loads(line) for line in (out / "results.jsonl").read_text().splitlines())
    assert first["localize"] == "none" and second["localize"] == "scan-match" and second["loop_closure"]
    assert first["ate_m"] == first["odometry_ate_m"] > 2.0          # odometry alone drifts metres
    # scan matching keeps the path within the target of the real logs; its shape is right to two cells
    # (the whole path turns by the heading the matcher loses where walls run out of the mapped part);
    # along a corridor no loop edge is trusted
    assert second["ate_m"] < 0.3 and second["ate_rigid_m"] < 0.1
    assert second["matches"]["loop-edges"] == 0
    assert second["matches"]["matched"] + second["matches"].get("degenerate", 0) == len(truth) - 1
    assert fixed.output.strip().endswith(f"ATE {second['ate_m']:.3f} m")
    assert second["scans"] == len(truth) and second["ate_alignment"] == "none"
    # the second map of the log in `out` has its own name: the first is kept
    assert (first["run"], second["run"]) == ("dense-sim", "dense-sim_2")
    assert (out / "dense-sim.yaml").is_file() and (out / "dense-sim.png").is_file()
    # the map is a ROS map and a world: the corridor's walls are where the world has them
    values, geo = load_ros_grid(out / "dense-sim_2.yaml")
    r, c = geo.cell_of(0.0, 8.5)                                     # the north wall's face at x = 0
    assert (values[r - 3:r + 4, c - 3:c + 4] == 100).any()
    r, c = geo.cell_of(0.0, 7.5)                                     # the middle of the corridor
    assert values[r, c] == 0
    world = load_ros_world(out / "dense-sim_2.yaml")
    assert len(world.boxes) > 0 and (out / "dense-sim_2.png").stat().st_size > 1000


def test_map_command_rejects_bad_input(tmp_path: Path) -> None:
    log = tmp_path / "x.log"
    log.write_text("PARAM a b\n")
    runner = CliRunner()
    res = runner.invoke(main, ["map", str(log), "--out", str(tmp_path / "o"), "--odometry-noise", "2%"])
    assert res.exit_code == 2 and "DIST,DEG_PER_M" in res.output
    res = runner.invoke(main, ["map", str(log), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "no FLASER, ROBOTLASER1 or RAWLASER1 line" in res.output
    assert not (tmp_path / "o" / "results.jsonl").exists()
    assert ate([[0.0, 0.0]], [[0.0, 0.0]]) == 0.0
    # a path 280 x 240 m across: too many 5 cm cells, and the command names the cell that fits
    far = tmp_path / "campus.log"
    far.write_text("".join(format_flaser(np.full(181, 5.0), p, p, float(k)) + "\n"
                           for k, p in enumerate([Pose(0.0, 0.0, 0.0), Pose(280.0, 240.0, 0.0)])))
    res = runner.invoke(main, ["map", str(far), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "campus.log" in res.output and "use a larger --cell (0.1 m fits)" in res.output
    assert not (tmp_path / "o" / "results.jsonl").exists()


def corridor_lines(n: int = 30) -> list[str]:
    """FLASER lines (181 beams, no echo: 81.91 m) along the corridor of `dense`, 0.15 m apart."""
    world = builtin_world("dense")
    index = RayIndex(world.boxes, world.discs, 2.0)
    angles = flaser_angles(181)
    lines = []
    for k in range(n):
        p = Pose(-8.0 + 0.15 * k, 7.5, 0.0)
        frac = index.cast(np.tile([p.x, p.y], (181, 1)), p.theta + angles, REACH, 0.3)
        lines.append(format_flaser(np.where(frac >= 1.0, 81.91, frac * REACH), p, p, float(k)))
    return lines


def test_a_log_whose_scans_have_no_beam_is_refused_in_one_line(tmp_path: Path) -> None:
    log = tmp_path / "z.log"
    log.write_text("FLASER 0 0 0 0 0 0 0 1 h 1\n" * 3)
    parsed = read_carmen(log)
    assert len(parsed.scans) == 3 and parsed.problems == [] and parsed.no_echo() == math.inf
    out = tmp_path / "o"
    res = CliRunner().invoke(main, ["map", str(log), "-o", str(out)])
    assert res.exit_code == 2, res.output
    assert res.output == (f"robotexp: error: {log}: no laser beams to map: its 3 laser readings have 0 beams each; "
                          "give a log whose laser lines carry ranges\n")
    assert not out.exists()                                       # nothing left of the map that failed


def test_a_second_map_in_a_folder_gets_its_own_name(tmp_path: Path) -> None:
    log = tmp_path / "base.log"
    log.write_text("\n".join(corridor_lines()) + "\n")
    out = tmp_path / "mm"
    runner = CliRunner()
    first = runner.invoke(main, ["map", str(log), "-o", str(out), "--localize", "none"])
    assert first.exit_code == 0, first.output
    kept = {f: (out / f).read_bytes() for f in ("base.png", "base.pgm", "base.yaml")}
    second = runner.invoke(main, ["map", str(log), "-o", str(out), "--localize", "none", "--cell", "0.2"])
    assert second.exit_code == 0, second.output
    assert f"map: {out / 'base_2.png'}, {out / 'base_2.yaml'}" in second.output
    assert all((out / f).read_bytes() == data for f, data in kept.items())       # the first map is untouched
    records = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert [(r["run"], r["cell_m"]) for r in records] == [("base", 0.05), ("base_2", 0.2)]
    values, geo = load_ros_grid(out / "base_2.yaml")
    assert geo.cell == 0.2 and "image: base_2.pgm" in (out / "base_2.yaml").read_text()
    # nothing but the maps and the records: the name's claim file is gone
    assert sorted(f.name for f in out.iterdir()) == ["base.pgm", "base.png", "base.yaml", "base_2.pgm",
                                                     "base_2.png", "base_2.yaml", "results.jsonl"]


def test_the_output_folder_and_names_are_checked_before_the_log_is_read(tmp_path: Path) -> None:
    runner = CliRunner()
    bad = tmp_path / "bad.log"                          # refused when read: an error about it means it was read
    bad.write_text("FLASER 0 0 0 0 0 0 0 1 h 1\n")
    blocker = tmp_path / "file"
    blocker.write_text("")
    res = runner.invoke(main, ["map", str(bad), "-o", str(blocker / "o")])
    assert res.exit_code == 2 and res.output.count("\n") == 1 and f"--out {blocker / 'o'}: cannot write" in res.output
    out = tmp_path / "o"
    (out / "results.jsonl").mkdir(parents=True)
    res = runner.invoke(main, ["map", str(bad), "-o", str(out)])
    assert res.exit_code == 2 and res.output.count("\n") == 1 and "results.jsonl: is a folder" in res.output
    assert sorted(f.name for f in out.iterdir()) == ["results.jsonl"]
    # a name whose files are in the way (folders, an earlier map's YAML without its PNG) is passed over
    log = tmp_path / "base.log"
    log.write_text("\n".join(corridor_lines(10)) + "\n")
    out = tmp_path / "o2"
    (out / "base.yaml").mkdir(parents=True)
    (out / "base_2.png").mkdir()
    res = runner.invoke(main, ["map", str(log), "-o", str(out), "--localize", "none"])
    assert res.exit_code == 0, res.output
    assert json.loads((out / "results.jsonl").read_text())["run"] == "base_3"
    assert sorted(f.name for f in out.iterdir()) == ["base.yaml", "base_2.png", "base_3.pgm", "base_3.png",
                                                     "base_3.yaml", "results.jsonl"]
    # a map that fails leaves nothing in a folder that was there
    res = runner.invoke(main, ["map", str(bad), "-o", str(out)])
    assert res.exit_code == 2 and "no laser beams to map" in res.output
    assert sorted(f.name for f in out.iterdir()) == ["base.yaml", "base_2.png", "base_3.pgm", "base_3.png",
                                                     "base_3.yaml", "results.jsonl"]


def test_a_line_too_long_is_refused_without_being_read_whole(tmp_path: Path) -> None:
    import tracemalloc

    log = tmp_path / "b.log.gz"
    log.write_bytes(gzip.compress(b"# " + b"x" * (64 * 2**20) + b"\n", 9))
    tracemalloc.start()
    try:
        with pytest.raises(ConfigError, match=r"b\.log\.gz:1: a line longer than 1 MiB"):
            read_carmen(log)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 8 * 2**20                                        # [bytes] a few MiB, not the 64 MiB line
    res = CliRunner().invoke(main, ["map", str(log), "-o", str(tmp_path / "o")])
    assert res.exit_code == 2 and res.output.count("\n") == 1 and "give a CARMEN log" in res.output
    # the line number is the one of the long line; a long comment line is as long a line
    plain = tmp_path / "p.log"
    plain.write_text("\n".join(corridor_lines(2)) + "\n#" + "x" * 2**20 + "\n")
    with pytest.raises(ConfigError, match=r"p\.log:3: a line longer than 1 MiB"):
        read_carmen(plain)
    plain.write_text("\n".join(corridor_lines(2)) + "\n#" + "x" * (2**20 - 1) + "\n")     # 1 MiB: kept
    assert len(read_carmen(plain).scans) == 2


def test_the_readings_a_log_may_hold_are_bounded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from robotexp.localization import carmen

    assert carmen.MAX_SCANS == 1_000_000 and carmen.MAX_BEAMS == 250_000_000
    log = tmp_path / "many.log.gz"
    line = corridor_lines(1)[0]
    log.write_bytes(gzip.compress(((line + "\n") * 6 + "ODOM 0 0 0 0 0 0 1 h 1\n" * 4).encode()))
    assert len(read_carmen(log).scans) == 6
    monkeypatch.setattr(carmen, "MAX_SCANS", 5)
    with pytest.raises(ConfigError, match=r"many\.log\.gz:6: more than 5 laser readings \(about 4 hours at 75 Hz\)"):
        read_carmen(log)
    res = CliRunner().invoke(main, ["map", str(log), "-o", str(tmp_path / "o")])
    assert res.exit_code == 2 and res.output.count("\n") == 1 and "split the log" in res.output
    monkeypatch.setattr(carmen, "MAX_SCANS", 1_000_000)
    monkeypatch.setattr(carmen, "MAX_BEAMS", 181 * 3)
    with pytest.raises(ConfigError, match=r"many\.log\.gz:4: more than 543 laser beams in all"):
        read_carmen(log)
    monkeypatch.setattr(carmen, "MAX_BEAMS", 250_000_000)
    monkeypatch.setattr(carmen, "MAX_ODOM", 3)
    with pytest.raises(ConfigError, match=r"many\.log\.gz:10: more than 3 ODOM lines"):
        read_carmen(log)
    monkeypatch.setattr(carmen, "MAX_ODOM", 5_000_000)
    monkeypatch.setattr(carmen, "MAX_PROBLEMS", 2)
    junk = tmp_path / "junk.log"
    junk.write_text("ODOM 1 2\n" * 5)
    with pytest.raises(ConfigError, match=r"junk\.log:3: more than 2 malformed lines"):
        read_carmen(junk)


def test_a_laser_line_whose_counts_do_not_match_its_values_is_skipped(tmp_path: Path) -> None:
    lines = corridor_lines()
    good = tmp_path / "good.log"
    good.write_text("\n".join(lines) + "\n")
    # 180 ranges where the line says 170: read by its count, ten ranges would be taken as the pose
    fields = lines[5].split()
    fields[1] = "170"
    corrupt = lines[:5] + [" ".join(fields)] + lines[5:]
    robot = ("ROBOTLASER1 0 -1.5708 3.1416 0.7854 30.0 0.01 0 4 1 2 3 4 5 0 1.0 2.0 0.1 0.9 2.0 0.1 "
             "0 0 0 0 0 13.0 host 13.1")                    # 5 ranges where it says 4: the 5th read as a count
    raw = "RAWLASER1 0 -1.57 3.14 0.5 30 0.01 0 3 1 2 3 1 4 5 15.0 host 15.1"   # 2 remissions where it says 1
    bad = tmp_path / "bad.log"
    bad.write_text("\n".join(corrupt + [robot, raw]) + "\n")
    parsed = read_carmen(bad)
    assert len(parsed.scans) == len(lines) and parsed.raw == []
    assert parsed.problems == [
        f"{bad}:6: malformed FLASER line skipped: it has 192 fields where a FLASER line of 170 beams has 181: "
        "the counts do not match the values (a corrupt line)",
        f"{bad}:{len(lines) + 2}: malformed ROBOTLASER1 line skipped: it has 29 fields where a ROBOTLASER1 line "
        "of 4 beams and 5 remissions has 33: the counts do not match the values (a corrupt line)",
        f"{bad}:{len(lines) + 3}: malformed RAWLASER1 line skipped: it has 18 fields where a RAWLASER1 line "
        "of 3 beams and 1 remissions has 17: the counts do not match the values (a corrupt line)"]
    runner = CliRunner()
    ok = runner.invoke(main, ["map", str(good), "-o", str(tmp_path / "o"), "--localize", "none"])
    res = runner.invoke(main, ["map", str(bad), "-o", str(tmp_path / "o"), "--localize", "none"])
    assert ok.exit_code == 0 and res.exit_code == 0, res.output
    assert f"robotexp: {bad}:6: malformed FLASER line skipped" in res.stderr
    first, second = (json.loads(x) for x in (tmp_path / "o" / "results.jsonl").read_text().splitlines())
    assert second["malformed_lines"] == 3 and second["scans"] == first["scans"]
    assert second["ate_m"] == first["ate_m"] == 0.0


def test_a_laser_max_param_that_is_no_range_is_reported_and_ignored(tmp_path: Path) -> None:
    lines = corridor_lines()
    log = tmp_path / "neg.log"
    log.write_text("\n".join(["PARAM robot_front_laser_max -1 nohost 0", "PARAM robot_frontlaser_offset nan nohost 0"]
                             + lines) + "\n")
    parsed = read_carmen(log)
    assert parsed.problems == [f"{log}:1: PARAM robot_front_laser_max -1 is not a positive range [m]: ignored",
                               f"{log}:2: PARAM robot_frontlaser_offset nan is not a finite offset [m]: ignored"]
    assert parsed.params == {} and parsed.no_echo() == pytest.approx(81.91)      # the saturated reading
    for value in ("0", "inf", "nan", "x"):
        assert read_with_laser_max(tmp_path, value).no_echo() == pytest.approx(81.91)
    out = tmp_path / "o"
    res = CliRunner().invoke(main, ["map", str(log), "-o", str(out), "--localize", "none"])
    assert res.exit_code == 0, res.output
    assert f"robotexp: {log}:1: PARAM robot_front_laser_max -1 is not a positive range [m]: ignored" in res.stderr
    values, geo = load_ros_grid(out / "neg.yaml")
    assert (values == 100).sum() > 100 and (values == 0).sum() > 1000         # walls and free space, not unknown


def read_with_laser_max(tmp_path: Path, value: str) -> CarmenLog:
    """A log of the corridor whose `robot_front_laser_max` PARAM is `value`, read."""
    log = tmp_path / f"max-{value}.log"
    log.write_text("\n".join([f"PARAM robot_front_laser_max {value} nohost 0"] + corridor_lines(3)) + "\n")
    parsed = read_carmen(log)
    assert len(parsed.problems) == 1 and parsed.problems[0].startswith(f"{log}:1: PARAM robot_front_laser_max")
    return parsed
