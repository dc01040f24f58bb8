"""The commands `robotexp replay` (rebuild a recording's map and metrics) and `robotexp video`.

robotexp.cli registers them at its end, so its helpers are already defined when this module loads."""

from __future__ import annotations

from pathlib import Path

import click

from robotexp.cli import handle_errors, writable_folder
from robotexp.errors import ConfigError

__all__ = ["replay"]


@click.command()
@click.argument("bag", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", type=click.Path(file_okay=False, path_type=Path), default=Path("out"),
              show_default=True, help="Output folder (results.jsonl, map, CSVs, as explore writes).")
@click.option("--cell", type=float, default=None,
              help="Map cell size [mm] (default: the recorded one; a ROS 2 robot's bag: 100).")
@handle_errors
def replay(bag: Path, out: Path, cell: float | None) -> None:
    """Rebuild the map and metrics of a recording (robotexp explore --record, or a ROS 2 robot's bag with
    /scan and /odom) and write them as explore does."""
    from robotexp.bag.replay import read_bag, replay_bag

    if cell is not None and not cell > 0:
        raise ConfigError(f"--cell must be > 0 mm, got {cell:g}")
    writable_folder(out)
    data = read_bag(bag)
    run = replay_bag(data, out, cell=None if cell is None else cell / 1000)
    r = run.record
    assert r is not None
    cov = "n/a" if r.coverage is None else f"{r.coverage * 100:.1f}%"
    click.echo(f"{r.run}: replayed {len(data.ticks)} ticks of {bag.name} ({r.reason}); path "
               f"{r.path_length_m:.1f} m, robot time {r.robot_time_s:.0f} s, coverage {cov}")
    click.echo(f"results: {out / 'results.jsonl'}")
    if r.coverage is None:
        click.echo("coverage n/a: no ground truth for this recording at this cell size", err=True)
