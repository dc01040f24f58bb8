"""The command line's reading of a script and of its options: a script file is read as Lua reads it (byte
order mark, #! line, Latin-1, a size bound), every error is one line of bounded length, and --world and
--robot are checked before the script starts. (Not timed: these run beside other tests.)"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from robotexp.errors import ConfigError


def test_an_error_is_one_line_of_bounded_length(tmp_path):
    """A message with line breaks, or echoing a 10 MB argument, is still one line of about 2000 characters:
    breaks escaped, the middle left out."""
    script = tmp_path / "s.lua"
    script.write_text("error('multi\\nline\\27[2Jmessage')")
    result = subprocess.run([sys.executable, "-m", "robotexp.cli", "run", str(script), "--out", str(tmp_path / "o")],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 1 and result.stderr == "robotexp: error: s.lua:1: multi\\nline\\x1b[2Jmessage\n"
    script.write_text('exploration.setMethod(("x"):rep(1e7))')
    result = subprocess.run([sys.executable, "-m", "robotexp.cli", "run", str(script), "--out", str(tmp_path / "o")],
                            capture_output=True, text=True, timeout=120)
    (line,) = result.stderr.splitlines()
    assert result.returncode == 1 and len(line) < 2100, len(line)
    assert line.startswith("robotexp: error: s.lua:1: exploration.setMethod") and "characters left out" in line
    assert line.endswith("ExplorationMethod.WAYPOINTS"), line[-300:]        # what to do is kept


def test_script_files_as_lua_reads_them(tmp_path):
    """A byte order mark and a #! line are left out (line numbers kept), a Latin-1 file runs, and a file of
    more than 16 MB (or /dev/zero) is refused before it is read whole."""
    from robotexp.lua.runtime import read_script

    bom, shebang, latin = tmp_path / "bom.lua", tmp_path / "sh.lua", tmp_path / "latin.lua"
    bom.write_bytes(b"\xef\xbb\xbfprint(1)\n")
    shebang.write_bytes(b"#!/usr/bin/env lua\nprint(2)\nerror('x')\n")
    latin.write_bytes('print("caf\u00e9, a\u00e7\u00e3o")\n'.encode("latin-1"))
    assert read_script(bom) == "print(1)\n" and read_script(shebang) == "\nprint(2)\nerror('x')\n"
    runs = [subprocess.run([sys.executable, "-m", "robotexp.cli", "run", str(p), "--out", str(tmp_path / "o")],
                           capture_output=True, text=True, timeout=120) for p in (bom, shebang, latin)]
    assert [r.returncode for r in runs] == [0, 1, 0], [r.stderr for r in runs]
    assert runs[0].stdout == "1\n" and runs[1].stdout == "2\n" and "sh.lua:3: x" in runs[1].stderr
    assert runs[2].stdout == "caf\u00e9, a\u00e7\u00e3o\n"
    big = tmp_path / "big.lua"
    with open(big, "wb") as f:
        f.truncate(20 * 2**20)
    for path in (big, Path("/dev/zero")):
        with pytest.raises(ConfigError, match=r"the script is larger than 16 MB"):
            read_script(path)
    res = subprocess.run([sys.executable, "-m", "robotexp.cli", "run", "/dev/zero", "--out", str(tmp_path / "o")],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "larger than 16 MB" in res.stderr


def test_run_options_are_checked_before_the_script_starts(tmp_path):
    """--world and --robot name things the script cannot change: a bad one is one line, exit 2, before the
    script writes anything."""
    script = tmp_path / "s.lua"
    script.write_text('local f = io.open("notes.txt", "w"); f:write("x"); f:close()\n'
                      'exploration.setMaxTime(5); exploration.start(); exploration.wait()')
    out = tmp_path / "out"
    for option, value, words in (("--world", "nope", "--world: unknown world 'nope'"),
                                 ("--world", "generated:office:0:100000x100000", "--world: generated world: size"),
                                 ("--robot", "r2d2", "--robot: unknown robot preset 'r2d2'")):
        res = subprocess.run([sys.executable, "-m", "robotexp.cli", "run", str(script), "--out", str(out), option,
                              value], capture_output=True, text=True, timeout=120)
        assert res.returncode == 2 and res.stderr.count("\n") == 1 and words in res.stderr, res.stderr
        assert not (out / "notes.txt").exists()
