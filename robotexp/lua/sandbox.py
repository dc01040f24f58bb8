"""What a script may touch: the Lua prelude that wraps the standard library, and the path rule.

Every path a script gives (io.open, io.lines, dofile, os.remove, mapView.saveMapImage, ...) is
relative to the output folder, as if the script ran there. With `--sandbox` a path must also
resolve (symbolic links followed) inside that folder, and os.execute, io.popen, os.tmpname,
package.loadlib, C-module searchers, binary chunks and most of `debug` are refused.

The prelude also installs the interrupt hook: every `HOOK_EVERY` Lua instructions it asks Python
whether the script must stop (Ctrl-C, --timeout, os.exit), and `pcall`, `xpcall` and
`coroutine.resume` re-raise that stop so a script cannot swallow it.
"""

from __future__ import annotations

import os
from pathlib import Path

from robotexp.errors import ScriptError

__all__ = ["PathPolicy", "PRELUDE", "HOOK_EVERY", "ABORT", "lua_kind"]

HOOK_EVERY = 10_000     # Lua instructions between two stop checks (~0.1 ms of Lua; ~1 % overhead)
ABORT = "\x00robotexp: script stopped"   # the error value of a stop; never shown to the user

_WRITE_MODES = ("w", "a", "+")


class PathPolicy:
    """Resolve the paths a script gives: relative to `out`; inside `out` only when `sandbox`.

    Args:
        out: the output folder (created on first write).
        sandbox: refuse every path outside `out`.
    """

    def __init__(self, out: Path, sandbox: bool) -> None:
        self.out = Path(out)
        self.sandbox = sandbox

    def resolve(self, path: object, mode: object, where: str) -> str:
        """The file-system path for the script's `path` opened with Lua `mode` by function `where`.

        Raises:
            ScriptError: `path` is not a string, or (sandbox) it leaves the output folder.
        """
        if isinstance(path, (int, float)) and not isinstance(path, bool):
            path = str(path)          # Lua coerces numbers to file names too
        if not isinstance(path, str) or not path:
            raise ScriptError(f"{where}: expected a file name (a non-empty string), got {lua_kind(path)}")
        full = Path(path) if os.path.isabs(path) else self.out / path
        writing = isinstance(mode, str) and any(c in mode for c in _WRITE_MODES)
        if self.sandbox:
            root = os.path.realpath(self.out)
            real = os.path.realpath(full)
            if os.path.commonpath([root, real]) != root:
                raise ScriptError(f"{where}({path!r}): refused by --sandbox: scripts may only use files "
                                  f"inside the output folder {self.out}")
        if writing:
            full.parent.mkdir(parents=True, exist_ok=True)
        return str(full)

    def refuse(self, what: str) -> None:
        """Raise the --sandbox refusal of `what` (os.execute, io.popen, ...)."""
        raise ScriptError(f"{what}: refused by --sandbox (scripts may not start programs, load C code or "
                          "reach outside the output folder); run without --sandbox to allow it")


def lua_kind(value: object) -> str:
    """What a value from Lua is, for error messages: "nil", "a number", "a table", ..."""
    if value is None:
        return "nil"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    from lupa import lua_type  # type: ignore[import-untyped]
    return f"a {lua_type(value) or 'Python value'}"


# Arguments: check (-> true to stop), resolve(path, mode, where), refuse(what), emit(text),
# exit(code), api {table = {name = python function}}, methods {LUA_NAME = plugin name},
# sandbox (boolean), every (instructions between hook calls), abort (the stop marker),
# script_dir (string: prepended to package.path when not sandboxed), out (the output folder).
PRELUDE = r"""
local check, resolve, refuse, emit, exit_request, api, methods, sandbox, every, ABORT, script_dir, out = ...
local pack, unpack, concat = table.pack, table.unpack, table.concat
local raw_pcall, raw_xpcall, tostring, error, select, pairs, type = pcall, xpcall, tostring, error, select, pairs, type
local sethook = debug.sethook

local stopping = false
local function aborting()
  if not stopping and check() then stopping = true end
  return stopping
end
local function hook()
  if aborting() then error(ABORT, 0) end
end
sethook(hook, "", every)

-- a Python function as a plain Lua function; errors become strings at the caller's line
local function wrap(f, level)
  return function(...)
    local r = pack(raw_pcall(f, ...))
    if r[1] then return unpack(r, 2, r.n) end
    if aborting() then error(ABORT, 0) end
    error(tostring(r[2]), level)
  end
end

for tname, funcs in pairs(api) do
  local t = {}
  for fname, f in pairs(funcs) do t[fname] = wrap(f, 2) end
  _G[tname] = t
end
local em = {}
for k, v in pairs(methods) do em[k] = v end
ExplorationMethod = em

-- a stop (Ctrl-C, --timeout, os.exit) cannot be caught
local function pass(r)
  if not r[1] and aborting() then error(ABORT, 0) end
  return unpack(r, 1, r.n)
end
pcall = function(...) return pass(pack(raw_pcall(...))) end
xpcall = function(...) return pass(pack(raw_xpcall(...))) end
local co_create, co_resume, co_close = coroutine.create, coroutine.resume, coroutine.close
coroutine.create = function(f)
  local co = co_create(f)
  sethook(co, hook, "", every)
  return co
end
coroutine.resume = function(...) return pass(pack(co_resume(...))) end
coroutine.wrap = function(f)
  local co = coroutine.create(f)
  return function(...)
    local r = pack(co_resume(co, ...))
    if r[1] then return unpack(r, 2, r.n) end
    if co_close then co_close(co) end
    if aborting() then error(ABORT, 0) end
    error(r[2], 0)
  end
end
debug.sethook = function()
  error("debug.sethook is reserved by robotexp (it stops scripts on Ctrl-C and --timeout)", 2)
end

print = function(...)
  local n, parts = select("#", ...), {}
  for i = 1, n do parts[i] = tostring((select(i, ...))) end
  emit(concat(parts, "\t"))
end
local exit_py = wrap(exit_request, 3)
os.exit = function(code)
  exit_py(code)
  error(ABORT, 0)
end

-- paths are relative to the output folder; --sandbox keeps them inside it
local path_of = wrap(resolve, 3)
local io_open, io_lines, io_input, io_output = io.open, io.lines, io.input, io.output
local raw_loadfile, raw_dofile, raw_load = loadfile, dofile, load
local os_remove, os_rename = os.remove, os.rename
io.open = function(name, mode) return io_open(path_of(name, mode or "r", "io.open"), mode) end
io.lines = function(name, ...)
  if name == nil then return io_lines() end
  return io_lines(path_of(name, "r", "io.lines"), ...)
end
io.input = function(f)
  if type(f) == "string" then return io_input(path_of(f, "r", "io.input")) end
  return io_input(f)
end
io.output = function(f)
  if type(f) == "string" then return io_output(path_of(f, "w", "io.output")) end
  return io_output(f)
end
os.remove = function(name) return os_remove(path_of(name, "w", "os.remove")) end
os.rename = function(a, b) return os_rename(path_of(a, "w", "os.rename"), path_of(b, "w", "os.rename")) end
local text_only = sandbox and "t" or nil
loadfile = function(name, mode, ...)
  if name == nil then return raw_loadfile(nil, text_only or mode, ...) end
  return raw_loadfile(path_of(name, "r", "loadfile"), text_only or mode, ...)
end
dofile = function(name)
  if name == nil then return raw_dofile() end
  local f = assert(raw_loadfile(path_of(name, "r", "dofile"), text_only))
  return f()
end

if sandbox then
  local refused = wrap(refuse, 3)
  local function no(what) return function() refused(what) end end
  os.execute = no("os.execute")
  os.tmpname = no("os.tmpname")
  io.popen = no("io.popen")
  package.loadlib = no("package.loadlib")
  load = function(chunk, name, mode, env) return raw_load(chunk, name, "t", env) end
  package.cpath = ""
  package.path = out .. "/?.lua;" .. out .. "/?/init.lua"
  local preload = package.searchers[1]
  local searchpath = package.searchpath
  package.searchers = {
    preload,
    function(name)
      local file, err = searchpath(name, package.path)
      if not file then return err end
      local f = assert(raw_loadfile(path_of(file, "r", "require"), "t"))
      return f, file
    end,
  }
  local tb, gi = debug.traceback, debug.getinfo
  debug = {traceback = tb, getinfo = gi}
  package.loaded.debug = debug
elseif script_dir ~= "" then
  package.path = script_dir .. "/?.lua;" .. package.path
end
"""
