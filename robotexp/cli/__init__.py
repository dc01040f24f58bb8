"""The `robotexp` command line: one module per command or command group (`robotexp.cli.main` assembles
them); the helpers every command shares are in `robotexp.cli.common`."""

from __future__ import annotations

from robotexp.cli.main import main

__all__ = ["main"]
