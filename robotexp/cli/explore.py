"""`robotexp explore`: one exploration run, on the embedded simulator or a connected robot."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import click

from robotexp.cli.common import compile_watch, end_interrupted, fail, handle_errors, image_formats, mm, params
from robotexp.cli.progress import Progress
from robotexp.errors import ConfigError, WorldError
from robotexp.registry import make_explorer
from robotexp.robot import Capability
from robotexp.output.safefile import writable_folder
from robotexp.run.observers import RunObserver
from robotexp.run.record import EndReason
from robotexp.view.live import end_view, start_view, view_options

if TYPE_CHECKING:
    from robotexp.experiment import RunOutput
    from robotexp.run.spec import RunSpec
    from robotexp.run.team import TeamSpec

__all__ = ["explore"]

@click.command()
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
@click.option("--team", default=None, metavar="N|PRESET,...|BACKEND:ADDRESS,...",
              help="Explore with a team: N simulated robots of --robot, a list of presets (p3dx,p3dx,kobuki), or "
                   "robots over their drivers, BACKEND:ADDRESS[+LASER:ADDRESS] each (p3dx:127.0.0.1:8101,"
                   "kobuki:/dev/ttyUSB0+rplidar:/dev/ttyUSB1); one record for the team.")
@click.option("--team-poses", default=None, metavar="POSE;POSE;...",
              help="With --team: each robot's start pose (names or x,y,theta in mm, mm, deg), ';'-separated "
                   "(default: spread from --pose).")
@click.option("--coordinator", default="none", show_default=True,
              help="With --team: the coordinator plugin that shares out frontier targets (none, greedy, burgard, "
                   "minpos).")
@click.option("--coordinator-param", multiple=True, metavar="KEY=VALUE",
              help="A coordinator parameter (repeatable); --coordinator-param help lists the coordinator's "
                   "parameters.")
@click.option("--comm-range", type=float, default=None, metavar="MM",
              help="With --team: each robot keeps its own map and merges the scans of robots within this range "
                   "[mm] (default: one shared map).")
@view_options
@handle_errors
def explore(world: str, method: str, pose: str | None, speed: float, laser_range: float, cell: float | None,  # noqa: C901
            seed: int, robot: str, address: str | None, laser: str | None, laser_pose: str | None,
            param: tuple[str, ...], show: str, max_time: float, noise_uniform: float, noise_sigma: float,
            odometry_error: str, localize: str, out: Path, bounds: str | None, bounds_wall: bool,
            record: Path | None, frames: Path | None, frame_every: float, image_format: str, team: str | None,
            team_poses: str | None, coordinator: str, coordinator_param: tuple[str, ...], comm_range: float | None,
            view: bool, view_port: int, view_host: str, view_speed: str | None) -> None:
    """Run one exploration on the embedded simulator (or a robot: --address) and write its results."""
    from robotexp.experiment import run_experiment, run_on_robot
    from robotexp.run.laser_mount import check_laser_options, connect_with_laser
    from robotexp.run.spec import RunSpec
    from robotexp.world.bounds import parse_bounds

    if "help" in param:         # -p help: the method's parameters, nothing run
        from robotexp.cli.paramhelp import parameters_text
        click.echo(parameters_text(method))
        return
    if "help" in coordinator_param:     # --coordinator-param help: the coordinator's, nothing run
        from robotexp.cli.paramhelp import parameters_text
        click.echo(parameters_text(coordinator, coordinator=True))
        return
    hint = _pose_hint(pose)     # said once the run starts, or with the error of a start that is refused

    robot_team = team is not None and _robot_team(team)
    if (laser is not None or (laser_pose is not None and not robot_team)) and address is None:
        raise ConfigError("--laser and --laser-pose attach a laser to a robot at --address (a team's robots: "
                          "BACKEND:ADDRESS+LASER:ADDRESS in --team); the embedded simulator has its own")
    check_laser_options(laser, None if robot_team else laser_pose)
    if robot_team and laser_pose is not None:
        from robotexp.run.laser_mount import parse_laser_pose

        parse_laser_pose(laser_pose)
    overlays = tuple(s for s in show.split(",") if s)
    formats = image_formats(image_format)
    unknown = set(overlays) - {"grid", "laser", "vectors", "potential"}
    if unknown:
        raise ConfigError(f"--show: unknown overlay(s) {', '.join(sorted(unknown))}; "
                          "use grid, laser, vectors, potential")
    if speed <= 0 or not math.isfinite(speed):
        raise ConfigError(f"--speed must be > 0 mm/s, got {speed:g}")
    spec = RunSpec(world=world, method=method, pose=pose, speed=speed / 1000, seed=seed, robot=robot,
                   laser_range=mm(laser_range, "--laser-range") or 3.0, cell=mm(cell, "--cell"),
                   params=params(param), max_time=max_time, laser_uniform=noise_uniform / 1000,
                   laser_sigma=noise_sigma / 1000, bounds_wall=bounds_wall,
                   map_bounds=None if bounds is None else parse_bounds(bounds),
                   odometry=odometry_error, localize=localize)
    spec.validate()
    team_spec = _team_spec(team, team_poses, coordinator, coordinator_param, comm_range, robot, address,
                           (record, frames, view))
    writable_folder(out)
    # the method and its parameters before anything starts: the plugins' scan reads every installed
    # distribution's metadata, which a live view's clients could leave no file descriptor for
    make_explorer(spec.method, spec.params)
    live = start_view(view, view_host, view_port, view_speed)
    progress = Progress(f"{Path(world).stem} {method}", notice=None if hint is None else f"robotexp: {hint}",
                        say_start=address is None)
    watchers: list[RunObserver] = [progress] if live is None else [progress, live.observer]
    if frames is not None:
        from robotexp.output.video import FrameObserver, PngFrames

        watchers.append(FrameObserver(PngFrames(frames), frame_every, overlays))
    recorder = None
    if record is not None:
        from robotexp.bag.recorder import BagRecorder

        recorder = BagRecorder(record, world=world)
        watchers.append(recorder)
    try:
        with compile_watch():       # the first run after an install: numba compiles, said as it happens
            if team_spec is not None and team_spec.members:
                result = _explore_robot_team(spec, team_spec, out, world, laser_pose, watchers, overlays, formats)
            elif team_spec is not None:
                from robotexp.experiment import run_team

                result = run_team(spec, team_spec, out, observers=watchers, show=overlays, image=formats)
            elif address is None:
                result = run_experiment(spec, out, observers=watchers, show=overlays, image=formats)
            else:
                given = click.get_current_context().get_parameter_source("world")
                truth_world = None if given == click.core.ParameterSource.DEFAULT else world
                with connect_with_laser(robot, address, laser, laser_pose) as bot:
                    if localize == "auto" and (laser is not None or Capability.LASER in bot.capabilities):
                        click.echo("robotexp: --localize auto: scan matching corrects the robot's odometry before "
                                   "the map and the explorer see it (--localize none turns it off)", err=True)
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
    if r.completed and r.coverage is not None and r.coverage_inside is not None and \
            round(r.coverage_inside * 1000) > round(r.coverage * 1000):    # explored, short by a fringe along the walls
        cov += f" (floor away from the walls {r.coverage_inside * 100:.1f}%)"
    ate = r.extra.get("ate_m")          # with an odometry error: how far the pose the explorer got was off
    if r.extra.get("odometry_error") in (None, "none") and r.extra.get("localize") in (None, "none"):
        ate = None                      # exact odometry: nothing to say
    extra = ("" if r.map_iou is None else f", map IoU {r.map_iou:.3f}") + ("" if ate is None else f", ATE {ate:.3f} m")
    click.echo(f"{r.run}: {r.reason}; path {r.path_length_m:.1f} m, robot time {r.robot_time_s:.0f} s "
               f"(wall {r.wall_time_s:.1f} s), coverage {cov}{extra}, collisions {r.collisions}")
    if r.team_size is not None:
        click.echo(f"team of {r.team_size} ({r.coordinator}): total path {r.total_path_m:.1f} m, longest "
                   f"{r.max_path_m:.1f} m, overlap {0 if r.overlap_ratio is None else r.overlap_ratio * 100:.1f}%, "
                   f"idle {r.idle_time_s:.0f} s, robot-robot collisions {r.robot_collisions}")
    click.echo(f"results: {out / 'results.jsonl'}" + (f", map: {result.image}" if result.image else ""))
    end_view(live, result.interrupted)
    if result.interrupted:
        from robotexp.run.loop import TERMINATED_REASON

        end_interrupted(r.reason == TERMINATED_REASON)
    if r.end in (EndReason.ROBOT_ERROR, EndReason.PLUGIN_ERROR):     # written, but the run failed
        fail(f"{r.run}: {r.reason}", 1)


def _team_spec(team: str | None, poses: str | None, coordinator: str, coordinator_param: tuple[str, ...],  # noqa: PLR0913
               comm_range: float | None, robot: str, address: str | None,
               recorders: tuple[object, ...]) -> TeamSpec | None:
    """The team of `--team`, checked (None without it)."""
    from robotexp.run.team import TeamSpec, parse_team

    source = click.get_current_context().get_parameter_source
    team_only = [name for name in ("team_poses", "coordinator", "coordinator_param", "comm_range")
                 if source(name) != click.core.ParameterSource.DEFAULT]
    if team is None:
        if team_only:
            raise ConfigError(f"--{team_only[0].replace('_', '-')} needs --team")
        return None
    if address is not None:
        raise ConfigError("--team takes the robots' addresses itself (--team p3dx:HOST:PORT,kobuki:/dev/ttyUSB0); "
                          "leave out --address")
    members: tuple[str, ...] = ()
    if _robot_team(team):
        from robotexp.run.teamrobots import check_members, parse_members

        if any(r not in (None, False) for r in recorders):
            raise ConfigError("--team over robots' addresses: --record, --frames and --view show simulated teams "
                              "only; leave them out")
        parsed = parse_members(team)
        check_members(parsed)
        members, names = tuple(m.text for m in parsed), tuple(m.backend for m in parsed)
    else:
        names = parse_team(team, robot)
    spec = TeamSpec(robots=names, coordinator=coordinator, members=members,
                    coordinator_params=params(coordinator_param, "--coordinator-param"),
                    comm_range=mm(comm_range, "--comm-range"),
                    poses=_team_poses(poses))
    spec.validate()
    if members and not spec.poses and source("world") == click.core.ParameterSource.DEFAULT:
        raise ConfigError("--team: robots over their drivers need --world (ground truth and where they start, as "
                          "`robotexp emulate` placed them) or --team-poses (where each one stands)")
    return spec


def _team_poses(text: str | None) -> tuple[str, ...]:
    """`--team-poses "x,y,theta;x,y,theta;..."` (one pose each, mm and degrees); () without it."""
    if text is None:
        return ()
    poses = tuple(p.strip() for p in text.split(";") if p.strip())
    if not poses:
        raise ConfigError(f"--team-poses: no pose in {text!r}; give one pose per robot, "
                          "\"x,y,theta;x,y,theta\" (mm, mm, degrees)")
    return poses


def _robot_team(team: str) -> bool:
    from robotexp.run.teamrobots import is_address_team

    return is_address_team(team)


def _explore_robot_team(spec: RunSpec, team: TeamSpec, out: Path, world: str,  # noqa: PLR0913
                        laser_pose: str | None, watchers: list[RunObserver], overlays: tuple[str, ...],
                        formats: tuple[str, ...]) -> RunOutput:
    """`explore --team BACKEND:ADDRESS,...`: connect the robots (each stopped and closed whatever way the run
    ends) and run the team on them; the world, when given, is ground truth and says where they start."""
    from dataclasses import replace

    from robotexp.experiment import run_team_on_robots
    from robotexp.run.teamrobots import connect_team, parse_members

    if spec.localize in ("scan-match", "slam"):
        raise ConfigError("--team: teams run on the robots' odometry, with no localizer for now; leave out --localize")
    given = click.get_current_context().get_parameter_source("world")
    truth_world = None if given == click.core.ParameterSource.DEFAULT else world
    robots = connect_team(parse_members(",".join(team.members)), laser_pose)
    click.echo(f"robotexp: connected {len(robots)} robots: "
               + ", ".join(f"{r.model} at {r.address}" for r in robots), err=True)
    try:
        return run_team_on_robots(replace(spec, localize="none"), team, robots, out, truth_world, observers=watchers,
                                  show=overlays, image=formats)
    finally:
        for robot in reversed(robots):
            robot.close()            # stops it first


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
