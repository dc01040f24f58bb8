"""`robotexp campaign run|report|plot`: campaigns from a TOML file, their tables and figures."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import click

from robotexp.cli.common import handle_errors
from robotexp.errors import ConfigError
from robotexp.output.safefile import writable_folder
from robotexp.run.record import RunRecord
from robotexp.view.live import end_view, start_view, view_options

__all__ = ["campaign", "campaign_run", "campaign_report", "campaign_plot"]

class _CampaignGroup(click.Group):
    """`robotexp campaign FILE` runs a campaign; `robotexp campaign report RESULTS` reports one."""

    def resolve_command(self, ctx: click.Context, args: list[str]) -> Any:
        if args and args[0] not in self.commands:
            args.insert(0, "run")
        return super().resolve_command(ctx, args)


@click.group(cls=_CampaignGroup)
def campaign() -> None:
    """Run a campaign file (robotexp campaign FILE), print its tables (robotexp campaign report
    RESULTS) or draw its box plots and trajectories (robotexp campaign plot RESULTS)."""


@campaign.command("run")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--jobs", "-j", type=int, default=None, help="Parallel runs (default: all cores).")
@click.option("--out", "-o", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Output folder (default: out/<campaign name>).")
@click.option("--resume", is_flag=True, help="Skip the runs already recorded in the output folder.")
@click.option("--cluster", default=None, metavar="ADDRESS",
              help="Run on a Dask cluster: tcp://HOST:PORT (a running `dask scheduler`) or local:N (N worker "
                   "processes here). Default: a local process pool of --jobs.")
@view_options
@handle_errors
def campaign_run(file: Path, jobs: int | None, out: Path | None, resume: bool, cluster: str | None, view: bool,
                 view_port: int, view_host: str, view_speed: str | None) -> None:
    """Run every run of a campaign FILE in parallel processes, appending each to results.jsonl."""
    import os
    import time

    from robotexp.campaign.runner import run_campaign
    from robotexp.campaign.spec import load_campaign

    if cluster is not None:
        from robotexp.campaign.cluster import check_cluster_address
        check_cluster_address(cluster)
    if jobs is not None and jobs < 1:
        raise ConfigError(f"--jobs must be >= 1, got {jobs}")
    camp = load_campaign(file)
    out = out or Path("out") / camp.name
    writable_folder(out)
    n_jobs = jobs if jobs is not None else (os.cpu_count() or 1)
    place = None
    if camp.devices:            # a robot: one run at a time, the operator places it between runs
        from robotexp.campaign.robots import one_at_a_time, operator
        click.echo(one_at_a_time(camp, jobs), err=True)
        # on a terminal the line starts below the progress bar
        n_jobs, place = 1, operator(sys.stdin.readline, lambda line: click.echo(
            ("\n" if sys.stderr.isatty() else "") + line, err=True))
    t0 = time.monotonic()
    tty = sys.stderr.isatty()
    failed: list[str] = []

    live = start_view(view, view_host, view_port, view_speed)
    feed = None
    if live is not None:
        from robotexp.view.campaign import CampaignFeed
        feed = CampaignFeed(live.hub, camp.name, len(camp.runs), n_jobs)

    def progress(done: int, total: int, record: RunRecord | None) -> None:
        if feed is not None:
            feed.progress(done, total, record)
        if record is not None and not record.completed:
            failed.append(f"{record.run}: {record.reason}")
        elapsed = time.monotonic() - t0
        if tty:
            width = 30
            bar = "#" * int(width * done / max(total, 1))
            click.echo(f"\r{camp.name} [{bar:<{width}}] {done}/{total} runs  {elapsed:6.0f} s", nl=False, err=True)
        elif record is not None:
            click.echo(f"{done}/{total} {record.run}: path {record.path_length_m:.1f} m, coverage "
                       f"{record.coverage}, {record.reason}", err=True)

    where = f"cluster {cluster}" if cluster else f"{n_jobs} jobs"
    click.echo(f"campaign {camp.name}: {len(camp.runs)} runs, {where}, results in {out}", err=True)
    try:
        records = run_campaign(camp, out, jobs=n_jobs, resume=resume, progress=progress, cluster=cluster,
                               place=place)
    except BaseException:
        end_view(live, interrupted=True)
        raise
    finally:
        if tty:
            click.echo("", err=True)
    click.echo(f"{len(records)} runs made in {time.monotonic() - t0:.0f} s; results: {out / 'results.jsonl'}")
    for line in failed:
        click.echo(f"  incomplete: {line}")
    click.echo(f"tables: robotexp campaign report {out / 'results.jsonl'}")
    if feed is not None:
        feed.finish(f"{len(records)} runs made; results: {out / 'results.jsonl'}")
    end_view(live, interrupted=False)


@campaign.command("report")
@click.argument("results", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Folder for tables.csv and tables.md (default: beside RESULTS).")
@click.option("--include-incomplete", is_flag=True,
              help="Count runs cut short in the visited-cells comparison (the thesis tables never do).")
@handle_errors
def campaign_report(results: Path, out: Path | None, include_incomplete: bool) -> None:
    """Print the thesis-style tables of a results.jsonl, and per world with 2+ methods the visited
    cells with Welch's t-test (Santos 2016, Table 8); write them as CSV and Markdown."""
    import csv

    from robotexp.campaign.compare import comparison_tables, excluded_table, load_results
    from robotexp.campaign.report import report_tables, table_markdown, table_text

    duplicates: list[RunRecord] = []
    records = load_results(results, duplicates=duplicates)
    tables = report_tables(records) + comparison_tables(records, include_incomplete=include_incomplete)
    if not tables:
        raise ConfigError(f"{results}: no finished runs to report")
    left_out = excluded_table(records, duplicates=duplicates, include_incomplete=include_incomplete)
    if left_out is not None:
        tables.append(left_out)
    folder = out or results.parent
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "tables.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        for t in tables:
            w.writerow([t.title])
            w.writerow(t.header)
            w.writerows(t.rows)
            w.writerow([])
    (folder / "tables.md").write_text("\n".join(table_markdown(t) for t in tables), encoding="utf-8")
    for t in tables:
        click.echo(table_text(t))
    click.echo(f"written: {folder / 'tables.csv'}, {folder / 'tables.md'}  "
               "(* = run not completed, left out of the statistics)")


@campaign.command("plot")
@click.argument("results", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Folder for the images (default: beside RESULTS).")
@click.option("--include-incomplete", is_flag=True, help="Count runs cut short in the box plot.")
@handle_errors
def campaign_plot(results: Path, out: Path | None, include_incomplete: bool) -> None:
    """Draw visited_cells.png (box plots per world and method) and paths_<world>_<method>.png
    (the runs' trajectories overlaid on the world's map, from their NAME.path.csv files)."""
    from robotexp.campaign.compare import campaign_plots, load_results

    records = load_results(results)
    written = campaign_plots(records, results.parent, out or results.parent, include_incomplete=include_incomplete,
                             note=lambda text: click.echo(f"robotexp: {text}", err=True))
    for path in written:
        click.echo(f"written: {path}")
