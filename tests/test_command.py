"""The `robotexp` program's entry point: a Ctrl-C or SIGTERM while the command line is still loading (its
imports take a few tenths of a second) ends as one during a command does: one line, exit 130 or 143."""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

# The child loads the `robotexp` console script as installed, with an import hook that raises the signal's
# exception the moment NumPy is first imported: a Ctrl-C (or SIGTERM) landing while the command loads.
_CHILD = """
import signal, sys
from importlib.metadata import entry_points

which = sys.argv[1]

class Interrupt:
    def find_spec(self, name, path=None, target=None):
        if name == "numpy":
            if which == "int":
                raise KeyboardInterrupt
            signal.raise_signal(signal.SIGTERM)
        return None

sys.meta_path.insert(0, Interrupt())
sys.argv = ["robotexp", "worlds"]
(script,) = [e for e in entry_points(group="console_scripts") if e.name == "robotexp"]
script.load()()
"""


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize(("which", "code", "line"), [("int", 130, "robotexp: interrupted"),
                                                     ("term", 143, "robotexp: terminated (SIGTERM)")])
def test_a_signal_while_the_command_line_loads_is_one_line(which: str, code: int, line: str) -> None:
    proc = subprocess.run([sys.executable, "-c", _CHILD, which], capture_output=True, text=True, timeout=60,
                          preexec_fn=_default_sigint)
    assert proc.returncode == code, proc.stderr
    assert proc.stderr == line + "\n"
    assert proc.stdout == ""

