"""`robotexp bench MAPS... --methods ...`: the map benchmark's command (see `robotexp.campaign.bench`)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import click

from robotexp.cli.common import fail, interrupted
from robotexp.errors import ConfigError, PluginError, WorldError

__all__ = ["bench"]


@click.command()
@click.argument("maps", nargs=-1)
@click.option("--methods", "-m", default=None, help="Comma-separated explorers [default: frontier,bvp; with "
              "--done-when: frontier,bvp,srt-laser,meta-ga,meta-firefly].")
@click.option("--done-when", is_flag=True, help="The Done-when benchmark: MAPS (the real maps) plus "
              "generated:office|warehouse|cave:SEEDS, with the five methods unless --methods.")
@click.option("--robots", "-r", default=None, help="Comma-separated robot presets, every map and method run with "
              "each [default: p3dx; with --done-when: p3dx,kobuki].")
@click.option("--seeds", default="0-49", show_default=True, help="With --done-when: the generated worlds' seeds, A-B.")
@click.option("--jobs", "-j", type=click.IntRange(min=1), default=None, help="Parallel runs (default: all cores).")
@click.option("--out", "-o", type=click.Path(file_okay=False, path_type=Path), default=Path("out/bench"),
              show_default=True, help="Output folder (results.jsonl, bench.txt, bench.csv, images).")
@click.option("--max-time", type=click.FloatRange(min=1.0), default=4 * 3600.0, show_default=True,
              help="Robot-time limit per run [s] (a run stopped by it is no success).")
@click.option("--resume", is_flag=True, help="Skip the runs already recorded in the output folder.")
@click.option("--report", is_flag=True, help="Run nothing: the table of the runs already recorded in --out.")
def bench(maps: tuple[str, ...], methods: str | None, robots: str | None, done_when: bool, seeds: str,  # noqa: PLR0913
          jobs: int | None, out: Path, max_time: float, resume: bool, report: bool) -> None:
    """Run explorers over MAPS (map files, folders of them, built-in names, generated:KIND:A-B) with each
    robot preset from each map's default start; print per map, method and robot the coverage of the
    reachable space, path, robot time, end reason and success, then the success rate per method, robot
    and map group and every failure with its causes (also bench.txt, bench.csv and bench.md in --out).
    Stopped and started again with --resume, it runs only what is missing."""
    from robotexp.campaign.bench import DONE_WHEN_METHODS, DONE_WHEN_ROBOTS, done_when_maps, run_bench

    def progress(done: int, total: int, record: Mapping[str, Any] | None) -> None:
        if record is not None:
            click.echo(f"{done}/{total} {record['run']}: coverage {record['coverage']}, {record['reason']}", err=True)

    if not maps and not done_when:
        fail("bench: give the maps to run (files, folders, generated:KIND:A-B), or --done-when", 2)
    if methods is None:
        methods = ",".join(DONE_WHEN_METHODS) if done_when else "frontier,bvp"
    if robots is None:
        robots = ",".join(DONE_WHEN_ROBOTS) if done_when else "p3dx"
    if done_when:
        maps = tuple(done_when_maps(maps, seeds))
    try:
        text, _ = run_bench(list(maps), [m.strip() for m in methods.split(",") if m.strip()], out,
                            jobs=jobs or os.cpu_count() or 1, resume=resume, max_time=max_time, progress=progress,
                            run=not report, robots=[r.strip() for r in robots.split(",") if r.strip()])
    except (ConfigError, WorldError, PluginError) as exc:
        fail(str(exc), 2)
    except KeyboardInterrupt as exc:
        interrupted(exc)
    click.echo(text, nl=False)
