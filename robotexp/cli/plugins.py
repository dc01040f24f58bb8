"""`robotexp plugins`: the installed explorers, robots and emulators."""

from __future__ import annotations

import click

from robotexp.cli.common import handle_errors

__all__ = ["plugins"]

@click.command()
@handle_errors
def plugins() -> None:
    """List the explorers, robot backends and their emulators found through entry points."""
    from robotexp.registry import COORDINATORS, EMULATORS, EXPLORERS, ROBOTS, available, lua_name

    for title, group in (("explorers", EXPLORERS), ("robots", ROBOTS), ("emulators", EMULATORS),
                         ("coordinators", COORDINATORS)):
        click.echo(f"{title} ({group}):")
        for info in available(group).values():
            extra = f"  Lua: ExplorationMethod.{lua_name(info.name)}" if group == EXPLORERS else ""
            click.echo(f"  {info.name:16s} {info.target:45s} {info.distribution} {info.version}{extra}")
