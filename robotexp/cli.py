"""The `robotexp` command line. Parses, calls the library, prints; maps errors to exit codes.

Exit codes: 0 ok; 1 a run failed (robot or script error); 2 bad input (world, method, parameter);
130 interrupted by Ctrl-C (the partial result is written first).
"""

from __future__ import annotations

import functools
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import click

from robotexp.errors import ConfigError, PluginError, RobotError, RobotexpError, ScriptError, WorldError
from robotexp.observers import RunObserver
from robotexp.record import EndReason, RunRecord
from robotexp.view.live import end_view, parse_speed, start_view, view_options

F = TypeVar("F", bound=Callable[..., Any])


def _fail(message: str, code: int) -> None:
    click.echo(f"robotexp: error: {message}", err=True)
    sys.exit(code)


def _quiet_stdout() -> None:
    """The reader of stdout went away (`robotexp plugins | head -1`): point stdout at the null device,
    so that nothing more (not even the flush at exit) fails on the closed pipe."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


def handle_errors(func: F) -> F:
    """Turn our errors into one line and an exit code (a traceback only with --debug)."""
    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        debug = click.get_current_context().find_root().params.get("debug", False)
        try:
            return func(*args, **kwargs)
        except (ConfigError, WorldError, PluginError) as exc:
            if debug:
                raise
            _fail(str(exc), 2)
        except (RobotError, ScriptError, RobotexpError) as exc:
            if debug:
                raise
            _fail(str(exc), 1)
        except KeyboardInterrupt:
            click.echo("robotexp: interrupted", err=True)
            sys.exit(130)
        except BrokenPipeError:
            _quiet_stdout()
            sys.exit(0)
        except OSError as exc:
            if debug:
                raise
            where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
            _fail(f"{exc.strerror or exc}{where}", 1)
    return wrapper  # type: ignore[return-value]


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--debug", is_flag=True, help="Show Python tracebacks on errors.")
@click.version_option(package_name="robotexp")
def main(debug: bool) -> None:
    """Mobile-robot exploration experiments, on the embedded simulator or a real robot."""


class Progress(RunObserver):
    """Progress of a run on stderr: on a terminal one line redrawn at each coverage sample (coverage,
    robot time, wall time and, at the run's speed so far, the wall time left until its time limit at
    most; "no gain for N s" once coverage stopped growing); without a terminal one line a minute (logs).
    A run observer (`on_sample`), or called as `progress(t, coverage)`.

    Args:
        label: what the line starts with (None: the world and method of each run, at its start).
        enabled: redraw one line (default: whether stderr is a terminal); False: a line every `every` s.
        every: [s] wall time between lines without a terminal.
        clock: wall clock [s].
        notice: a line said on stderr when the run starts.
        say_start: say where the run starts (its pose's name; why, for a default start) on stderr.
    """

    STALL = 60.0        # [s] robot time without a coverage gain of GAIN before "no gain" is said
    GAIN = 0.001        # coverage

    def __init__(self, label: str | None, enabled: bool | None = None, every: float = 60.0,
                 clock: Callable[[], float] | None = None, notice: str | None = None,
                 say_start: bool = False) -> None:
        import time

        self.fixed = label
        self.label = label or ""
        self.notice = notice
        self.say_start = say_start
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.shown = False
        self.every = every
        self.clock = clock or time.monotonic
        self.wall0 = self.clock()
        self.next_line = self.wall0 + every
        self.max_time: float | None = None
        self.best = (-1.0, 0.0)         # (coverage, robot time it was reached)

    def on_start(self, run: Any) -> None:
        """Say the notice, note the run's time limit and start the wall clock."""
        if self.notice:
            click.echo(self.notice, err=True)
        if self.say_start:
            click.echo(f"robotexp: {_start_line(run)}", err=True)
        self.max_time = run.max_time
        self.wall0 = self.clock()
        self.next_line = self.wall0 + self.every
        self.best = (-1.0, 0.0)
        if self.fixed is None:
            self.label = f"{Path(run.info.world or '').stem} {run.info.method}".strip()

    def on_end(self, run: Any, record: Any) -> None:
        """End the run's line (the next run of a script starts its own)."""
        self.close()

    def on_sample(self, run: Any, time: float, coverage: float | None) -> None:
        """Show the sample."""
        self(time, coverage)

    def line(self, t: float, coverage: float | None) -> str:
        """The progress text at robot time `t` [s] with `coverage` (None: unknown)."""
        wall = self.clock() - self.wall0
        parts = [self.label]
        if coverage is not None:
            width = 30
            done = int(round(coverage * width))
            parts.append(f"[{'#' * done}{'-' * (width - done)}] {coverage * 100:5.1f}%")
            if coverage > self.best[0] + self.GAIN:
                self.best = (coverage, t)
            elif t - self.best[1] >= self.STALL:
                parts.append(f"no gain for {t - self.best[1]:.0f} s")
        parts.append(f"robot time {t:7.0f} s, wall {wall:5.0f} s")
        if self.max_time is not None and t > 0 and wall > 1.0:
            left = max(0.0, (self.max_time - t) * wall / t)     # a run's last sample may pass its limit
            parts.append(f"<= {round(left):d} s left (time limit)")
        return "  ".join(parts)

    def __call__(self, t: float, coverage: float | None) -> None:
        text = self.line(t, coverage)
        if self.enabled:
            click.echo(f"\r{text}\033[K", nl=False, err=True)
            self.shown = True
        elif self.clock() >= self.next_line:
            self.next_line = self.clock() + self.every
            click.echo(text, err=True)

    def close(self) -> None:
        """End the progress line."""
        if self.shown:
            click.echo("", err=True)
            self.shown = False


def _mm(value: float | None, what: str) -> float | None:
    if value is None:
        return None
    if not (value > 0 and math.isfinite(value)):
        raise ConfigError(f"{what} must be a positive number of mm, got {value:g}")
    return value / 1000.0


def writable_folder(out: Path, option: str = "--out") -> None:
    """Check, before any run starts, that the output folder `out` can be made and written.

    Raises:
        ConfigError: it cannot (under a file, in /proc, no permission, a read-only file system), or
            (--out) its results.jsonl is a folder or another file that cannot take records.
    """
    import tempfile

    made = [d for d in (out, *out.parents) if not d.exists()]     # removed again: nothing is left behind
    try:
        for attempt in range(5):
            out.mkdir(parents=True, exist_ok=True)
            try:
                with tempfile.NamedTemporaryFile(dir=out, prefix=".robotexp-check-"):
                    pass
                break
            except FileNotFoundError:
                # another robotexp checking the same new folder removed it between our mkdir and the
                # probe (both saw it missing): make it again; a folder that keeps vanishing is an error
                if attempt == 4:
                    raise
    except OSError as exc:
        raise ConfigError(f"{option} {out}: cannot write there ({exc.strerror or exc}); give a folder you can "
                          "create and write") from None
    finally:
        for d in made:
            try:
                d.rmdir()
            except OSError:
                break
    if option == "--out":
        from robotexp.safefile import check_results_file
        check_results_file(out / "results.jsonl")


def _params(items: tuple[str, ...]) -> dict[str, Any]:
    """Parse repeated `--param key=value` (values as JSON numbers/booleans, else strings)."""
    import json
    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key.isidentifier():
            raise ConfigError(f"--param {item!r}: expected key=value with key a parameter name")
        try:
            out[key] = json.loads(raw)
        except json.JSONDecodeError:
            out[key] = raw
    return out


def _image_formats(text: str) -> tuple[str, ...]:
    """--image-format: "png,svg" -> ("png", "svg"); ConfigError for anything else."""
    from robotexp.figures import FORMATS

    fmts = tuple(dict.fromkeys(f.strip().lower() for f in text.split(",") if f.strip()))
    if not fmts or set(fmts) - set(FORMATS):
        raise ConfigError(f"--image-format {text!r}: use png, svg, pdf (comma-separated)")
    return fmts


@main.command()
@click.option("--world", "-w", default="dense", show_default=True,
              help="Built-in world name, or the path of a MobileSim .map or ROS .yaml map.")
@click.option("--method", "-m", default="frontier", show_default=True, help="Explorer plugin name.")
@click.option("--pose", default=None, help="Start pose: a name of the world's poses, or x,y,theta in mm, mm, deg.")
@click.option("--speed", type=float, default=300.0, show_default=True, help="Maximum speed [mm/s].")
@click.option("--laser-range", type=float, default=3000.0, show_default=True, help="Laser range [mm].")
@click.option("--cell", type=float, default=None, help="Map cell size [mm] (default: the method's, else 100).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of every random choice.")
@click.option("--robot", default="p3dx", show_default=True,
              help="Simulated robot preset (p3dx, kobuki); with --address, the robot backend.")
@click.option("--address", default=None,
              help="Run on a connected robot at this address (serial device, host[:port], pyserial URL); "
                   "--world, if given, is then only the ground truth for coverage.")
@click.option("--laser", default=None, help="With --address: a laser of its own, NAME:ADDRESS (rplidar:/dev/ttyUSB0).")
@click.option("--laser-pose", default=None, help="Where --laser sits on the robot: X,Y,THETA [mm, mm, deg].")
@click.option("--param", "-p", multiple=True,
              help="Explorer parameter key=value (repeatable); -p help lists the method's parameters.")
@click.option("--show", default="", help="Overlays on the map image: grid,laser,vectors,potential.")
@click.option("--max-time", type=float, default=14400.0, show_default=True, help="Robot-time limit [s].")
@click.option("--noise-uniform", type=float, default=0.0, show_default=True,
              help="Laser noise: uniform in +-MM (the UFMG study: 100).")
@click.option("--noise-sigma", type=float, default=0.0, show_default=True, help="Laser noise: gaussian sigma [mm].")
@click.option("--odometry-error", default="none", show_default=True,
              help="Simulated odometry error: none, p3dx, kobuki, or key=value,... (mismatch, slip, drift "
                   "[deg/m], servo); a preset:key=value,... overrides its values.")
@click.option("--localize", type=click.Choice(["auto", "none", "scan-match", "slam"]), default="auto",
              show_default=True,
              help="Correct the pose by scan matching before the map and the explorer see it (auto: in the "
                   "simulator when --odometry-error is on); slam: with online loop closure as well.")
@click.option("--out", "-o", type=click.Path(file_okay=False, path_type=Path), default=Path("out"),
              show_default=True, help="Output folder (results.jsonl, images).")
@click.option("--bounds", default=None, metavar="XMIN,YMIN,XMAX,YMAX",
              help="Exploration area [mm] (default: what the map declares, else the world's box).")
@click.option("--bounds-wall", is_flag=True, help="The simulator gets walls along the exploration area's edge.")
@click.option("--record", type=click.Path(dir_okay=False, path_type=Path), default=None, metavar="FILE.mcap",
              help="Record the run as a ROS 2 bag in MCAP (robotexp replay / video read it; Foxglove opens it).")
@click.option("--frames", type=click.Path(file_okay=False, path_type=Path), default=None, metavar="DIR",
              help="Save a PNG frame of the map (with the --show overlays) every --frame-every s of robot time in DIR.")
@click.option("--frame-every", type=float, default=1.0, show_default=True, help="Robot time between frames [s].")
@click.option("--image-format", "image_format", default="png", show_default=True,
              help="Formats of the run's map and coverage figures, comma-separated: png, svg, pdf.")
@view_options
@handle_errors
def explore(world: str, method: str, pose: str | None, speed: float, laser_range: float, cell: float | None,
            seed: int, robot: str, address: str | None, laser: str | None, laser_pose: str | None,
            param: tuple[str, ...], show: str, max_time: float, noise_uniform: float, noise_sigma: float,
            odometry_error: str, localize: str, out: Path, bounds: str | None, bounds_wall: bool,
            record: Path | None, frames: Path | None, frame_every: float, image_format: str, view: bool,
            view_port: int, view_host: str, view_speed: str | None) -> None:
    """Run one exploration on the embedded simulator (or a robot: --address) and write its results."""
    from robotexp.experiment import RunSpec, run_experiment, run_on_robot
    from robotexp.laser_mount import check_laser_options, connect_with_laser
    from robotexp.world.bounds import parse_bounds

    if "help" in param:         # -p help: the method's parameters, nothing run
        from robotexp.paramhelp import parameters_text
        click.echo(parameters_text(method))
        return
    hint = _pose_hint(pose)     # said once the run starts, or with the error of a start that is refused

    if (laser is not None or laser_pose is not None) and address is None:
        raise ConfigError("--laser and --laser-pose attach a laser to a robot at --address; the embedded "
                          "simulator has its own")
    check_laser_options(laser, laser_pose)
    overlays = tuple(s for s in show.split(",") if s)
    formats = _image_formats(image_format)
    unknown = set(overlays) - {"grid", "laser", "vectors", "potential"}
    if unknown:
        raise ConfigError(f"--show: unknown overlay(s) {', '.join(sorted(unknown))}; "
                          "use grid, laser, vectors, potential")
    if speed <= 0 or not math.isfinite(speed):
        raise ConfigError(f"--speed must be > 0 mm/s, got {speed:g}")
    spec = RunSpec(world=world, method=method, pose=pose, speed=speed / 1000, seed=seed, robot=robot,
                   laser_range=_mm(laser_range, "--laser-range") or 3.0, cell=_mm(cell, "--cell"),
                   params=_params(param), max_time=max_time, laser_uniform=noise_uniform / 1000,
                   laser_sigma=noise_sigma / 1000, bounds_wall=bounds_wall,
                   map_bounds=None if bounds is None else parse_bounds(bounds),
                   odometry=odometry_error, localize=localize)
    spec.validate()
    writable_folder(out)
    live = start_view(view, view_host, view_port, view_speed)
    progress = Progress(f"{Path(world).stem} {method}", notice=None if hint is None else f"robotexp: {hint}",
                        say_start=address is None)
    watchers: list[RunObserver] = [progress] if live is None else [progress, live.observer]
    if frames is not None:
        from robotexp.video import FrameObserver, PngFrames

        watchers.append(FrameObserver(PngFrames(frames), frame_every, overlays))
    recorder = None
    if record is not None:
        from robotexp.bag.recorder import BagRecorder

        recorder = BagRecorder(record, world=world)
        watchers.append(recorder)
    try:
        with compile_watch():       # the first run after an install: numba compiles, said as it happens
            if address is None:
                result = run_experiment(spec, out, observers=watchers, show=overlays, image=formats)
            else:
                given = click.get_current_context().get_parameter_source("world")
                truth_world = None if given == click.core.ParameterSource.DEFAULT else world
                if localize == "auto":
                    click.echo("robotexp: --localize auto: scan matching corrects the robot's odometry before the "
                               "map and the explorer see it (--localize none turns it off)", err=True)
                with connect_with_laser(robot, address, laser, laser_pose) as bot:
                    result = run_on_robot(spec, bot, out, truth_world, observers=watchers, show=overlays,
                                          image=formats)
    except (WorldError, ConfigError) as exc:
        end_view(live, interrupted=True)
        if hint is not None:            # one line: the refusal and how the pose was read
            raise type(exc)(f"{exc} ({hint})") from None
        raise
    except BaseException:
        end_view(live, interrupted=True)
        raise
    finally:
        progress.close()
        if recorder is not None:
            recorder.close()            # a run that never started leaves no file
    r = result.record
    cov = "n/a" if r.coverage is None else f"{r.coverage * 100:.1f}%"
    ate = r.extra.get("ate_m")          # with an odometry error: how far the pose the explorer got was off
    if r.extra.get("odometry_error") in (None, "none") and r.extra.get("localize") in (None, "none"):
        ate = None                      # exact odometry: nothing to say
    extra = ("" if r.map_iou is None else f", map IoU {r.map_iou:.3f}") + ("" if ate is None else f", ATE {ate:.3f} m")
    click.echo(f"{r.run}: {r.reason}; path {r.path_length_m:.1f} m, robot time {r.robot_time_s:.0f} s "
               f"(wall {r.wall_time_s:.1f} s), coverage {cov}{extra}, collisions {r.collisions}")
    click.echo(f"results: {out / 'results.jsonl'}" + (f", map: {result.image}" if result.image else ""))
    end_view(live, result.interrupted)
    if result.interrupted:
        sys.exit(130)
    if r.end in (EndReason.ROBOT_ERROR, EndReason.PLUGIN_ERROR):     # written, but the run failed
        _fail(f"{r.run}: {r.reason}", 1)


def compile_watch(tty: bool | None = None) -> Any:
    """A `robotexp.compilewatch.CompileWatch` that tells stderr, as it happens, that numba compiles the
    kernels of a group (the first run after an install) and how far it got: on a terminal (`tty`,
    default: whether stderr is one) one line redrawn per group, else a line per kernel."""
    from robotexp.compilewatch import CompileWatch

    redraw = sys.stderr.isatty() if tty is None else tty
    drawn = [False]

    def say(text: str) -> None:
        step = text.startswith("  ")
        if step and redraw:
            click.echo(f"\r{text.strip()}\033[K", nl=False, err=True)
            drawn[0] = True
            return
        if drawn[0]:
            click.echo("", err=True)
            drawn[0] = False
        click.echo(text if step else f"robotexp: {text}", err=True)
    return CompileWatch(say)


def _start_line(run: Any) -> str:
    """Where a run starts, with its pose's name (and, for the default start, why it lies there)."""
    from robotexp.world.start import chosen_start

    p = run.start_pose
    label = getattr(run.info, "pose", None)
    line = f"start {label or 'pose'!s}: ({p.x:.2f}, {p.y:.2f}) m, heading {math.degrees(p.theta):.0f} deg"
    choice = chosen_start(run.info.world) if label == "centre" else None
    if choice is not None and choice.pose.x == p.x and choice.pose.y == p.y:
        line += f" ({choice.describe()})"
    return line


def _pose_hint(text: str | None) -> str | None:
    """How an x,y[,theta] --pose is read when it has no heading or looks like metres (0 < |x|, |y| < 100 mm),
    else None."""
    from robotexp.world.poses import parse_pose

    if text is None or "," not in text:
        return None
    p = parse_pose(text)
    parts = text.split(",")
    small = 0 < max(abs(p.x), abs(p.y)) < 0.1
    if not small and len(parts) == 3:
        return None
    return (f"--pose {text} is read as x {p.x * 1000:g} mm, y {p.y * 1000:g} mm, heading {math.degrees(p.theta):g} deg"
            + ("" if len(parts) == 3 else " (none given)")
            + (f"; in metres write {float(parts[0]) * 1000:g},{float(parts[1]) * 1000:g}" if small else ""))


@main.group(invoke_without_command=True)
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


from robotexp.world.generate_cli import generate  # noqa: E402  (the command lives with the generator)

worlds.add_command(generate)
main.add_command(__import__("robotexp.bench_cli", fromlist=["bench"]).bench)
for _name in ("replay", "video", "figure"):      # recordings, video, figures (robotexp.bag.cli)
    _command = getattr(__import__("robotexp.bag.cli", fromlist=[_name]), _name)
    _command.callback = handle_errors(_command.callback)
    main.add_command(_command)


@main.command()
@handle_errors
def plugins() -> None:
    """List the explorers, robot backends and their emulators found through entry points."""
    from robotexp.registry import EMULATORS, EXPLORERS, ROBOTS, available, lua_name

    for title, group in (("explorers", EXPLORERS), ("robots", ROBOTS), ("emulators", EMULATORS)):
        click.echo(f"{title} ({group}):")
        for info in available(group).values():
            extra = f"  Lua: ExplorationMethod.{lua_name(info.name)}" if group == EXPLORERS else ""
            click.echo(f"  {info.name:16s} {info.target:45s} {info.distribution} {info.version}{extra}")


class _CampaignGroup(click.Group):
    """`robotexp campaign FILE` runs a campaign; `robotexp campaign report RESULTS` reports one."""

    def resolve_command(self, ctx: click.Context, args: list[str]) -> Any:
        if args and args[0] not in self.commands:
            args.insert(0, "run")
        return super().resolve_command(ctx, args)


@main.group(cls=_CampaignGroup)
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

    from robotexp.campaign import load_campaign, run_campaign

    if cluster is not None:
        from robotexp.cluster import check_cluster_address
        check_cluster_address(cluster)
    camp = load_campaign(file)
    out = out or Path("out") / camp.name
    writable_folder(out)
    n_jobs = jobs if jobs is not None else (os.cpu_count() or 1)
    place = None
    if camp.devices:            # a robot: one run at a time, the operator places it between runs
        from robotexp.campaign_robot import one_at_a_time, operator
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

    from robotexp.campaign import report_tables, table_markdown, table_text
    from robotexp.compare import comparison_tables, excluded_table, load_results

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
    from robotexp.compare import campaign_plots, load_results

    records = load_results(results)
    written = campaign_plots(records, results.parent, out or results.parent, include_incomplete=include_incomplete,
                             note=lambda text: click.echo(f"robotexp: {text}", err=True))
    for path in written:
        click.echo(f"written: {path}")


def _say_ready(fd: int) -> None:
    """Tell the supervisor the script starts (its --timeout runs from now); once."""
    import os

    try:
        os.write(fd, b"r")
        os.close(fd)
    except OSError:
        pass


@main.command("run")
@click.argument("script", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--world", "-w", default=None,
              help="Run on the embedded simulator of this world whatever robot.setAddress says.")
@click.option("--robot", default="p3dx", show_default=True, help="Simulated robot preset (p3dx, kobuki).")
@click.option("--out", "-o", type=click.Path(file_okay=False, path_type=Path), default=Path("out"),
              show_default=True, help="Output folder; the script's relative paths are relative to it.")
@click.option("--sandbox", is_flag=True,
              help="Refuse os.execute, io.popen, C modules, files outside the output folder and robot addresses "
                   "not given with --allow-address; limit the script's memory (--max-memory, default 512 MB) "
                   "and what it writes to files (--max-write, default 512 MB).")
@click.option("--allow-address", multiple=True,
              help="With --sandbox: a robot or laser address (host[:port] or device path) the script may open "
                   "(repeatable).")
@click.option("--max-memory", type=float, default=None,
              help="Limit of the script's Lua memory [MB] (default: none; 512 with --sandbox).")
@click.option("--timeout", type=float, default=None, help="Stop the script after this many seconds (exit 1).")
@click.option("--child", is_flag=True, hidden=True, help="Run in this process (robotexp.lua.supervise's child).")
@click.option("--tty-progress", is_flag=True, hidden=True,
              help="Redraw the progress line (the child's stderr is a pipe to a terminal).")
@click.option("--ready-fd", type=int, default=None, hidden=True,
              help="A pipe to write one byte to when the script starts (robotexp.lua.supervise's child).")
@click.option("--max-write", type=float, default=None,
              help="Limit of what the script writes to files [MB] (default: none; 512 with --sandbox).")
@click.option("--record", type=click.Path(file_okay=False, path_type=Path), default=None, metavar="DIR",
              help="Record each run of the script as a ROS 2 bag, DIR/<run>.mcap.")
@view_options
@handle_errors
def run_lua(script: Path, world: str | None, robot: str, out: Path, sandbox: bool, allow_address: tuple[str, ...],
            max_memory: float | None, timeout: float | None, child: bool, tty_progress: bool, record: Path | None,
            view: bool, view_port: int, view_host: str, view_speed: str | None, ready_fd: int | None = None,
            max_write: float | None = None) -> None:
    """Run a Lua experiment script (IfTEA's API: robot, exploration, mapView, robotView).

    The script runs in a child process that is killed at --timeout (+1 s) or 3 s after Ctrl-C
    if it does not stop by itself; runs already written stay in results.jsonl."""
    from robotexp.lua.runtime import SANDBOX_MAX_MEMORY_MB, SANDBOX_MAX_WRITE_MB
    from robotexp.lua.sandbox import AddressPolicy

    if timeout is not None and not (timeout > 0 and math.isfinite(timeout)):
        raise ConfigError(f"--timeout must be a number of seconds > 0, got {timeout:g}")
    if max_memory is not None and not (1 <= max_memory <= 2**20):
        raise ConfigError(f"--max-memory must be 1..1048576 MB, got {max_memory:g}")
    if allow_address and not sandbox:
        raise ConfigError("--allow-address only means something with --sandbox (without it a script may open "
                          "any address)")
    AddressPolicy(sandbox, allow_address)       # a malformed --allow-address: one line, before anything runs
    memory = max_memory if max_memory is not None else (SANDBOX_MAX_MEMORY_MB if sandbox else None)
    if max_write is not None and not (0 <= max_write <= 2**30):
        raise ConfigError(f"--max-write must be 0..1073741824 MB, got {max_write:g}")
    written = max_write if max_write is not None else (SANDBOX_MAX_WRITE_MB if sandbox else None)
    writable_folder(out)
    parse_speed(view_speed)                     # a bad --view-speed: one line, before anything runs
    if record is not None:
        writable_folder(record, "--record")
        record = record.resolve()
    if not child:
        from robotexp.lua.supervise import supervise

        args = [str(script), "--robot", robot, "--out", str(out)] + (["--world", world] if world else [])
        args += (["--sandbox"] if sandbox else []) + [f"--allow-address={a}" for a in allow_address]
        args += [f"--max-memory={max_memory!r}"] if max_memory is not None else []
        args += [f"--max-write={max_write!r}"] if max_write is not None else []
        args += [f"--timeout={timeout!r}"] if timeout is not None else []
        args += [f"--record={record}"] if record is not None else []
        if view:            # the child runs the script, so it serves the view
            args += ["--view", f"--view-port={view_port}", f"--view-host={view_host}"]
            args += [f"--view-speed={view_speed}"] if view_speed is not None else []
        if click.get_current_context().find_root().params.get("debug", False):
            args.append("--debug")
        if sys.stderr.isatty():         # the child writes to a pipe, relayed here: it redraws for a terminal
            args.append("--tty-progress")
        sys.exit(supervise(args, script=script.name, out=out, timeout=timeout))

    from robotexp.lua import run_script

    live = start_view(view, view_host, view_port, view_speed)
    progress = Progress(None, enabled=True if tty_progress else None)      # each run of the script
    try:
        with compile_watch(True if tty_progress else None):
            result = run_script(script, out=out, world=world, robot=robot, sandbox=sandbox, timeout=timeout,
                                emit=click.echo, notice=lambda text: click.echo(f"robotexp: {text}", err=True),
                                max_memory=None if memory is None else int(memory * 2**20),
                                allow_addresses=allow_address, retire=True,
                                observers=(progress,) if live is None else (progress, live.observer),
                                record=record, max_write=None if written is None else int(written * 2**20),
                                on_start=None if ready_fd is None else lambda: _say_ready(ready_fd))
    except BaseException:
        end_view(live, interrupted=True)
        raise
    finally:
        progress.close()
    click.echo(f"{script.name}: {len(result.records)} exploration(s); results: {out / 'results.jsonl'}", err=True)
    end_view(live, interrupted=False)
    if result.exit_code:
        sys.exit(result.exit_code)


@main.command()
@click.argument("backend")
@click.option("--world", "-w", default="dense", show_default=True,
              help="Built-in world name, or the path of a MobileSim .map or ROS .yaml map.")
@click.option("--pose", default=None, help="Start pose: a name of the world's poses, or x,y,theta in mm, mm, deg.")
@click.option("--port", type=int, default=None, help="TCP port on 127.0.0.1 (default: the backend's, 8101 for p3dx).")
@click.option("--pty", is_flag=True, help="Serve on a pseudo-terminal (prints its device path) instead of TCP.")
@click.option("--speedup", type=float, default=1.0, show_default=True, help="Robot time per wall time.")
@click.option("--udp", default=None, help="mavlink: send to a ground station at HOST:PORT (e.g. 127.0.0.1:14550).")
@click.option("--laser", default=None, help="Serve a laser on the simulated robot too (rplidar, hokuyo, lms2xx).")
@click.option("--laser-pose", default=None, help="Where that laser sits on the robot: X,Y,THETA [mm, mm, deg].")
@click.option("--odometry-error", default="none", show_default=True,
              help="Odometry error of the emulated robot's encoders, as explore's --odometry-error: none, p3dx, "
                   "kobuki, or key=value,... (the robot reports drifting odometry; its laser sees the truth).")
@handle_errors
def emulate(backend: str, world: str, pose: str | None, port: int | None, pty: bool, speedup: float,
            udp: str | None, laser: str | None, laser_pose: str | None, odometry_error: str) -> None:
    """Serve the simulated robot of a world over BACKEND's protocol (p3dx: replaces MobileSim), or
    a laser (BACKEND rplidar, hokuyo, lms2xx) on a still robot of the world."""
    import time

    from robotexp.laser_mount import emulate_devices

    odometry = None if odometry_error.strip().lower() in ("", "none") else odometry_error
    devices = emulate_devices(backend, world, pose=pose, port=port, pty=pty, speedup=speedup, udp=udp,
                              laser=laser, laser_pose=laser_pose, odometry=odometry)
    try:
        served = [(label, device) for label, device in devices if label != "simulator"]
        if [label for label, _ in served] == ["robot"]:
            click.echo(f"{backend} emulator of world {world!r} at {served[0][1].address} (speedup {speedup:g}); "
                       "Ctrl-C stops")
        else:
            for label, device in served:
                click.echo(f"{label}: {device.address}")
            click.echo(f"world {world!r}, speedup {speedup:g}; Ctrl-C stops", err=True)
        while True:
            time.sleep(0.5)
    except KeyboardInterrupt:
        click.echo("emulator stopped", err=True)
    finally:
        for _, device in reversed(devices):
            device.close()


def _status_line(state: Any) -> str:
    """One line of what a robot reports: pose, speeds, battery, bumpers, nearest obstacle."""
    p, v = state.pose, state.velocity
    near = [s.nearest() for s in (state.laser,) if s is not None]
    if state.sonar is not None:
        finite = [r for r in state.sonar.ranges.tolist() if math.isfinite(r)]
        near += [min(finite)] if finite else []
    nearest = f"{min(near) * 1000:.0f} mm" if near and math.isfinite(min(near)) else "none"
    battery = "?" if state.battery is None else f"{state.battery:.1f} V"
    bumped = "stalled" if state.stalled else ("bumper" if any(state.bumpers) else "free")
    return (f"t {state.time:7.1f} s  pose {p.x * 1000:7.0f} {p.y * 1000:7.0f} mm {math.degrees(p.theta):6.1f} deg  "
            f"v {v.v * 1000:5.0f} mm/s w {math.degrees(v.w):6.1f} deg/s  battery {battery}  {bumped}  "
            f"nearest {nearest}")


@main.command()
@click.argument("backend")
@click.argument("address")
@click.option("--drive", default=None, help="Drive at V,W (mm/s, deg/s) during --for; the robot stops after.")
@click.option("--for", "duration", type=float, default=2.0, show_default=True, help="How long [s] to drive / watch.")
@click.option("--laser", default=None, help="A laser of the robot's own, NAME:ADDRESS (rplidar:/dev/ttyUSB0).")
@click.option("--laser-pose", default=None, help="Where --laser sits on the robot: X,Y,THETA [mm, mm, deg].")
@click.option("--record", type=click.Path(dir_okay=False, path_type=Path), default=None, metavar="FILE.mcap",
              help="Record the states read (odometry, laser) as a ROS 2 bag in MCAP (robotexp replay maps it).")
@view_options
@handle_errors
def connect(backend: str, address: str, drive: str | None, duration: float, laser: str | None,
            laser_pose: str | None, record: Path | None, view: bool, view_port: int, view_host: str,
            view_speed: str | None) -> None:
    """Connect to robot BACKEND at ADDRESS, print what it says about itself and a live status line
    (with --view: its pose, laser, path and a map built from its scans in the browser)."""
    from robotexp.laser_mount import check_laser_options
    from robotexp.robot import Twist

    check_laser_options(laser, laser_pose)
    twist = None
    if drive is not None:
        try:
            v_mm, w_deg = (float(x) for x in drive.split(","))
        except ValueError:
            raise ConfigError(f"--drive {drive!r}: expected V,W in mm/s and deg/s, e.g. 200,0") from None
        twist = Twist(v_mm / 1000, math.radians(w_deg))
    if not (duration >= 0 and math.isfinite(duration)):
        raise ConfigError(f"--for must be >= 0 s, got {duration:g}")
    tty = sys.stdout.isatty()
    recorder = None
    if record is not None:
        from robotexp.bag.recorder import BagRecorder

        recorder = BagRecorder(record)
    live = start_view(view, view_host, view_port, view_speed)
    try:
        if live is None:
            _connect_watch(backend, address, twist, duration, tty, live, laser, laser_pose, recorder)
        else:
            with compile_watch():   # the view's map is built by the map kernels
                _connect_watch(backend, address, twist, duration, tty, live, laser, laser_pose, recorder)
    except BaseException:
        end_view(live, interrupted=True)
        raise
    finally:
        if recorder is not None:
            recorder.close()
    end_view(live, interrupted=False)


def _connect_watch(backend: str, address: str, twist: Any, duration: float, tty: bool, live: Any,
                   laser: str | None = None, laser_pose: str | None = None, recorder: Any = None) -> None:
    """`connect`'s watch of the robot for `duration` [s], driving at `twist` (None: not), shown in `live`,
    with `laser` (NAME:ADDRESS) attached at `laser_pose` when given, each state read written to
    `recorder` (a `robotexp.bag.recorder.BagRecorder`) when given."""
    import time

    from robotexp.laser_mount import connect_with_laser
    from robotexp.robot import new_scan
    from robotexp.view.watch import StateFeed

    with connect_with_laser(backend, address, laser, laser_pose) as robot:
        feed = None if live is None else StateFeed(live.hub, f"{backend} at {address}", robot.radius)
        info = robot.describe()
        click.echo("  ".join(f"{key}: {value}" for key, value in info.items()))
        lim = robot.limits
        click.echo(f"limits: {lim.v_max * 1000:.0f} mm/s, {math.degrees(lim.w_max):.0f} deg/s; "
                   f"capabilities: {', '.join(sorted(robot.capabilities)) or 'none'}")
        end, next_line = time.monotonic() + duration, 0.0
        t0: float | None = None
        written: float | None = None        # the stamp of the last scan written (each measurement once)
        try:
            while True:
                now = time.monotonic()
                if twist is not None:
                    robot.command(twist)
                due = now >= next_line or now >= end
                state = robot.read() if due or feed is not None or recorder is not None else None
                if feed is not None and state is not None:
                    feed.publish(state)
                if recorder is not None and state is not None:
                    t0 = state.time if t0 is None else t0
                    fresh = new_scan(state.laser, written)
                    recorder.write_state(state.time - t0, state, fresh)
                    if fresh:
                        assert state.laser is not None
                        written = state.laser.stamp
                if due:
                    line = _status_line(state)
                    click.echo(f"\r{line}" if tty else line, nl=not tty)
                    next_line = now + 0.5
                if now >= end or (feed is not None and feed.stop_requested):
                    break
                time.sleep(0.1)
        finally:
            robot.stop()
            if tty:
                click.echo("")
            if feed is not None:
                feed.finish("stopped from the live view" if feed.stop_requested else "watch over; robot stopped")
    click.echo("robot stopped and disconnected")


from robotexp.mapcmd import map_command  # noqa: E402  (a command of its own module, registered here)

map_command.callback = handle_errors(map_command.callback)  # type: ignore[type-var]
main.add_command(map_command)


if __name__ == "__main__":  # pragma: no cover
    main()
