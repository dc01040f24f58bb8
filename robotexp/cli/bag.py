"""The commands `robotexp replay` (rebuild a recording's map and metrics), `robotexp video` and
`robotexp figure`. `robotexp.cli.main` registers them, wrapping each in `handle_errors`."""

from __future__ import annotations

import math
from pathlib import Path

import click

from robotexp.errors import ConfigError
from robotexp.run.record import EndReason
from robotexp.view.live import end_view, start_view, view_options

__all__ = ["replay", "video", "figure"]


@click.command()
@click.argument("bag", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", type=click.Path(file_okay=False, path_type=Path), default=Path("out"),
              show_default=True, help="Output folder (results.jsonl, map, CSVs, as explore writes).")
@click.option("--cell", type=float, default=None,
              help="Map cell size [mm] (default: the recorded one; a ROS 2 robot's bag: 100).")
@click.option("--world", "world_file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="The map file (.yaml, .map) the recording was made in: ground truth at another --cell "
                   "(a replay never opens a file the recording names).")
@view_options
def replay(bag: Path, out: Path, cell: float | None, world_file: Path | None, view: bool, view_port: int,
           view_host: str, view_speed: str | None) -> None:
    """Rebuild the map and metrics of a recording (robotexp explore --record, or a ROS 2 robot's bag with
    /scan and /odom) and write them as explore does (--view: then play the recording in the browser at
    --view-speed times its robot time, with pause, step, stop and seeking to any time)."""
    from robotexp.bag.replay import read_bag, replay_bag
    from robotexp.output.safefile import writable_folder
    from robotexp.view.player import Checkpoints, ReplayPlayer

    if cell is not None and not cell > 0:
        raise ConfigError(f"--cell must be > 0 mm, got {cell:g}")
    writable_folder(out)
    if world_file is not None:
        from robotexp.world.loader import is_map_file

        if not (world_file.is_file() and is_map_file(str(world_file))):
            raise ConfigError(f"--world {world_file}: no such map file; give the .yaml or .map the recording was "
                              "made in")
    data = read_bag(bag)
    live = start_view(view, view_host, view_port, view_speed)
    checkpoints = None
    try:
        if live is not None:
            live.hub.set_status(state="waiting", reason="replaying the recording")
            checkpoints = Checkpoints(duration=data.ticks[-1].time)
        run = replay_bag(data, out, cell=None if cell is None else cell / 1000,
                         observers=() if checkpoints is None else (checkpoints,), world_file=world_file)
    except BaseException:
        end_view(live, interrupted=True)
        raise
    r = run.record
    assert r is not None
    if r.end is EndReason.INTERRUPTED:     # the loop ended the replay at Ctrl-C and wrote what it had
        end_view(live, interrupted=True)
        click.echo(f"{r.run}: replay interrupted at robot time {r.robot_time_s:.0f} s; its record is in "
                   f"{out / 'results.jsonl'}", err=True)
        raise KeyboardInterrupt
    cov = "n/a" if r.coverage is None else f"{r.coverage * 100:.1f}%"
    click.echo(f"{r.run}: replayed {len(data.ticks)} ticks of {bag.name} ({r.reason}); path "
               f"{r.path_length_m:.1f} m, robot time {r.robot_time_s:.0f} s, coverage {cov}")
    click.echo(f"results: {out / 'results.jsonl'}")
    if r.coverage is None:
        click.echo("coverage n/a: no ground truth for this recording at this cell size", err=True)
    if live is None:
        return
    click.echo("view: playing the recording (pause, step, speed, seek on the page); Ctrl-C ends")
    player = ReplayPlayer(live.hub, data, run, checkpoints, speed=live.observer.pacer.speed)
    try:
        player.play()
    except KeyboardInterrupt:
        pass
    finally:
        live.close()


@click.command()
@click.argument("bag", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The video: run.mp4 (H.264) or run.gif.")
@click.option("--every", type=float, default=1.0, show_default=True, help="Robot time between frames [s].")
@click.option("--fps", type=float, default=10.0, show_default=True, help="Frames per second of the video.")
@click.option("--cell", type=float, default=None, help="Map cell size [mm] (default: the recorded one).")
def video(bag: Path, output: Path, every: float, fps: float, cell: float | None) -> None:
    """Render a recording (robotexp explore --record, or a ROS 2 robot's /scan + /odom bag) as a video:
    the map as it grew, the path, the laser and the robot, a frame every --every seconds of robot time."""
    from robotexp.bag.replay import read_bag, replay_bag
    from robotexp.output.video import FrameObserver, VideoWriter, check_fps, check_video_path

    check_video_path(output)
    check_fps(fps)
    if cell is not None and not cell > 0:
        raise ConfigError(f"--cell must be > 0 mm, got {cell:g}")
    if not (every > 0 and math.isfinite(every)):
        raise ConfigError(f"--every must be > 0 s, got {every:g}")
    data = read_bag(bag)
    with VideoWriter(output, fps) as writer:
        frames = FrameObserver(writer, every)
        run = replay_bag(data, None, cell=None if cell is None else cell / 1000, observers=(frames,))
        if run.end is EndReason.INTERRUPTED:        # the loop ended the replay at Ctrl-C: no video of half of it
            writer.discard()
            click.echo(f"video: interrupted; {output} was not written" + (" (the one there is kept)"
                                                                          if output.exists() else ""), err=True)
            raise KeyboardInterrupt
    click.echo(f"video: {output} ({writer.count} frames, {writer.count / fps:.1f} s at {fps:g} fps)")


@click.command()
@click.argument("source", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "-o", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Output folder (default: beside SOURCE).")
@click.option("--format", "formats", default="png,svg,pdf", show_default=True, help="Comma-separated: png, svg, pdf.")
@click.option("--include-incomplete", is_flag=True, help="Count runs cut short in the box plots.")
def figure(source: Path, out: Path | None, formats: str, include_incomplete: bool) -> None:
    """Figures for a thesis (matplotlib; PNG, SVG, PDF): a recording (.mcap) gives its map with a legend,
    scale bar and axes in metres; a results.jsonl gives box plots of coverage, path length and robot
    time per world and method, over the completed runs (as campaign report and plot count them)."""
    from robotexp.output.safefile import writable_folder
    from robotexp.output.figures import FORMATS, campaign_figures, displayable, run_map_figure, save_figure

    fmts = [f.strip().lower() for f in formats.split(",") if f.strip()]
    bad = sorted(set(fmts) - set(FORMATS))
    if bad or not fmts:
        raise ConfigError(f"--format {formats!r}: use png, svg, pdf (comma-separated)")
    if not source.is_file():
        raise ConfigError(f"{source}: no such file; give a recording (.mcap) or a results.jsonl")
    folder = out or source.parent
    writable_folder(folder)
    folder.mkdir(parents=True, exist_ok=True)
    if source.suffix.lower() == ".mcap":
        from robotexp.bag.replay import read_bag, replay_bag

        run = replay_bag(read_bag(source), None)
        written = save_figure(run_map_figure(run), folder / f"{run.info.name}.map", fmts)
    elif source.suffix.lower() == ".jsonl":
        from robotexp.campaign.compare import load_results      # checked and counted as `campaign report` does

        written = campaign_figures(load_results(source), folder, fmts, include_incomplete=include_incomplete)
    else:
        raise ConfigError(f"{source}: give a recording (.mcap) or a results file (.jsonl)")
    for path in written:
        click.echo(f"written: {displayable(str(path))}")     # a world named by a non-UTF-8 file name
