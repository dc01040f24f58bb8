"""Scripts cannot reach Python internals; --sandbox refuses programs, C code and outside files."""

from __future__ import annotations

import pytest

from robotexp.errors import ScriptError


def test_no_python_escape_hatches(lua):
    lua("print(python, package.loaded.python, type(robot.setAddress), type(exploration))")
    assert lua.lines == ["nil\tnil\tfunction\ttable"]
    for code in ("python.eval('1')", "robot.setAddress.__class__", "return exploration.start.__globals__"):
        with pytest.raises(ScriptError):
            lua(code)


def test_attribute_walk_on_a_raw_python_function_is_refused(lua):
    # a Python callable dug out of a wrapper's upvalues still shows no attributes
    code = """
local f
for i = 1, 30 do
  local _, v = debug.getupvalue(robot.setAddress, i)
  if type(v) == "userdata" then f = v end
end
assert(f ~= nil, "no Python callable found")
print(f.__class__)
"""
    with pytest.raises(ScriptError, match="scripts cannot reach Python attributes"):
        lua(code)


def test_debug_sethook_is_reserved(lua):
    with pytest.raises(ScriptError, match=r"script.lua:1: debug.sethook is reserved by robotexp"):
        lua("debug.sethook()")


@pytest.mark.parametrize(("code", "what"), [
    ('os.execute("echo hi")', "os.execute"),
    ('io.popen("ls")', "io.popen"),
    ("os.tmpname()", "os.tmpname"),
    ('package.loadlib("libc.so.6", "puts")', "package.loadlib"),
    ('io.open("/tmp/robotexp_sandbox_test.txt", "w")', "io.open"),
    ('io.open("../escape.txt", "w")', "io.open"),
    ('io.lines("/etc/passwd")', "io.lines"),
    ('dofile("/etc/hostname")', "dofile"),
    ('os.remove("../x")', "os.remove"),
    ('mapView.saveMapImage("/tmp/x.png")', "mapView.saveMapImage"),
])
def test_sandbox_refuses(lua, code, what):
    with pytest.raises(ScriptError, match=rf"^script.lua:1: {what}.*refused by --sandbox"):
        lua(code, sandbox=True)


def test_sandbox_refuses_c_modules_and_binary_chunks(lua):
    lua('print(package.cpath, #package.searchers, debug.getregistry, debug.getupvalue)\n'
        'print(load(string.dump(function() end)))\n'
        'print(pcall(require, "socket.core"))', sandbox=True)
    assert lua.lines[0] == "\t2\tnil\tnil"
    assert "attempt to load a binary chunk" in lua.lines[1]
    assert lua.lines[2].startswith("false\t") and "socket.core" in lua.lines[2]


def test_sandbox_allows_the_output_folder(lua):
    lua('local f = assert(io.open("inside.txt", "w")); f:write("ok"); f:close()\n'
        'local g = io.open("' + str(lua.out / "abs.txt") + '", "w"); g:write("ok2"); g:close()\n'
        'local m = io.open("mod.lua", "w"); m:write("return 7"); m:close()\n'
        'print(require("mod"), dofile("mod.lua"))', sandbox=True)
    assert (lua.out / "inside.txt").read_text() == "ok" and (lua.out / "abs.txt").read_text() == "ok2"
    assert lua.lines == ["7\t7"]
