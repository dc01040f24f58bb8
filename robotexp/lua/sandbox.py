"""What a script may touch: the Lua prelude that wraps the standard library, and the path rule.

Every path a script gives (io.open, io.lines, dofile, os.remove, mapView.saveMapImage, ...) is
relative to the output folder, as if the script ran there. With `--sandbox` a path must also
resolve (symbolic links followed) inside that folder, and os.execute, io.popen, os.tmpname,
package.loadlib, C-module searchers, binary chunks and most of `debug` are refused. Whatever the
options, robotexp's records (results.jsonl, its `.torn` file, the folder lock) are not the script's
to write, remove or rename (`PathPolicy`), and with a write limit (`--max-write`, on by default
with `--sandbox`) every byte the script writes to a file is counted (`WriteQuota`).

A robot address a script gives (robot.setAddress) goes through `AddressPolicy`: with `--sandbox`
only "" / "sim" or an address the user named on the command line (`--allow-address`, a host:port
or a device path) is accepted, never a pyserial URL (spy:// writes files, socket:// and
rfc2217:// reach the network, loop:// / alt:// / hwgrep:// / cp2110:// pick devices).

The prelude also installs the interrupt hook: every `HOOK_EVERY` Lua instructions it asks Python
whether the script must stop (Ctrl-C, --timeout, os.exit), and `pcall`, `xpcall` and
`coroutine.resume` re-raise that stop so a script cannot swallow it. The debug functions that
reach into other functions (getupvalue, setupvalue, upvaluejoin, getlocal, setlocal,
getregistry) refuse robotexp's own functions (those made while the script runs, such as the one
`coroutine.wrap` returns, too), so the raw sethook and the hook's state stay out of reach even
without `--sandbox`; the metatables shared by every Python object (lupa's) and by every file read
as locked and cannot be replaced, and `print` hands Python text only (bytes that are not UTF-8
become U+FFFD), so no Python object reaches the script. What the hook cannot see (a finalizer, a long pattern match, a
message handler that loops) is stopped from outside: `robotexp run` runs the script in a child
process and kills it at the deadline (`robotexp.lua.supervise`).
"""

from __future__ import annotations

import math

import os
import re
import unicodedata
from pathlib import Path

from robotexp.errors import ConfigError, ScriptError
from robotexp.output.safefile import LOCK_NAME

__all__ = ["AddressPolicy", "PathPolicy", "WriteQuota", "PRELUDE", "HOOK_EVERY", "ABORT", "lua_kind",
           "parameter_args"]

HOOK_EVERY = 10_000     # Lua instructions between two stop checks (~0.1 ms of Lua; ~1 % overhead)
ABORT = "\x00robotexp: script stopped"   # the error value of a stop; never shown to the user

_WRITE_MODES = ("w", "a", "+")
RECORDS = "results.jsonl"   # robotexp's record file; it, its `.torn` file and the folder lock are not the script's
_HOST_PORT = re.compile(r"^([A-Za-z0-9][A-Za-z0-9.-]*|\[[0-9A-Fa-f:]+\]):(\d{1,5})$")
_HOST = re.compile(r"^[A-Za-z0-9][A-Za-z0-9.-]*$")
_DEVICE = re.compile(r"^/[A-Za-z0-9_./+-]+$")
DEFAULT_PORT = 8101     # a bare host is MobileSim's TCP port (as robotexp.lua.api.parse_address)


def _normal_address(address: str) -> str | None:
    """`address` in one spelling ("host:port" or a resolved device path), or None when it is
    neither a host[:port] nor a plain device path (a pyserial URL, a query, spaces, ...)."""
    a = address.strip()
    m = _HOST_PORT.match(a)
    if m:
        port = int(m.group(2))
        return f"{m.group(1).lower()}:{port}" if 1 <= port <= 65535 else None
    if _HOST.match(a):
        return f"{a.lower()}:{DEFAULT_PORT}"
    if _DEVICE.match(a) and "/../" not in a + "/":
        return os.path.realpath(a)
    return None


class AddressPolicy:
    """Which robot (and laser) addresses a script may open.

    Without a sandbox every address is the script's to choose. With one, only "" / "sim" (the
    embedded simulator) and the addresses of `allowed` (given by the user on the command line) are
    accepted, compared in one spelling (`_normal_address`): "host" is "host:8101", a device path is
    compared after resolving its symbolic links. A pyserial URL is never accepted in a sandbox,
    even when named: its handlers open files (spy://), sockets (socket://, rfc2217://) or search
    devices (hwgrep://) on their own.

    Args:
        sandbox: apply the rule.
        allowed: the addresses the user allowed (each a host[:port] or a device path).

    Raises:
        ConfigError: an allowed address that is not a host[:port] or a device path.
    """

    def __init__(self, sandbox: bool, allowed: tuple[str, ...] | list[str] = ()) -> None:

        self.sandbox = sandbox
        self.allowed: dict[str, str] = {}
        for a in allowed:
            key = _normal_address(a)
            if key is None:
                raise ConfigError(f"--allow-address {a!r}: expected host, host:port (port 1..65535) or a device "
                                  "path such as /dev/ttyUSB0; pyserial URLs (socket://, spy://, ...) are never "
                                  "allowed in a sandbox")
            self.allowed[key] = a

    def check(self, address: str, where: str) -> None:
        """Accept `address` given by the script to `where`, or refuse it.

        Raises:
            ScriptError: (sandbox) the address is neither the simulator nor one the user allowed.
        """
        if not self.sandbox or address.strip() in ("", "sim"):
            return
        key = _normal_address(address)
        if key is None or key not in self.allowed:
            named = ", ".join(sorted(self.allowed.values())) or "none"
            raise ScriptError(f"{where}({address!r}): refused by --sandbox: a sandboxed script may use the "
                              "simulator ('' or 'sim') or an address given with --allow-address "
                              f"(allowed: {named})")


def _protected(name: str) -> bool:
    """True for a file name of robotexp's records: results.jsonl, its `.torn` file (any
    `results.jsonl.*`) and the folder lock, in any letter case or Unicode spelling."""
    key = unicodedata.normalize("NFKC", name).casefold()
    return key.startswith(RECORDS) or key == LOCK_NAME


class PathPolicy:
    """Resolve the paths a script gives: relative to `out`; inside `out` only when `sandbox`.

    Whatever the options, a script may not write, create, remove or rename robotexp's records
    (results.jsonl, results.jsonl.torn, the folder lock), wherever they are: a path whose name, or
    the name of a folder on its way, is one of them is refused for writing, as written and after
    `..` and symbolic links are resolved; so is renaming a folder that holds one.

    Args:
        out: the output folder (created on first write).
        sandbox: refuse every path outside `out`.
        max_write: [bytes] what the script may write in all (`WriteQuota`; None: no limit).
    """

    def __init__(self, out: Path, sandbox: bool, max_write: int | None = None) -> None:
        self.out = Path(out)
        self.sandbox = sandbox
        self.quota = WriteQuota(max_write)

    def _guard_records(self, path: str, full: Path, where: str) -> None:
        """Refuse writing `full` (the script's `path`) when it names robotexp's records."""
        spellings = (os.path.normpath(full), os.path.realpath(full))
        if any(_protected(part) for spelling in spellings for part in Path(spelling).parts):
            raise ScriptError(f"{where}({path!r}): refused: scripts may not write, remove or rename robotexp's "
                              "records (results.jsonl, results.jsonl.torn, .robotexp.lock)")
        if os.path.isdir(full):
            for _, dirs, files in os.walk(full):
                if any(_protected(n) for n in dirs + files):
                    raise ScriptError(f"{where}({path!r}): refused: the folder holds robotexp's records "
                                      "(results.jsonl); scripts may not move or remove them")

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
            self._guard_records(path, full, where)
            full.parent.mkdir(parents=True, exist_ok=True)
        return str(full)

    def refuse(self, what: str) -> None:
        """Raise the --sandbox refusal of `what` (os.execute, io.popen, ...)."""
        raise ScriptError(f"{what}: refused by --sandbox (scripts may not start programs, load C code or "
                          "reach outside the output folder); run without --sandbox to allow it")


class WriteQuota:
    """The bytes a script may write to files (`robotexp run --max-write`).

    The script's file writes (file:write, io.write) ask for bytes in grants of up to `GRANT` bytes
    (the prelude counts them down without calling Python), and each file the script creates costs
    `FILE_COST` bytes (what a file takes on disk at least); the images the script saves
    (mapView.saveMapImage) are counted at their size once written. A write the remaining bytes do
    not cover is refused with an error, and so is every one after it.

    Args:
        limit: [bytes] the limit, or None for none.
    """

    GRANT = 65536           # [bytes] asked for at once by the prelude's write wrapper
    FILE_COST = 4096        # [bytes] charged for each file the script creates

    def __init__(self, limit: int | None) -> None:
        self.limit = limit
        self.used = 0       # [bytes] written or granted

    def grant(self, need: object, where: object = "file:write") -> int:
        """Charge `need` bytes about to be written; return how many more the caller may write
        without asking again (0 without a limit: the prelude does not count then).

        Raises:
            ScriptError: the limit does not cover `need`.
        """
        if self.limit is None:
            return 0
        n = int(need) if isinstance(need, (int, float)) and need >= 0 else 0
        left = self.limit - self.used
        if n > left:
            self.used = self.limit        # nothing more: every later write is refused too
            raise ScriptError(f"{where}: refused: the script's files reached its --max-write limit of "
                              f"{self.limit / 2**20:g} MB; raise it with --max-write MB if the script needs more")
        extra = min(self.GRANT, left - n)
        self.used += n + extra
        return extra

    def charge(self, n: int) -> None:
        """Count `n` bytes written by robotexp for the script (a saved image)."""
        if self.limit is not None:
            self.used = min(self.used + max(n, 0), self.limit)

    def check(self, where: str) -> None:
        """Refuse a write when nothing is left (before robotexp writes a file for the script).

        Raises:
            ScriptError: the limit is reached.
        """
        if self.limit is not None and self.used >= self.limit:
            self.grant(1, where)


def parameter_args(fname: str, args: tuple[object, ...]) -> tuple[str, object]:
    """The (name, value) of a plugin parameter call, `fname(name, value)` (exploration.setParameter,
    team.setCoordinatorParameter): a parameter name and a number, boolean or string; ScriptError naming
    `fname` otherwise (the plugin checks names, types and ranges when it is made)."""
    if len(args) == 2 and isinstance(args[0], str) and (
            isinstance(args[1], (bool, int, str)) or (isinstance(args[1], float) and math.isfinite(args[1]))):
        name, value = args[0], args[1]
        if not name.isidentifier():
            raise ScriptError(f"{fname}({name!r}, ...): expected a parameter name")
        return name, value
    got = ", ".join(lua_kind(a) for a in args) or "nothing"
    raise ScriptError(f"{fname}(name, value): expected a parameter name (string) and a number, boolean or string, "
                      f"got {got}")


def lua_kind(value: object) -> str:
    """What a value from Lua is, for error messages: "nil", the number itself ("1.5", "nan"), "a table", ..."""
    if value is None:
        return "nil"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, float) and not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")     # 0/0, 1/0, -1/0
    if isinstance(value, (int, float)):
        text = repr(value)
        return text if len(text) <= 24 else f"{value:.6g}"     # the number itself: "got 1.5", not "a number"
    if isinstance(value, str):
        return "a string"
    from lupa import lua_type  # type: ignore[import-untyped]
    return f"a {lua_type(value) or 'Python value'}"


# Arguments: check (-> true to stop), resolve(path, mode, where), refuse(what), emit(text),
# exit(code), api {table = {name = python function}}, methods {LUA_NAME = plugin name},
# sandbox (boolean), every (instructions between hook calls), abort (the stop marker),
# script_dir (string: prepended to package.path when not sandboxed), out (the output folder),
# grant(bytes, where) (-> more bytes the script may write; `WriteQuota.grant`), counting (boolean:
# count the script's file writes against a limit).
PRELUDE = r"""
local check, resolve, refuse, emit, exit_request, api, methods, sandbox, every, ABORT, script_dir, out,
      grant, counting = ...
local pack, unpack, concat = table.pack, table.unpack, table.concat
local raw_pcall, raw_xpcall, tostring, error, select, pairs, type = pcall, xpcall, tostring, error, select, pairs, type
local rawequal, s_find, s_sub, utf8_len = rawequal, string.find, string.sub, utf8.len
local sethook = debug.sethook
local d_getupvalue, d_getinfo, d_setupvalue, d_upvaluejoin, d_getlocal, d_setlocal =
    debug.getupvalue, debug.getinfo, debug.setupvalue, debug.upvaluejoin, debug.getlocal, debug.setlocal
local d_getmetatable, d_setmetatable = debug.getmetatable, debug.setmetatable
-- robotexp's own Lua functions, closed to the debug library (filled below; a function made while the
-- script runs, such as coroutine.wrap's, is added when it is made)
local guarded = setmetatable({}, {__mode = "k"})

-- the metatables of Python objects (lupa's, shared by all of them) and of files are robotexp's: a
-- script that changed them would change every call into Python (the stop check) or every file write
local LOCKED = "robotexp: locked"
local python_mt = d_getmetatable(check)
local file_mt = d_getmetatable(io.stdout)
python_mt.__metatable = LOCKED
file_mt.__metatable = LOCKED

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
  local function resume(...)
    local r = pack(co_resume(co, ...))
    if r[1] then return unpack(r, 2, r.n) end
    if co_close then co_close(co) end
    if aborting() then error(ABORT, 0) end
    error(r[2], 0)
  end
  guarded[resume] = true      -- its upvalues (aborting, error) are the hook's
  return resume
end
debug.sethook = function()
  error("debug.sethook is reserved by robotexp (it stops scripts on Ctrl-C and --timeout)", 2)
end

-- text for Python: every byte sequence that is not UTF-8 becomes U+FFFD
local function utf8_text(s)
  if utf8_len(s) then return s end
  local parts, i = {}, 1
  while true do
    local n, bad = utf8_len(s, i)
    if n then parts[#parts + 1] = s_sub(s, i); break end
    parts[#parts + 1] = s_sub(s, i, bad - 1)
    parts[#parts + 1] = "\u{FFFD}"
    i = bad + 1
  end
  return concat(parts)
end
local emit_py = wrap(emit, 3)
print = function(...)
  local n, parts = select("#", ...), {}
  for i = 1, n do parts[i] = tostring((select(i, ...))) end
  emit_py(utf8_text(concat(parts, "\t")))
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
local io_stdout, io_stderr, f_write = io.stdout, io.stderr, file_mt.__index.write
-- with a write limit (--max-write) every byte written to a file is counted: up to `budget` bytes
-- without asking Python, then a new grant; each file created costs what one takes on disk at least
local budget, FILE_COST = 0, 4096
local function take(n, where)
  if n <= budget then budget = budget - n; return nil end
  local ok, r = raw_pcall(grant, n, where)
  if ok then budget = r; return nil end
  if aborting() then error(ABORT, 0) end
  return tostring(r)
end
local function count(where, f, ...)
  if not counting or rawequal(f, io_stdout) or rawequal(f, io_stderr) then return nil end
  local args, n = pack(...), 0
  for i = 1, args.n do
    local kind = type(args[i])
    if kind == "string" then n = n + #args[i] elseif kind == "number" then n = n + 24 end
  end
  return take(n, where)
end
local function create_cost(full, mode, where)
  if not counting or type(mode) ~= "string" or not s_find(mode, "[wa+]") then return end
  local f = io_open(full, "rb")
  if f then f:close(); return end
  local e = take(FILE_COST, where)
  if e then error(e, 3) end
end
if counting then
  file_mt.__index.write = function(f, ...)
    local e = count("file:write", f, ...)
    if e then error(e, 2) end
    return f_write(f, ...)
  end
  io.write = function(...)
    local f = io_output()
    local e = count("io.write", f, ...)
    if e then error(e, 2) end
    return f_write(f, ...)
  end
end
io.open = function(name, mode)
  local full = path_of(name, mode or "r", "io.open")
  create_cost(full, mode, "io.open")
  return io_open(full, mode)
end
io.lines = function(name, ...)
  if name == nil then return io_lines() end
  return io_lines(path_of(name, "r", "io.lines"), ...)
end
io.input = function(f)
  if type(f) == "string" then return io_input(path_of(f, "r", "io.input")) end
  return io_input(f)
end
io.output = function(f)
  if type(f) == "string" then
    local full = path_of(f, "w", "io.output")
    create_cost(full, "w", "io.output")
    return io_output(full)
  end
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
  load = function(chunk, name, mode, ...)
    if select("#", ...) == 0 then return raw_load(chunk, name, "t") end   -- no env: the globals
    return raw_load(chunk, name, "t", (...))
  end
  os.getenv = function() return nil end     -- the user's environment is not the script's business
  package.cpath = ""
  package.path = out .. "/?.lua;" .. out .. "/?/init.lua"
  local preload = package.searchers[1]
  -- a file outside the output folder is "not found" whether or not it exists
  local function searchpath(name, path, sep, rep)
    if type(name) ~= "string" or type(path) ~= "string" then
      error("package.searchpath(name, path): expected two strings", 2)
    end
    sep, rep = sep or ".", rep or "/"
    if sep ~= "" then name = name:gsub(sep:gsub("%p", "%%%0"), (rep:gsub("%%", "%%%%"))) end
    local tried = {}
    for template in path:gmatch("[^;]+") do
      local file = template:gsub("%?", (name:gsub("%%", "%%%%")))
      local ok, full = raw_pcall(resolve, file, "r", "package.searchpath")
      local f = ok and io_open(full, "r")
      if f then f:close(); return file end
      tried[#tried + 1] = "no file '" .. file .. "'"
    end
    return nil, concat(tried, "\n\t")
  end
  package.searchpath = searchpath
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

-- robotexp's own functions (the hook, its state, the wrappers) are closed to the debug library:
-- every Lua function reachable from the globals now, and every one in their upvalues, was made
-- here (the script has not run yet)
local dbg = debug
local seen = {}
local function collect(v)
  if seen[v] then return end
  local kind = type(v)
  if kind == "table" then
    seen[v] = true
    for _, x in pairs(v) do collect(x) end
  elseif kind == "function" then
    seen[v] = true
    if d_getinfo(v, "S").what ~= "C" then guarded[v] = true end
    local i = 1
    while true do
      local up, x = d_getupvalue(v, i)
      if up == nil then break end
      if type(x) == "function" then collect(x) end
      i = i + 1
    end
  end
end
collect(_G)
collect(file_mt)
for _, f in ipairs({hook, aborting, wrap, pass, path_of, take, count}) do collect(f) end
seen = nil
if dbg.getupvalue then
  local function closed(what, level)
    error(what .. ": robotexp's own functions are closed to scripts (they stop the script on Ctrl-C and "
          .. "--timeout)", level or 3)
  end
  -- the function running at a stack level given to getlocal/setlocal (1 = the caller of the wrapper)
  local function frame(what, a, b)
    local info
    if type(a) == "thread" then
      if type(b) == "number" then info = d_getinfo(a, b, "f") end
    elseif type(a) == "number" then
      info = d_getinfo(a + 2, "f")
    end
    if info and guarded[info.func] then closed(what, 4) end
  end
  dbg.getupvalue = function(f, n)
    if guarded[f] then closed("debug.getupvalue") end
    return d_getupvalue(f, n)
  end
  dbg.setupvalue = function(f, n, v)
    if guarded[f] then closed("debug.setupvalue") end
    return d_setupvalue(f, n, v)
  end
  dbg.upvaluejoin = function(f1, n1, f2, n2)
    if guarded[f1] or guarded[f2] then closed("debug.upvaluejoin") end
    return d_upvaluejoin(f1, n1, f2, n2)
  end
  -- getlocal / setlocal: refused on a frame of robotexp's own; a level counts from the caller
  local function level_guarded(what, raw)
    return function(a, b, ...)
      frame(what, a, b)
      if type(a) == "number" then
        local r = pack(raw(a + 1, b, ...))
        return unpack(r, 1, r.n)
      end
      return raw(a, b, ...)
    end
  end
  dbg.getlocal = level_guarded("debug.getlocal", d_getlocal)
  dbg.setlocal = level_guarded("debug.setlocal", d_setlocal)
  dbg.getregistry = function()
    error("debug.getregistry is reserved by robotexp (the registry holds the hook that stops scripts)", 2)
  end
  -- the metatables of Python objects and files read as locked and cannot be replaced
  local function ours(v)
    local mt = d_getmetatable(v)
    return rawequal(mt, python_mt) or rawequal(mt, file_mt)
  end
  dbg.getmetatable = function(v)
    if ours(v) then return LOCKED end
    return d_getmetatable(v)
  end
  dbg.setmetatable = function(v, mt)
    if ours(v) then closed("debug.setmetatable") end
    return d_setmetatable(v, mt)
  end
  for _, name in ipairs({"getupvalue", "setupvalue", "upvaluejoin", "getlocal", "setlocal", "getregistry",
                         "getmetatable", "setmetatable"}) do
    guarded[dbg[name]] = true
  end
end
"""
