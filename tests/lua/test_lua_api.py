"""Every function of the IfTEA API, through the real lupa runtime, against the written results."""

from __future__ import annotations

import json
import math
import re
from typing import Any

import numpy as np
import pytest
from PIL import Image

from robotexp.errors import ScriptError
from robotexp.lua import parse_address
from robotexp.registry import EXPLORERS, available, lua_name
from robotexp.output.render import COLORS

SHORT = 'exploration.setWorld("ufmg-static")\nexploration.setMaxTime(6000)\n'


def load(path):
    with Image.open(path) as img:
        return img.convert("RGB")


def records(runner):
    return [json.loads(line) for line in (runner.out / "results.jsonl").read_text().splitlines()]


def test_print_and_exploration_method_lists_every_installed_plugin(lua):
    lua('for k, v in pairs(ExplorationMethod) do print(k .. "=" .. v) end\nprint("a", 1, nil, true)')
    expected = {f"{lua_name(n)}={n}" for n in available(EXPLORERS)}
    assert set(lua.lines[:-1]) == expected and "FRONTIER=frontier" in expected
    assert lua.lines[-1] == "a\t1\tnil\ttrue"


def test_settings_reach_the_run_record(lua):
    lua(SHORT + """
robot.setAddress("")
robot.setMaxSpeed(200)
robot.setMaxLaserRange(2500)
robot.setModel("kobuki")
exploration.setSeed(3)
exploration.setCellSize(50)
exploration.setMethod(ExplorationMethod.FRONTIER)
exploration.setParameter("replan_period", 0.5)
robot.moveMobileSim(-4000, -4000, 90)
exploration.start()
exploration.wait()
local r = exploration.results()
print(exploration.elapsedTime(), robot.pathLength(), exploration.getMethod())
print(r.max_speed_m_s, r.laser_range_m, r.seed, r.cell_m, r.robot, r.script, type(r.start_pose))
print(r.start_pose[1], r.start_pose[2], r.start_pose[3])
""")
    (rec,) = records(lua)
    elapsed, path_mm, method = lua.lines[0].split("\t")
    assert int(elapsed) == round(rec["robot_time_s"] * 1000) == 6000
    assert float(path_mm) == pytest.approx(rec["path_length_m"] * 1000, abs=0.1) and rec["path_length_m"] > 0
    assert method == "frontier" == rec["method"]
    assert lua.lines[1].split("\t") == ["0.2", "2.5", "3", "0.05", "kobuki", "script.lua", "table"]
    x, y, th = map(float, lua.lines[2].split("\t"))
    assert (x, y, th) == pytest.approx((-4.0, -4.0, math.pi / 2))


def test_next_run_starts_where_the_last_ended(lua):
    lua(SHORT + """
exploration.start(); exploration.wait()
print(robot.getPose())
exploration.start()   -- wait() is implied by the next call that needs the result
print(exploration.elapsedTime())
""")
    first, second = records(lua)
    assert first["start_pose"] == pytest.approx([-4.2, -4.2, math.pi / 4])      # world's first pose
    x, y, th = map(float, lua.lines[0].split("\t"))
    assert second["start_pose"] == pytest.approx([x / 1000, y / 1000, math.radians(th)])
    assert math.hypot(x / 1000 + 4.2, y / 1000 + 4.2) > 0.05                    # it did move
    assert lua.lines[1] == "6000"


def test_armed_run_is_finished_at_script_end(lua):
    result = lua(SHORT + "exploration.start()\n")
    assert len(result.records) == 1 == len(records(lua))


def test_wrong_parameter_is_reported_by_start(lua):
    with pytest.raises(ScriptError, match=r"script.lua:3: exploration.start: .*frontier.*nonsense"):
        lua(SHORT + 'exploration.setParameter("nonsense", 1); exploration.start()')


def test_map_limits_and_potential_interval(lua):
    lua(SHORT + """
exploration.setMapLimits(-5000, -4500, 1000, 2500)
exploration.setPotentialUpdateInterval(500)   -- frontier has no potential: ignored
exploration.start(); exploration.wait()
""")
    (rec,) = records(lua)
    meta = (lua.out / f"{rec['run']}.map.yaml").read_text()
    with Image.open(lua.out / f"{rec['run']}.map.pgm") as pgm:
        size = pgm.size
    assert "origin: [-5.0, -4.5" in meta
    assert size == (60, 70)


def test_map_images_scale_zoom_path_and_tracking(lua):
    lua(SHORT + """
exploration.start(); exploration.wait()
mapView.setMapScaling(0.1)
mapView.saveMapImage("a.png")
robotView.setShowPath(false)
mapView.setShowGrid(true)
mapView.setShowVectorField(true)
mapView.setShowPotentialField(true)
robotView.setShowLaser(true)
mapView.saveMapImage("b.png")
mapView.zoomIn()
mapView.saveMapImage("sub/c.png")
robotView.setTracking(true)
mapView.saveMapImage("d.png")
mapView.zoomOut()
robotView.setTracking(false)
print(mapView.saveMapImage("e.png"))
""")
    a, b, c, d, e = (load(lua.out / n) for n in ("a.png", "b.png", "sub/c.png", "d.png", "e.png"))
    # figures (legend, axes): the map at 0.1 px/mm = 100 px/m, twice that zoomed in, the text with it
    assert a.size == e.size and abs(c.width - 2 * a.width) <= 2 and abs(c.height - 2 * a.height) <= 2
    assert d.size == (800, 600)                                  # tracking: the raster window around the robot
    blue = [int((np.asarray(img.convert("RGB")) == COLORS["path"]).all(axis=2).sum()) for img in (a, b)]
    assert blue[0] > 50 and blue[1] == 0
    assert lua.lines == [str(lua.out / "e.png")]


def test_map_figure_title_is_the_same_from_lua_and_the_cli(lua: Any) -> None:
    from click.testing import CliRunner

    from robotexp.cli import main

    lua(SHORT + 'exploration.start(); exploration.wait()\nmapView.saveMapImage("lua.svg")')
    svg = (lua.out / "lua.svg").read_text()
    out = lua.out / "cli"
    res = CliRunner().invoke(main, ["explore", "--world", "ufmg-static", "--method", "frontier", "--max-time", "6",
                                    "--out", str(out), "--image-format", "png,svg"])
    assert res.exit_code == 0, res.output
    (cli_svg,) = out.glob("*_s0.svg")
    title = re.compile(r"ufmg-static - frontier")
    assert title.search(svg) and title.search(cli_svg.read_text())
    assert "FrontierExplorer" not in svg
    for words in ("free", "occupied", "unknown", "path", "start", "end", "x [m]", "cell 100 mm"):
        assert words in svg and words in cli_svg.read_text(), words


def test_frames_are_saved_every_redraw_interval(lua):
    lua(SHORT + """
mapView.setFrameFolder("frames")
mapView.setRedrawInterval(2000)
exploration.start(); exploration.wait()
mapView.setFrameFolder(nil)
exploration.start(); exploration.wait()
""")
    frames = sorted(p.name for p in (lua.out / "frames").iterdir())
    # robot time 0, 2 and 4 s of a 6 s run
    assert frames == ["frame_000001.png", "frame_000002.png", "frame_000003.png"]


def test_address_kinds(lua, tmp_path):
    assert parse_address("") == parse_address(" sim ") == ("sim", "")
    assert parse_address("localhost") == ("tcp", "localhost:8101")
    assert parse_address("10.0.0.2:9000") == ("tcp", "10.0.0.2:9000")
    assert parse_address("/dev/ttyUSB0") == ("serial", "/dev/ttyUSB0") and parse_address("COM3") == ("serial", "COM3")
    # nothing connects before a run needs the robot
    lua('robot.setAddress(""); robot.setAddress("sim"); robot.setAddress("10.0.0.2:9000"); '
        'robot.setAddress("/dev/ttyUSB0")')
    missing = tmp_path / "no-such-tty"
    with pytest.raises(ScriptError, match=rf"^script.lua:2: robot.setAddress\('{missing}'\): cannot connect to a "
                                          rf"P3-DX \(serial {missing}\): .*robotexp emulate p3dx"):
        lua(f'robot.setAddress("{missing}")\nexploration.start()')
    with pytest.raises(ScriptError, match=r"port 1..65535"):
        lua('robot.setAddress("host:99999")')
    lua(SHORT + 'robot.setAddress("localhost"); robot.setAddress("/dev/ttyS0"); exploration.start()',
        world="ufmg-static")
    assert len(lua.notices) == 1 and "embedded simulator" in lua.notices[0]
    assert len(records(lua)) == 1


def test_output_folder_and_relative_files(lua):
    lua('local f = io.open("sub/x.txt", "w"); f:write("hi"); f:close(); print(exploration.outputFolder())\n'
        'for line in io.lines("sub/x.txt") do print(line) end')
    assert (lua.out / "sub" / "x.txt").read_text() == "hi"
    assert lua.lines == [str(lua.out), "hi"]


def test_os_exit_gives_the_exit_status(lua):
    assert lua("os.exit(3)\nprint('not reached')").exit_code == 3
    assert lua("os.exit(true)").exit_code == 0
    assert lua.lines == []
