"""The sandbox has no way out, checked in-process (not timed: these run beside other tests): pyserial URLs,
the addresses a script may open, a map's image outside the output folder, minor leaks, errors without a
message, map limits and images too large to draw."""

from __future__ import annotations

import json
import os
import pkgutil
from pathlib import Path

import pytest
import serial.urlhandler
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.errors import ConfigError, ScriptError
from robotexp.lua.sandbox import AddressPolicy

SCHEMES = sorted(m.name[len("protocol_"):] for m in pkgutil.iter_modules(serial.urlhandler.__path__)
                 if m.name.startswith("protocol_"))


def test_every_pyserial_url_is_refused_in_the_sandbox(lua, tmp_path):
    assert {"spy", "socket", "rfc2217", "loop", "alt", "hwgrep"} <= set(SCHEMES)
    victim, fresh = tmp_path / "victim.txt", tmp_path / "fresh.txt"
    victim.write_text("keep me")
    addresses = []
    for scheme in SCHEMES:
        addresses += [f"{scheme}://{victim}?file={victim}&raw=:8101", f"{scheme}:///dev/null?file={fresh}",
                      f"{scheme}://127.0.0.1:8101", f"{scheme}://{fresh}"]
    addresses += [f"/dev/null?file={fresh}:8101", "127.0.0.1:8101", "localhost", "/dev/ttyS0", str(victim)]
    code = "local refused = 0\n"
    for a in addresses:
        code += (f"local ok, e = pcall(robot.setAddress, {json.dumps(a)})\n"
                 "if not ok and e:find('refused by --sandbox', 1, true) then refused = refused + 1 end\n"
                 "pcall(robot.getPose)\n")
    code += "print(refused)"
    lua(code, sandbox=True, allow_addresses=("127.0.0.1:9",))
    assert lua.lines == [str(len(addresses))]
    assert victim.read_text() == "keep me" and not fresh.exists()


def test_allowed_addresses_in_one_spelling(lua):
    policy = AddressPolicy(True, ("127.0.0.1", "/dev/null"))
    policy.check("127.0.0.1:8101", "robot.setAddress")
    policy.check("/dev/null", "robot.setAddress")
    for bad in ("127.0.0.1:8102", "socket://127.0.0.1:8101", "/dev/zero", "/dev/null?x"):
        with pytest.raises(ScriptError, match="refused by --sandbox.*allowed: /dev/null, 127.0.0.1"):
            policy.check(bad, "robot.setAddress")
    for url in ("spy:///dev/null?file=/tmp/x", "socket://h:1", "h:99999"):
        with pytest.raises(ConfigError, match="--allow-address"):
            AddressPolicy(True, (url,))
    # an allowed address reaches the connection attempt (nothing listens on port 9)
    with pytest.raises(ScriptError, match=r"robot.setAddress\('127.0.0.1:9'\): cannot connect"):
        lua('robot.setAddress("127.0.0.1:9"); robot.getPose()', sandbox=True, allow_addresses=("127.0.0.1:9",))


def test_allow_address_is_checked_on_the_command_line(tmp_path):
    script = tmp_path / "s.lua"
    script.write_text("print(1)")
    result = CliRunner().invoke(main, ["run", str(script), "--out", str(tmp_path / "o"), "--sandbox",
                                       "--allow-address", "spy:///dev/null?file=/tmp/x"])
    assert result.exit_code == 2 and result.output.count("\n") == 1 and "--allow-address" in result.output


def _pgm(path: Path) -> None:
    path.write_bytes(b"P5\n2 2\n255\n" + bytes([0, 254, 254, 0]))


@pytest.mark.parametrize("image", ["../secret.pgm", "{tmp}/secret.pgm", "/nonexistent/secret.pgm", "link.pgm"])
def test_a_map_yaml_cannot_name_an_image_outside_the_output_folder(lua, tmp_path, image):
    _pgm(tmp_path / "secret.pgm")
    lua.out.mkdir()
    (lua.out / "link.pgm").symlink_to(tmp_path / "secret.pgm")
    code = ('local f = io.open("m.yaml", "w"); f:write("image: ' + image.format(tmp=tmp_path) + '\\n'
            'resolution: 0.1\\norigin: [0, 0, 0]\\nnegate: 0\\noccupied_thresh: 0.65\\nfree_thresh: 0.196\\n")\n'
            'f:close(); exploration.setWorld("m.yaml")')
    with pytest.raises(ScriptError) as err:
        lua(code, sandbox=True)
    # the same refusal whether the outside file exists or not: nothing was read
    assert "exploration.setWorld('m.yaml'): the map's image" in str(err.value)
    assert "refused by --sandbox" in str(err.value)


def test_a_map_yaml_with_its_image_inside_loads(lua):
    lua.out.mkdir()
    _pgm(lua.out / "m.pgm")
    lua('local f = io.open("m.yaml", "w"); f:write("image: m.pgm\\nresolution: 0.5\\norigin: [0, 0, 0]\\n'
        'negate: 0\\noccupied_thresh: 0.65\\nfree_thresh: 0.196\\n"); f:close(); exploration.setWorld("m.yaml")\n'
        'print("loaded")', sandbox=True)
    assert lua.lines == ["loaded"]



@pytest.mark.parametrize("code", ["error({})", "error(nil)", "error()", "error(setmetatable({}, {}))"])
def test_errors_without_a_message_still_say_something(lua, code):
    with pytest.raises(ScriptError, match=r"^s.lua: the script raised an error without a message"):
        lua(code, name="s.lua")


def test_sandbox_minor_leaks(lua, tmp_path):
    (tmp_path / "exists.lua").write_text("return 1")
    lua('print(load("return 1 + 1")(), load("return x", "c", "t", {x = 3})(), os.getenv("HOME"), os.getenv("PATH"))\n'
        f'local a = select(2, package.searchpath("exists", "{tmp_path}/?.lua"))\n'
        f'local b = select(2, package.searchpath("absent", "{tmp_path}/?.lua"))\n'
        'print(a:gsub("exists", "X") == b:gsub("absent", "X"), package.searchpath("exists", "/etc/?"))\n'
        'local f = io.open("mod.lua", "w"); f:write("return 1"); f:close()\n'
        'print(package.searchpath("mod", package.path) ~= nil)', sandbox=True)
    assert lua.lines == ["2\t3\tnil\tnil", "true\tnil\tno file '/etc/exists'", "true"]
    assert os.environ.get("HOME")


def test_map_limits_that_do_not_fit_are_refused_before_the_run(lua):
    # the Lua memory cap does not see numpy: the size is checked before any array is made
    with pytest.raises(ScriptError, match=r"exploration.start: map limits .* make 1.6e\+17 cells of 5 mm, more than"):
        lua("exploration.setMapLimits(-1e9, -1e9, 1e9, 1e9); exploration.setCellSize(5); exploration.start()",
            sandbox=True)
    assert not (lua.out / "results.jsonl").exists()


@pytest.mark.parametrize("view", ["mapView.setMapScaling(1000)", "for i = 1, 2000 do mapView.zoomIn() end"])
def test_a_map_image_too_large_is_refused_before_it_is_drawn(lua, view):
    with pytest.raises(ScriptError, match=r"mapView: the map image would be .* px, more than 1e\+08 pixels"):
        lua('exploration.setWorld("dense"); exploration.setMaxTime(1000); exploration.start(); exploration.wait()\n'
            f'{view}; mapView.saveMapImage("x.png")', sandbox=True)
    assert not (lua.out / "x.png").exists() and (lua.out / "results.jsonl").exists()
