"""Run small Lua scripts through the real lupa runtime."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from robotexp.lua import ScriptResult, run_script


class Runner:
    """Writes a script into tmp_path and runs it; keeps what it printed and the notices."""

    def __init__(self, tmp_path: Path) -> None:
        self.tmp = tmp_path
        self.out = tmp_path / "out"
        self.lines: list[str] = []
        self.notices: list[str] = []

    def __call__(self, code: str, name: str = "script.lua", on_print: Callable[[str], None] | None = None,
                 **kwargs: Any) -> ScriptResult:
        """Run `code`; `on_print(line)` is called (in the script's thread, which it holds) after each printed line."""
        path = self.tmp / name
        path.write_text(code)
        kwargs.setdefault("out", self.out)

        def emit(line: str) -> None:
            self.lines.append(line)
            if on_print is not None:
                on_print(line)

        return run_script(path, emit=emit, notice=self.notices.append, **kwargs)


@pytest.fixture
def lua(tmp_path: Path) -> Callable[..., ScriptResult]:
    return Runner(tmp_path)
