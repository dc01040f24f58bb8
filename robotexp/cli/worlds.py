"""`robotexp worlds` (the built-in worlds and their start poses) and `robotexp worlds generate` (a procedural
world written as a ROS map or an ARIA `.map`)."""

from __future__ import annotations

import math
from pathlib import Path

import click

from robotexp.cli.common import fail, handle_errors
from robotexp.errors import ConfigError, WorldError
from robotexp.world.generate import DEFAULT_SIZES, KINDS, write_generated

__all__ = ["generate", "worlds"]


@click.group(invoke_without_command=True)
@click.pass_context
@handle_errors
def worlds(ctx: click.Context) -> None:
    """List the built-in worlds with their sizes and start poses (`worlds generate`: make one)."""
    from robotexp.world.builtin import builtin_names, builtin_world

    if ctx.invoked_subcommand is not None:
        return
    for name in builtin_names():
        w = builtin_world(name)
        width, height = w.size
        click.echo(f"{name:14s} {width:5.1f} x {height:4.1f} m  {len(w.poses)} start poses  {w.description}")
        # the poses --pose takes by name, with where they are (x, y in mm, heading in degrees, as --pose reads them)
        click.echo("  poses: " + ", ".join(f"{key} ({p.x * 1000:.0f},{p.y * 1000:.0f},{math.degrees(p.theta):.0f})"
                                           for key, p in w.poses.items()))


def _size(text: str | None) -> tuple[float, float] | None:
    """(width, height) [m] of 'WxH'; ConfigError when malformed."""
    if text is None:
        return None
    parts = text.lower().split("x")
    try:
        if len(parts) != 2:
            raise ValueError
        return float(parts[0]), float(parts[1])
    except ValueError:
        raise ConfigError(f"--size {text!r}: expected WIDTHxHEIGHT in metres, e.g. 30x20") from None


@worlds.command()
@click.option("--kind", required=True, type=click.Choice(KINDS), help="What to build.")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="The same seed gives the same file.")
@click.option("--size", default=None, metavar="WxH",
              help="Building size [m] (default: " + ", ".join(f"{k} {w:g}x{h:g}" for k, (w, h) in
                                                            DEFAULT_SIZES.items()) + ").")
@click.option("--scanned", is_flag=True, help="Artefacts of laser-built maps: thin and broken walls, gaps to the "
                                              "outside, unknown space around the building (a building has them "
                                              "always).")
@click.option("--out", "out", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="FILE.yaml (ROS map_server, with FILE.pgm) or FILE.map (ARIA points).")
def generate(kind: str, seed: int, size: str | None, scanned: bool, out: Path) -> None:
    """Generate a floor plan (office, warehouse, cave, or a building drawn from real buildings' measured doors,
    corridors, rooms, clutter and laser noise) with rooms, doors, furniture, pillars and clutter."""
    try:
        files = write_generated(out, kind, seed, _size(size), scanned=scanned)
    except (ConfigError, WorldError) as exc:
        fail(str(exc), 2)
    click.echo(" ".join(str(f) for f in files))
