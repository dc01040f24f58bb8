"""The IfTEA scripting API (thesis section 4.2.2) as plain Python functions for Lua tables.

Units are IfTEA's at this edge: millimetres, mm/s, milliseconds, degrees; everything is SI inside.
`Session` holds the settings and the runs of one script; `Session.functions()` gives the tables
(`robot`, `exploration`, `mapView`, `robotView`; `team`: `robotexp.lua.team`) of plain functions the
prelude wraps. Each function checks its arguments and raises `ScriptError` naming itself and what it expects.

Runs. `exploration.start()` validates the settings and arms a run; `exploration.wait()` runs it to
the end on the stepped simulator. Calls that need a result (`elapsedTime`, `pathLength`,
`results`, `saveMapImage`, `moveMobileSim`, `getPose`) and the next `start` first finish an armed
run, and so does the end of the script. Each finished run is appended to OUT/results.jsonl at
once. Between runs the robot stays where its last run ended, unless `robot.moveMobileSim` moves it.

Robots. With a P3-DX address (`robot.setAddress("host[:port]")` or a serial device) and no
`robotexp run --world`, runs go to a connected `p3dx` robot (MobileSim, our emulator or the real
one) through `run_on_robot`, at the robot's pace (a robot model with a backend of its own,
`robot.setModel("kobuki")` or `robotexp run --robot kobuki`, connects that backend instead): one
connection for the whole script, opened at the first `exploration.start()` (or `robot.getPose()`),
closed by `Session.close()` (robot stopped). `robot.moveMobileSim` then sends SIM_SET_POSE (at
once when connected, else right after connecting). Coverage is null unless the script names a
world with `exploration.setWorld`, which is then ground truth only (as `robotexp explore
--address --world`).

Lasers. `robot.setLaser("NAME:ADDRESS", x, y, theta)` mounts a laser device (`robotexp.lasers`) at
(x [mm], y [mm], theta [deg]) on the robot of the address, as `robotexp explore --laser --laser-pose`
does (`robotexp.run.laser_mount`): runs then map from its scans, each paired with the robot's pose at
its stamp. Its address obeys the script's address rule (`--sandbox`, `--allow-address`).
"""

from __future__ import annotations

import logging
import math
import os
import re
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robotexp.errors import RobotError, RobotexpError, ScriptError
from robotexp.lua.sandbox import AddressPolicy, lua_kind, parameter_args
from robotexp.lua.team import TeamCalls
from robotexp.run.observers import RunObserver
from robotexp.run.record import EndReason
from robotexp.robot import Capability, Pose

if TYPE_CHECKING:
    from robotexp.experiment import RunOutput
    from robotexp.run.spec import RunSpec
    from robotexp.run.loop import ExplorationRun
    from robotexp.run.record import RunRecord
    from robotexp.robot import Robot
    from robotexp.lua.sandbox import AddressPolicy, PathPolicy
    from robotexp.world.model import World

__all__ = ["Session", "Control", "P3DX_PORT", "parse_address"]

log = logging.getLogger(__name__)

P3DX_PORT = 8101        # MobileSim's and ARIA's default TCP port
ROBOT_BACKEND = "p3dx"  # the `robotexp.robots` backend of a non-sim address (the P3-DX protocol) ...
ADDRESS_MODELS = ("kobuki",)   # ... unless the robot model is one of these (its own backend)
TRACK_WINDOW = (800, 600)       # [px] image size around the robot when tracking is on
MIN_FIGURE_DPI = 100            # saveMapImage: a map drawn at fewer px/m keeps this resolution (text stays legible)
MAX_IMAGE_PIXELS = 1e8          # a map image larger than 10000 x 10000 px is refused (memory, not a picture)
_UPDATE_PARAMS = ("update_period",)   # explorer parameter names of the potential update interval [s]
_NAME = {"n": "a number", "s": "a string", "b": "a boolean", "i": "an integer"}


class Control:
    """Why a script must stop now (Ctrl-C, --timeout, os.exit), shared by the hook and the runs.

    Args:
        timeout: [s] wall-time limit of the script, or None.
        clock: monotonic clock [s] (time.monotonic).
        on_run: told True when a run of the script starts, False when it is over (`running`).
    """

    def __init__(self, timeout: float | None, clock: Callable[[], float],
                 on_run: Callable[[bool], None] | None = None) -> None:
        self.timeout = timeout
        self.clock = clock
        self.deadline = None if timeout is None else clock() + timeout
        self.reason: str | None = None      # "interrupted", "timeout", "exit"
        self.terminated = False             # "interrupted" by a SIGTERM (not a Ctrl-C)
        self.exit_code = 0
        self.on_run = on_run

    def check(self) -> bool:
        """True when the script must stop (the deadline passing sets reason "timeout")."""
        if self.reason is None and self.deadline is not None and self.clock() >= self.deadline:
            self.reason = "timeout"
        return self.reason is not None

    @contextmanager
    def running(self) -> Iterator[None]:
        """Around one run of the script: says so (`on_run` True, then False once the run is over, written or
        failed). No Lua code runs during a run, so a script in one cannot be stuck where the hook cannot stop it:
        the supervisor's kill at the timeout waits for the run to be written, `robotexp.lua.supervise`."""
        if self.on_run is not None:
            self.on_run(True)
        try:
            yield
        finally:
            if self.on_run is not None:
                self.on_run(False)


def parse_address(address: str) -> tuple[str, str]:
    """Classify a robot address: ("sim", "") for "" or "sim", ("serial", path) for a device path,
    ("tcp", "host:port") otherwise (port 8101 by default).

    Raises:
        ScriptError: a host:port whose port is not an integer 1..65535.
    """
    a = address.strip()
    if a in ("", "sim"):
        return "sim", ""
    if a.startswith(("/", "\\\\.\\")) or re.fullmatch(r"(?i)com\d+", a):
        return "serial", a
    host, sep, port = a.rpartition(":")
    if not sep:
        return "tcp", f"{a}:{P3DX_PORT}"
    if not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ScriptError(f"robot.setAddress({address!r}): expected '' or 'sim' (embedded simulator), "
                          "'host' or 'host:port' (P3-DX over TCP, port 1..65535) or a serial device path")
    return "tcp", a


def _args(fname: str, usage: str, args: tuple[Any, ...], kinds: str) -> list[Any]:
    """Check `args` against `kinds` (n number, i integer, s string, b boolean); return them.

    Raises:
        ScriptError: wrong count or kind, naming `fname(usage)`.
    """
    if len(args) != len(kinds):
        raise ScriptError(f"{fname}({usage}): expected {len(kinds)} argument(s), got {len(args)}")
    for i, (value, kind) in enumerate(zip(args, kinds, strict=True), start=1):
        ok = {"n": isinstance(value, (int, float)) and not isinstance(value, bool)
              and math.isfinite(value),
              "i": isinstance(value, int) and not isinstance(value, bool),
              "s": isinstance(value, str),
              "b": isinstance(value, bool)}[kind]
        if not ok:
            raise ScriptError(f"{fname}({usage}): argument {i} must be {_NAME[kind]}"
                              f"{' (finite)' if kind == 'n' else ''}, got {lua_kind(value)}")
    return list(args)



class _ScriptWatch(RunObserver):
    """The run observer of a script's runs: a map frame every redraw interval (`mapView.setFrameFolder`)
    and the script's --timeout, checked at each coverage sample."""

    def __init__(self, session: Session) -> None:
        self.session = session

    def on_sample(self, run: ExplorationRun, time: float, coverage: float | None) -> None:
        """Save a frame when one is due; stop the run when the script's time is up."""
        self.session._on_run(run)

def _pose_text(p: Pose) -> str:
    """`p` as a RunSpec pose: "x,y,theta" in mm, mm, degrees."""
    return f"{p.x * 1000!r},{p.y * 1000!r},{math.degrees(p.theta)!r}"


def _positive(fname: str, usage: str, value: float, unit: str) -> float:
    if not value > 0:
        raise ScriptError(f"{fname}({usage}): expected a value > 0 {unit}, got {value:g}")
    return float(value)


class Session:
    """The state of one script: settings, view options, the robot's pose and the runs (its team's, the
    `team` table's, in `team`: `robotexp.lua.team.TeamCalls`).

    Args:
        out: output folder (results.jsonl, images).
        paths: the path rule of the script (relative to `out`; sandbox).
        control: the stop flags (Ctrl-C, --timeout).
        world: the world given by `robotexp run --world`, or None (default "dense").
        robot: simulated robot preset (p3dx, kobuki).
        notice: prints a one-line notice for the user (stderr).
        script: the script's name, recorded with each run.
        addresses: which robot addresses the script may open (default: any).
        observers: told about each of the script's runs (`robotexp run --view`).
    """

    def __init__(self, *, out: Path, paths: PathPolicy, control: Control, world: str | None = None,
                 robot: str = "p3dx", notice: Callable[[str], None] = log.info, script: str = "",
                 addresses: AddressPolicy | None = None, observers: Sequence[RunObserver] = ()) -> None:
        from robotexp.run.spec import RunSpec

        self.out, self.paths, self.control, self.notice, self.script = out, paths, control, notice, script
        self.addresses = addresses if addresses is not None else AddressPolicy(False)
        self.observers = list(observers)               # told about every run (a live view)
        self.forced_world = world is not None
        self.spec = RunSpec(world=world or "dense", robot=robot)
        self.address = ""
        self.target: tuple[str, str] = ("sim", "")     # parse_address(self.address)
        self.connected: Robot | None = None            # the robot of a P3-DX address, once connected
        self.laser: tuple[str, str] | None = None      # robot.setLaser: ("NAME:ADDRESS", "x,y,theta" mm/deg)
        self._mounted: tuple[str, str] | None = None   # the laser mounted on self.connected
        self.truth_world = False                       # the script named a world (exploration.setWorld)
        self._move_pending = False                     # moveMobileSim not yet sent to the robot
        self._moved = False                            # self.pose comes from moveMobileSim (no run since)
        self.potential_interval: float | None = None   # [s]
        self.pose: Pose | None = None                  # where the next run starts (None: world default)
        # view (IfTEA's Display menu)
        self.scaling: float | None = None              # [px/mm]; None: fit the image to 1400 px
        self.zoom = 1.0
        self.show: dict[str, bool] = {"grid": False, "path": True, "laser": False, "vectors": False,
                                      "potential": False, "tracking": False}
        self.frame_folder: Path | None = None
        self.record_folder: Path | None = None         # each run as a ROS 2 bag there (exploration.setRecordFolder)
        self.redraw_interval = 1.0                     # [s] robot time between frames
        self.frames = 0
        self.armed: RunSpec | None = None
        self.last: RunOutput | None = None
        self.records: list[RunRecord] = []
        self._told_forced = False
        self._told_laser = False
        self._worlds: dict[str, World] = {}
        self.team = TeamCalls(self)

    # -- plumbing ----------------------------------------------------------------------------------
    def functions(self) -> dict[str, dict[str, Callable[..., Any]]]:
        """The Lua tables: {table: {function name: callable}}, each callable checked and named."""
        tables: dict[str, dict[str, Callable[..., Any]]] = {}
        for owner in (self, self.team):
            for attr in dir(owner):
                if not attr.startswith("lua_"):
                    continue
                table, _, name = attr[4:].partition("__")
                tables.setdefault(table, {})[name] = self._entry(f"{table}.{name}", getattr(owner, attr))
        return tables

    @staticmethod
    def _entry(qualname: str, method: Callable[..., Any]) -> Callable[..., Any]:
        def call(*args: Any) -> Any:
            try:
                return method(*args)
            except ScriptError:
                raise
            except (RobotexpError, OSError) as exc:
                raise ScriptError(f"{qualname}: {exc}") from exc
        call.__name__ = qualname
        return call

    def methods(self) -> dict[str, str]:
        """ExplorationMethod: IfTEA spelling -> plugin name, for every installed explorer."""
        from robotexp.registry import EXPLORERS, available, lua_name
        return {lua_name(name): name for name in available(EXPLORERS)}

    def world(self) -> World:
        """The current world (loaded once per name)."""
        from robotexp.world.loader import load_world
        name = self.spec.world
        if name not in self._worlds:
            self._worlds[name] = load_world(name)
        return self._worlds[name]

    def current_pose(self) -> Pose:
        """Where the next run starts: the last moveMobileSim or run end, else the world's default."""
        if self.on_robot:
            if self.connected is None and self.pose is not None:     # placed by moveMobileSim, not sent yet
                return self.pose
            return self._robot().read().pose
        if self.pose is not None:
            return self.pose
        from robotexp.sim import preset
        from robotexp.world.poses import resolve_pose
        return resolve_pose(self.world(), None, preset(self.spec.robot).radius)[0]

    def finish(self) -> None:
        """Run the armed exploration to its end (nothing when none is armed).

        Raises:
            ScriptError: the script must stop (Ctrl-C, --timeout) once the run is written.
        """
        spec, self.armed = self.armed, None
        if spec is None:
            return
        from robotexp.experiment import run_experiment, run_on_robot

        self._next_frame = 0.0
        observers = self._observers(spec)
        with self.control.running():
            if self.on_robot:
                robot = self._robot()
                if self.laser is None and hasattr(robot, "laser_range"):   # beams beyond it read as no hit (P3DXRobot)
                    robot.laser_range = spec.laser_range
                if self.truth_world and self.pose is not None and not self._moved:
                    # run_on_robot moves the robot to the start: start where it stands now, not where
                    # the last run's final state was (it went on turning and slowing after it)
                    spec.pose = _pose_text(robot.read().pose)
                output = run_on_robot(spec, robot, self.out, self.world() if self.truth_world else None,
                                      image=False, record_extra={"script": self.script}, observers=observers)
            else:
                output = run_experiment(spec, self.out, image=False, record_extra={"script": self.script},
                                        observers=observers)
        self.last, self._moved = output, False
        self.records.append(output.record)
        state = output.run.state
        if state is not None:
            self.pose = state.true_pose or state.pose
        if self.control.check():
            raise ScriptError("exploration stopped")    # the runtime reports the real reason
        record = output.record
        if record.end is EndReason.ROBOT_ERROR:         # as a plugin error: the script stops, the record is written
            raise RobotError(f"run {record.run} ended: {record.reason} (its record is in results.jsonl)")

    def _observers(self, spec: RunSpec) -> list[RunObserver]:
        """The observers of a run of the script: its frames and --timeout, the caller's, its recorder."""
        watch = self.frame_folder is not None or self.control.deadline is not None
        observers = ([_ScriptWatch(self)] if watch else []) + self.observers
        if self.record_folder is not None:
            from robotexp.bag.recorder import BagRecorder

            observers.append(BagRecorder(folder=self.record_folder, world=spec.world))
        return observers

    @property
    def on_robot(self) -> bool:
        """True when runs go to a connected robot (a P3-DX address and no `robotexp run --world`)."""
        return self.target[0] != "sim" and not self.forced_world

    @property
    def backend(self) -> str:
        """The `robotexp.robots` backend of the address: the robot model's own, else the P3-DX's."""
        return self.spec.robot if self.spec.robot in ADDRESS_MODELS else ROBOT_BACKEND

    def _robot(self) -> Robot:
        """The robot of the address, connected on first use, with the laser of robot.setLaser mounted;
        a pending moveMobileSim is sent.

        Raises:
            ScriptError: the robot or its laser cannot be reached (naming the call and the address).
        """
        if self.connected is None:
            from robotexp.run.laser_mount import robot_options
            from robotexp.registry import connect_robot
            kind, where = self.target
            backend = self.backend
            if kind == "tcp" and backend != ROBOT_BACKEND:
                where = self.address.strip()           # host:8101 is the P3-DX's default, not this robot's
            try:
                options = robot_options(backend, self.laser is not None)
                self.connected = connect_robot(backend, where, **options)
            except RobotexpError as exc:
                shown, peer = ("P3-DX", "MobileSim or ") if backend == ROBOT_BACKEND else (backend, "")
                raise ScriptError(f"robot.setAddress({self.address!r}): cannot connect to a {shown} ({kind} {where}): "
                                  f"{exc}; start {peer}`robotexp emulate {backend}` there, or use '' for the "
                                  "embedded simulator") from exc
            self._mounted = None
            log.info("lua: connected to %s at %s", backend, where)
        if self.laser != self._mounted:
            self._mount_laser(self.connected)
        if self._move_pending and self.pose is not None:
            self._move_pending = False
            self._place(self.connected, self.pose)
        return self.connected

    def _place(self, robot: Robot, pose: Pose) -> None:
        if Capability.MOVE_TO not in robot.capabilities:
            raise ScriptError(f"robot.moveMobileSim: the robot at {self.address!r} ({robot.name}) cannot be "
                              "moved or told its pose")
        robot.move_to(pose)

    def _mount_laser(self, robot: Robot) -> None:
        """Mount the laser of robot.setLaser on the connected `robot` (replacing the one mounted before).

        Raises:
            ScriptError: the laser cannot be reached (the robot stays connected; the script's end stops it).
        """
        from robotexp.run.laser_mount import LaserMountedRobot, connect_laser, parse_laser_pose

        if isinstance(robot, LaserMountedRobot):
            robot.laser.close()
            robot = robot.robot
        self.connected, self._mounted = robot, None
        if self.laser is None:
            return
        spec, pose = self.laser
        try:
            laser = connect_laser(spec)
        except RobotexpError as exc:
            raise ScriptError(f"robot.setLaser({spec!r}): cannot connect to the laser: {exc}") from exc
        self.connected = LaserMountedRobot(robot, laser, parse_laser_pose(pose))
        self._mounted = self.laser
        log.info("lua: laser %s mounted at %s mm, mm, deg", spec, pose)

    def close(self) -> None:
        """Stop the connected robot and close its link (nothing without one). Safe to call twice."""
        robot, self.connected, self._mounted = self.connected, None, None
        if robot is not None:
            try:
                robot.close()
            except RobotexpError as exc:      # a robot already gone cannot be stopped either
                log.warning("lua: closing the robot at %s: %s", self.address, exc)

    def _on_run(self, run: ExplorationRun) -> None:
        if self.frame_folder is not None and run.robot_time >= self._next_frame:
            from robotexp.output.render import save_png
            self.frames += 1
            self.paths.quota.check("mapView.setFrameFolder")
            self._charge(save_png(self._image(run), self.frame_folder / f"frame_{self.frames:06d}.png"))
            self._next_frame += self.redraw_interval
        if self.control.check() and self.control.reason == "timeout":
            run.request_stop(f"stopped: the script's --timeout of {self.control.timeout:g} s was reached")

    def _scale(self, run: ExplorationRun, title: str) -> float:
        """[px per cell] the scale the script asked for (mapView.setMapScaling, zoom; default: fit 1400 px),
        refused when the image would be too large to be a picture."""
        from robotexp.output.render import map_layout

        geo = run.grid.geo
        if self.scaling is None:
            base = float(map_layout(geo, scale=None, title=title).scale)
        else:
            base = self.scaling * geo.cell * 1000.0       # px/mm -> px per cell
        wanted = base * self.zoom
        if not wanted * wanted * geo.rows * geo.cols <= MAX_IMAGE_PIXELS:     # inf and nan refused too
            raise ScriptError(f"mapView: the map image would be {geo.cols * wanted:.3g} x {geo.rows * wanted:.3g} px, "
                              f"more than {MAX_IMAGE_PIXELS:.0e} pixels; lower mapView.setMapScaling or zoomOut")
        return wanted

    def _show(self) -> tuple[str, ...]:
        return tuple(k for k in ("grid", "laser", "vectors", "potential") if self.show[k])

    def _image(self, run: ExplorationRun) -> Any:
        """The fast raster image (frames, tracking view), titled by the figures' convention."""
        from robotexp.output.figures import run_title
        from robotexp.output.render import map_layout
        from robotexp.output.results import map_image

        title = run_title(run, f"{run.metrics.path_length:.1f} m")
        scale = max(1, round(self._scale(run, title)))
        image = map_image(run, title, self._show(), scale=scale, path=self.show["path"])
        state = run.state
        if self.show["tracking"] and state is not None:
            p = state.true_pose or state.pose
            cx, cy = map_layout(run.grid.geo, scale=scale, title=title).to_pixel(p.x, p.y)
            w, h = min(TRACK_WINDOW[0], image.width), min(TRACK_WINDOW[1], image.height)
            left = int(min(max(cx - w / 2, 0), image.width - w))
            top = int(min(max(cy - h / 2, 0), image.height - h))
            image = image.crop((left, top, left + w, top + h))
        return image

    def _save_figure(self, run: ExplorationRun, target: Path) -> Path:
        """The run's map figure (`robotexp.output.figures.run_map_figure`, as the CLI's) at the scale asked: the map
        drawn at mapView's pixels per metre (at least MIN_FIGURE_DPI), PNG, or SVG / PDF by `target`'s suffix."""
        from robotexp.output.figures import run_map_figure, run_title, write_figure

        scale = self._scale(run, run_title(run))
        fig = run_map_figure(run, show=self._show(), path=self.show["path"])
        ax = fig.axes[0]
        x0, x1 = ax.get_xlim()
        axes_in = ax.get_position().width * fig.get_figwidth()
        dpi = max(MIN_FIGURE_DPI, scale / run.grid.geo.cell * (x1 - x0) / axes_in)
        fmt = target.suffix.lower().lstrip(".")
        return write_figure(fig, target, fmt if fmt in ("svg", "pdf") else "png", dpi)

    def _last(self, fname: str) -> RunOutput:
        self.finish()
        if self.last is None:
            raise ScriptError(f"{fname}: no exploration has run yet; call exploration.start() and "
                              "exploration.wait() first")
        return self.last

    def _flag(self, fname: str, key: str, args: tuple[Any, ...]) -> None:
        (self.show[key],) = _args(fname, "on", args, "b")

    # -- robot ---------------------------------------------------------------------------------------
    def lua_robot__setAddress(self, *args: Any) -> None:
        """'' or 'sim': embedded simulator; 'host[:port]' (TCP, 8101) or a device path (serial): a P3-DX.

        Ignored (said once) when `robotexp run --world` was given: the script stays on the simulator.
        """
        (address,) = _args("robot.setAddress", "address", args, "s")
        self.addresses.check(address, "robot.setAddress")
        target = parse_address(address)
        if target[0] != "sim" and self.forced_world and not self._told_forced:
            self.notice(f"robot.setAddress({address!r}): --world {self.spec.world} given, so the script "
                        "runs on the embedded simulator of that world")
            self._told_forced = True
        self.finish()
        if target != self.target and not self.forced_world:   # another robot: its pose is its own
            self.close()
            if not self._moved:
                self.pose = None
            self._move_pending = self._moved and target[0] != "sim"
        self.address, self.target = address, target

    def lua_robot__setLaser(self, *args: Any) -> None:
        """A laser device "NAME:ADDRESS" (rplidar:/dev/ttyUSB0) mounted at (x [mm], y [mm], theta [deg]) on
        the robot of robot.setAddress (default 0, 0, 0); nil: no laser of its own (the robot's).

        Ignored (said once) when the script runs on the embedded simulator, which has its own laser.
        """
        from robotexp.laser import LASERS
        from robotexp.run.laser_mount import check_laser_options, parse_laser_spec
        from robotexp.registry import available

        usage = "address, x_mm, y_mm, theta_deg"
        if len(args) == 1 and args[0] is None:
            self.finish()
            self.laser = None
            return
        spec, *pose = _args("robot.setLaser", usage, args, "snnn" if len(args) > 1 else "s")
        pose_text = ",".join(repr(float(v)) for v in pose) if pose else "0,0,0"
        try:
            check_laser_options(spec, pose_text)
        except RobotexpError as exc:
            raise ScriptError(f"robot.setLaser({spec!r}): {exc}") from None
        name, address = parse_laser_spec(spec)
        lasers = available(LASERS)
        if name not in lasers:
            raise ScriptError(f"robot.setLaser({spec!r}): unknown laser {name!r}; available: {', '.join(lasers)}")
        self.addresses.check(address, "robot.setLaser")
        self.finish()
        self.laser = (spec, pose_text)

    def lua_robot__setMaxLaserRange(self, *args: Any) -> None:
        """Laser range [mm]."""
        (mm,) = _args("robot.setMaxLaserRange", "range_mm", args, "n")
        self.spec.laser_range = _positive("robot.setMaxLaserRange", "range_mm", mm, "mm") / 1000.0

    def lua_robot__setLaserNoise(self, *args: Any) -> None:
        """robot.setLaserNoise(uniform_mm[, sigma_mm]): noise on the embedded simulator's laser for the
        following runs.

        Every range that hits something gets an error drawn uniformly in +-`uniform_mm` [mm] plus, when
        `sigma_mm` [mm] is given, a gaussian one with that standard deviation (default 0: none); the
        UFMG study's laser is `robot.setLaserNoise(100)`. Both >= 0; `robot.setLaserNoise(0)` turns the
        noise off. The draws follow `exploration.setSeed`. A real laser (robot.setAddress, robot.setLaser)
        reads as it reads: the setting is for the simulator. The same as `robotexp explore --noise-uniform
        MM --noise-sigma MM` and the campaign keys `laser_uniform_mm`, `laser_sigma_mm`.

        Raises:
            ScriptError: not one or two numbers, or a negative or non-finite one
                (`script.lua:LINE: robot.setLaserNoise(-5): expected noise >= 0 mm`).
        """
        usage = "uniform_mm[, sigma_mm]"
        values = _args("robot.setLaserNoise", usage, args, "nn" if len(args) == 2 else "n")
        from robotexp.run.spec import MAX_LASER_NOISE

        if not all(0 <= v <= MAX_LASER_NOISE * 1000 for v in values):
            raise ScriptError(f"robot.setLaserNoise({', '.join(f'{v:g}' for v in values)}): expected noise within "
                              f"0..{MAX_LASER_NOISE * 1000:g} mm")
        self.spec.laser_uniform = values[0] / 1000.0
        self.spec.laser_sigma = values[1] / 1000.0 if len(values) == 2 else 0.0

    def lua_robot__setMaxSpeed(self, *args: Any) -> None:
        """Maximum forward speed [mm/s]."""
        (v,) = _args("robot.setMaxSpeed", "speed_mm_s", args, "n")
        self.spec.speed = _positive("robot.setMaxSpeed", "speed_mm_s", v, "mm/s") / 1000.0

    def lua_robot__setModel(self, *args: Any) -> None:
        """The simulated robot (p3dx, kobuki)."""
        from robotexp.sim import PRESETS
        (name,) = _args("robot.setModel", "name", args, "s")
        if name not in PRESETS:
            raise ScriptError(f"robot.setModel({name!r}): unknown robot; available: {', '.join(PRESETS)}")
        self.finish()
        before = self.backend
        self.spec.robot = name
        if self.backend != before:      # another protocol at the address: connect that at the next start
            self.close()

    def lua_robot__moveMobileSim(self, *args: Any) -> None:
        """Place the simulated robot at (x [mm], y [mm], theta [deg]) and reset odometry there."""
        x, y, th = _args("robot.moveMobileSim", "x_mm, y_mm, theta_deg", args, "nnn")
        self.finish()
        pose = Pose(x / 1000.0, y / 1000.0, math.radians(th))
        if not self.on_robot or self.truth_world:
            xmin, ymin, xmax, ymax = self.world().bounds or (0.0, 0.0, 0.0, 0.0)
            if not (xmin <= pose.x <= xmax and ymin <= pose.y <= ymax):
                raise ScriptError(f"robot.moveMobileSim({x:g}, {y:g}, {th:g}): outside world {self.spec.world!r} (x "
                                  f"{xmin * 1000:.0f}..{xmax * 1000:.0f}, y {ymin * 1000:.0f}..{ymax * 1000:.0f} mm)")
        self.pose, self._moved = pose, True
        if self.on_robot:
            self._move_pending = True
            if self.connected is not None:
                self._robot()

    def lua_robot__getPose(self, *args: Any) -> tuple[float, float, float]:
        """Where the robot is (x [mm], y [mm], theta [deg])."""
        _args("robot.getPose", "", args, "")
        self.finish()
        p = self.current_pose()
        return p.x * 1000.0, p.y * 1000.0, math.degrees(p.theta)

    def lua_robot__pathLength(self, *args: Any) -> float:
        """Path length of the last run [mm]."""
        _args("robot.pathLength", "", args, "")
        return round(self._last("robot.pathLength").record["path_length_m"] * 1000.0, 1)

    # -- exploration -----------------------------------------------------------------------------------
    def lua_exploration__setMethod(self, *args: Any) -> None:
        """The explorer: an ExplorationMethod value (or a plugin name)."""
        methods = self.methods()
        listing = ", ".join(f"ExplorationMethod.{k}" for k in methods)
        if len(args) != 1 or not isinstance(args[0], str):
            got = "nothing" if not args else lua_kind(args[0])
            raise ScriptError(f"exploration.setMethod(method): expected an installed method, got {got} "
                              f"(ExplorationMethod.X is nil when plugin x is not installed); available: {listing}")
        name = methods.get(args[0], args[0])
        if name not in methods.values():
            raise ScriptError(f"exploration.setMethod({args[0]!r}): unknown method; available: {listing}")
        self.spec.method = name

    def lua_exploration__getMethod(self, *args: Any) -> str:
        """The plugin name of the chosen method."""
        _args("exploration.getMethod", "", args, "")
        return self.spec.method

    def lua_exploration__setParameter(self, *args: Any) -> None:
        """An explorer keyword parameter (SI units, as `--param`); checked at start()."""
        name, value = parameter_args("exploration.setParameter", args)
        self.spec.params[name] = value

    def lua_exploration__clearParameters(self, *args: Any) -> None:
        """Forget every parameter given with setParameter."""
        _args("exploration.clearParameters", "", args, "")
        self.spec.params = {}

    def lua_exploration__setWorld(self, *args: Any) -> None:
        """A built-in world name, or a .map / .yaml file (relative to the output folder)."""
        (name,) = _args("exploration.setWorld", "name_or_file", args, "s")
        suffix = Path(name).suffix.lower()
        if suffix in (".map", ".yaml", ".yml"):
            name = self.paths.resolve(name, "r", "exploration.setWorld")
            if suffix != ".map" and self.paths.sandbox and Path(name).is_file():
                from robotexp.world.rosmap import ros_image_path
                # the image the YAML names must be inside the output folder too (checked before it is read)
                image = os.path.abspath(ros_image_path(name))
                self.paths.resolve(image, "r", f"exploration.setWorld({args[0]!r}): the map's image")
        self.finish()
        old = self.spec.world
        self.spec.world = name
        try:
            self.world()
        except RobotexpError:
            self.spec.world = old
            raise
        self.truth_world = True
        if name != old and not self.on_robot:     # a robot stays where it is: the world is only truth
            self.pose = None

    def lua_exploration__setSeed(self, *args: Any) -> None:
        """Seed of every random choice of the next runs."""
        (seed,) = _args("exploration.setSeed", "seed", args, "i")
        if seed < 0:
            raise ScriptError(f"exploration.setSeed({seed}): expected an integer >= 0")
        self.spec.seed = seed

    def lua_exploration__setMaxTime(self, *args: Any) -> None:
        """Robot-time limit of a run [ms]."""
        (ms,) = _args("exploration.setMaxTime", "time_ms", args, "n")
        self.spec.max_time = _positive("exploration.setMaxTime", "time_ms", ms, "ms") / 1000.0

    def lua_exploration__setMapLimits(self, *args: Any) -> None:
        """Map limits (xmin, ymin, xmax, ymax) [mm]; no argument: the world's bounds plus 1 m."""
        if not args:
            self.spec.map_bounds = None
            return
        x0, y0, x1, y1 = _args("exploration.setMapLimits", "xmin_mm, ymin_mm, xmax_mm, ymax_mm", args, "nnnn")
        if not (x0 < x1 and y0 < y1):
            raise ScriptError(f"exploration.setMapLimits({x0:g}, {y0:g}, {x1:g}, {y1:g}): expected xmin < xmax "
                              "and ymin < ymax")
        self.spec.map_bounds = (x0 / 1000.0, y0 / 1000.0, x1 / 1000.0, y1 / 1000.0)

    def lua_exploration__setCellSize(self, *args: Any) -> None:
        """Map cell size [mm] (5..2000)."""
        (mm,) = _args("exploration.setCellSize", "cell_mm", args, "n")
        if not 5 <= mm <= 2000:
            raise ScriptError(f"exploration.setCellSize({mm:g}): expected 5..2000 mm")
        self.spec.cell = mm / 1000.0

    def lua_exploration__setPotentialUpdateInterval(self, *args: Any) -> None:
        """Robot time between potential updates [ms] (methods with an `update_period`, e.g. BVP)."""
        (ms,) = _args("exploration.setPotentialUpdateInterval", "interval_ms", args, "n")
        self.potential_interval = _positive("exploration.setPotentialUpdateInterval", "interval_ms", ms, "ms") / 1000

    def lua_exploration__start(self, *args: Any) -> None:
        """Check the settings and arm a run (wait() runs it)."""
        _args("exploration.start", "", args, "")
        self.finish()
        if self.laser is not None and not self.on_robot and not self._told_laser:
            self.notice(f"robot.setLaser({self.laser[0]!r}): the embedded simulator measures with its own laser; "
                        "the laser is mounted on a robot at robot.setAddress")
            self._told_laser = True
        if self.on_robot:
            self._robot()
        self.armed = self._spec()

    def lua_exploration__setRecordFolder(self, *args: Any) -> None:
        """Record each following run as a ROS 2 bag, FOLDER/<run>.mcap (nil: stop recording)."""
        if len(args) == 1 and args[0] is None:
            self.record_folder = None
            return
        (folder,) = _args("exploration.setRecordFolder", "folder", args, "s")
        self.record_folder = Path(self.paths.resolve(folder.rstrip("/") + "/run.mcap", "w",
                                                     "exploration.setRecordFolder")).parent

    def lua_exploration__wait(self, *args: Any) -> None:
        """Run the armed exploration to its end (nothing when none is armed)."""
        _args("exploration.wait", "", args, "")
        self.finish()

    def lua_exploration__elapsedTime(self, *args: Any) -> int:
        """Robot time of the last run [ms]."""
        _args("exploration.elapsedTime", "", args, "")
        return round(self._last("exploration.elapsedTime").record["robot_time_s"] * 1000.0)

    def lua_exploration__results(self, *args: Any) -> dict[str, Any]:
        """Every metric of the last run (the keys of docs/reference/results.md; SI units; null values are nil)."""
        _args("exploration.results", "", args, "")
        return dict(self._last("exploration.results").record)

    def lua_exploration__outputFolder(self, *args: Any) -> str:
        """The output folder (relative paths of the script are relative to it)."""
        _args("exploration.outputFolder", "", args, "")
        return str(self.out)

    def _spec(self) -> RunSpec:
        from robotexp.registry import make_explorer
        from robotexp.sim import preset

        spec = replace(self.spec, params=dict(self.spec.params))
        if self.pose is not None:
            spec.pose = _pose_text(self.pose)
        spec.validate()
        cls = type(make_explorer(spec.method, spec.params))   # unknown method or parameter: now
        if self.potential_interval is not None:
            import inspect
            accepted = [n for n in _UPDATE_PARAMS if n in inspect.signature(cls).parameters]
            if accepted:
                spec.params.setdefault(accepted[0], self.potential_interval)
        if spec.map_bounds is not None:
            p = self.current_pose()
            x0, y0, x1, y1 = spec.map_bounds
            if not (x0 <= p.x <= x1 and y0 <= p.y <= y1):
                raise ScriptError(f"exploration.start: the robot ({p.x * 1000:.0f}, {p.y * 1000:.0f}) mm is "
                                  "outside the map limits set by exploration.setMapLimits")
        preset(spec.robot)
        return spec

    # -- views -----------------------------------------------------------------------------------------
    def lua_mapView__setMapScaling(self, *args: Any) -> None:
        """Image scale [px/mm] (IfTEA: 0.1 = 100 px per metre)."""
        (s,) = _args("mapView.setMapScaling", "pixels_per_mm", args, "n")
        self.scaling = _positive("mapView.setMapScaling", "pixels_per_mm", s, "px/mm")

    def lua_mapView__zoomIn(self, *args: Any) -> None:
        """Double the image scale."""
        _args("mapView.zoomIn", "", args, "")
        self.zoom *= 2.0

    def lua_mapView__zoomOut(self, *args: Any) -> None:
        """Halve the image scale."""
        _args("mapView.zoomOut", "", args, "")
        self.zoom /= 2.0

    def lua_mapView__setShowGrid(self, *args: Any) -> None:
        """Draw cell edges."""
        self._flag("mapView.setShowGrid", "grid", args)

    def lua_mapView__setShowVectorField(self, *args: Any) -> None:
        """Draw the explorer's vector field (BVP)."""
        self._flag("mapView.setShowVectorField", "vectors", args)

    def lua_mapView__setShowPotentialField(self, *args: Any) -> None:
        """Draw the explorer's potential field (BVP)."""
        self._flag("mapView.setShowPotentialField", "potential", args)

    def lua_mapView__setRedrawInterval(self, *args: Any) -> None:
        """Robot time between two frames saved in the frame folder [ms] (rounded to 1 s samples)."""
        (ms,) = _args("mapView.setRedrawInterval", "interval_ms", args, "n")
        self.redraw_interval = _positive("mapView.setRedrawInterval", "interval_ms", ms, "ms") / 1000.0

    def lua_mapView__setFrameFolder(self, *args: Any) -> None:
        """Save a map frame there every redraw interval during runs (nil: stop saving frames)."""
        if len(args) == 1 and args[0] is None:
            self.frame_folder = None
            return
        (folder,) = _args("mapView.setFrameFolder", "folder", args, "s")
        self.frame_folder = Path(self.paths.resolve(folder.rstrip("/") + "/frame", "w",
                                                    "mapView.setFrameFolder")).parent

    def lua_mapView__saveMapImage(self, *args: Any) -> str:
        """Save the last run's map as a figure (legend, scale bar, axes in metres; PNG, or SVG / PDF by the
        file's suffix; with tracking, the 800 x 600 px raster view around the robot); returns the path."""
        from robotexp.output.render import save_png
        (path,) = _args("mapView.saveMapImage", "path", args, "s")
        target = self.paths.resolve(path, "w", "mapView.saveMapImage")
        run = self._last("mapView.saveMapImage").run
        self.paths.quota.check("mapView.saveMapImage")
        if self.show["tracking"]:          # a window around the robot: the raster view, as the frames
            saved = save_png(self._image(run), target)
        else:
            saved = self._save_figure(run, Path(target))
        self._charge(saved)
        return str(saved)

    def _charge(self, path: Path) -> None:
        """Count a file written for the script against its --max-write limit."""
        try:
            self.paths.quota.charge(os.path.getsize(path))
        except OSError:
            pass

    def lua_robotView__setShowPath(self, *args: Any) -> None:
        """Draw the robot's path."""
        self._flag("robotView.setShowPath", "path", args)

    def lua_robotView__setShowLaser(self, *args: Any) -> None:
        """Draw the last laser scan."""
        self._flag("robotView.setShowLaser", "laser", args)

    def lua_robotView__setTracking(self, *args: Any) -> None:
        """Crop saved images to 800 x 600 px around the robot."""
        self._flag("robotView.setTracking", "tracking", args)
