"""Scripts cannot reach Python internals; --sandbox refuses programs, C code and outside files."""

from __future__ import annotations

import pytest

from robotexp.errors import ScriptError


def test_no_python_escape_hatches(lua):
    lua("print(python, package.loaded.python, type(robot.setAddress), type(exploration))")
    assert lua.lines == ["nil\tnil\tfunction\ttable"]
    for code in ("python.eval('1')", "local c = robot.setAddress.__class__", "return exploration.start.__globals__"):
        with pytest.raises(ScriptError):
            lua(code)


@pytest.mark.parametrize("code", [
    "debug.getupvalue(robot.setAddress, 1)",                # the raw Python callable behind a wrapper
    "debug.getupvalue(coroutine.create, 2)",                # the raw sethook
    "debug.setupvalue(pcall, 1, function() end)",
    "debug.upvaluejoin(pcall, 1, function() return x end, 1)",
    "debug.getregistry()",                                  # the hook table
    "local h = debug.gethook(); debug.getupvalue(h, 1)",    # the hook's state (the stop flag, the check)
    # a local of robotexp's pcall (level 3: 1 the function, 2 Lua's own pcall); pcall returns the refusal
    "local ok, e = pcall(function() debug.setlocal(3, 1, nil) end); error(e, 0)",
])
def test_debug_cannot_reach_robotexp_functions(lua, code):
    # without --sandbox too: the raw sethook and the hook's state would let a script remove its stop
    with pytest.raises(ScriptError, match=r"script.lua:1: debug.(getupvalue|setupvalue|upvaluejoin|getregistry|"
                                          r"setlocal).*(closed to scripts|reserved by robotexp)"):
        lua(code)


def test_debug_still_works_on_the_scripts_own_functions(lua):
    lua("local a = 5; local function f() return a end\n"
        "local n1, v1 = debug.getupvalue(f, 1); local n2, v2 = debug.getlocal(1, 1); print(n1, v1, n2, v2)\n"
        "debug.setupvalue(f, 1, 6); print(f())")
    assert lua.lines == ["a\t5\ta\t5", "6"]


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
