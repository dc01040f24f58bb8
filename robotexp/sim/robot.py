"""`SimRobot`: the embedded simulator backend of `Robot` (pybullet, stepped clock, deterministic)."""

from __future__ import annotations

import math
from contextlib import AbstractContextManager, nullcontext
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robotexp.clock import Clock, SimClock
from robotexp.errors import WorldError
from robotexp.laser import ScanSource
from robotexp.robot import (Capability, Footprint, LaserScan, Pose, Robot, RobotState, SonarScan, Twist, sensor_origin,
                            wrap_angle)
from robotexp.sim.engine import Engine
from robotexp.sim.presets import LaserConfig, OdometryError, RobotPreset, preset
from robotexp.world.model import World

if TYPE_CHECKING:
    from robotexp.sim.team import SharedWorld

__all__ = ["SimRobot", "mounted_source"]

CONTACT_MARGIN = 0.02   # [m] clearance that ends a contact
SONAR_HEIGHT = 0.2      # [m] height of the sonar ring


class SimRobot(Robot):
    """A differential-drive robot in a pybullet world, advanced only by `advance(dt)`.

    Motion is integrated here (unicycle model with acceleration limits); pybullet detects contacts
    and casts the laser and sonar rays. A move that would touch an obstacle is refused: the robot
    stalls (its translation stops, rotation in place stays possible) and each new contact counts as
    one collision. Odometry integrates the true wheel travel through an `OdometryError` model;
    `RobotState.pose` is the odometry and `true_pose` the ground truth. All noise comes from one
    generator seeded with `seed`, so a run is repeatable.

    Args:
        world: the environment.
        robot: preset name ("p3dx", "kobuki") or a RobotPreset.
        pose: start pose; default the world's first named pose, else its `home`.
        seed: seed of the noise generator.
        laser: laser settings (default: the preset's).
        odometry: odometry error model (default: perfect).
        max_speed: forward speed limit [m/s] (default: the preset's).
        sonar: read the preset's sonar ring in every state (off saves a third of the time of a
            step when nothing uses it; `sonar()` still works).
        laser_in_state: cast the laser in every state (off: `read()` reports laser None, `scan()`
            still works; emulators that serve a laser-less protocol use this).
        rays: "exact" (default) or "pybullet": who casts the laser and sonar rays (see `Engine`).

    Raises:
        WorldError: the start pose is outside the world or touches an obstacle.
        ConfigError: a parameter out of range.
    """

    name = "sim"
    capabilities = frozenset({Capability.SONAR, Capability.MOVE_TO, Capability.GROUND_TRUTH})
    by_address = False

    def __init__(self, world: World, *, robot: str | RobotPreset = "p3dx", pose: Pose | None = None,
                 seed: int = 0, laser: LaserConfig | None = None, odometry: OdometryError | None = None,
                 max_speed: float | None = None, sonar: bool = True, laser_in_state: bool = True,
                 rays: str = "exact") -> None:
        self.preset = preset(robot) if isinstance(robot, str) else robot
        self.world = world
        self.radius = self.preset.radius
        self.limits = self.preset.limits
        self.laser_config = laser or self.preset.laser
        self.odometry_error = odometry or OdometryError()
        if max_speed is not None:
            self.set_max_speed(max_speed)
        self.sonar_in_state = sonar and self.preset.sonar is not None
        self.laser_in_state = laser_in_state
        self.rng = np.random.default_rng(seed)
        self.time = 0.0
        self.collisions = 0
        self.robot_collisions = 0       # the collisions with another robot of a team (counted in `collisions` too)
        self._in_contact = False
        self._stalled = False
        self._cmd = Twist.ZERO
        self._vel = Twist.ZERO
        self._distance = 0.0
        self._mover_time = [0.0] * len(world.movers)
        self._angles = self.laser_config.angles()
        self._sonar_dirs = self._sonar_pattern()
        self._sonar_positions = np.zeros((0, 2)) if self.preset.sonar is None else self.preset.sonar.origins()
        self._sonar_positions.flags.writeable = False     # handed out with every SonarScan
        self._scan_cache: tuple[float, int, LaserScan] | None = None    # (time, moves in a shared world, scan)
        self.shared: SharedWorld | None = None     # the world shared with robots advanced elsewhere (`SharedWorld`)
        self.engine = Engine(world, self.preset.radius, self.preset.height, rays, self.footprint)
        try:
            start = pose or _default_pose(world)
            self._true = start
            self._odom = start
            self._check_free(start)
            self.engine.place_robot(start.x, start.y, start.theta)
            self._place_movers()
        except Exception:
            self.engine.close()
            raise
        super().__init__()

    @property
    def model(self) -> str:
        """The simulated robot's preset name ("p3dx", "kobuki"), as run records name it."""
        return self.preset.name

    def describe(self) -> dict[str, str]:
        """The simulator, the simulated model and the world."""
        return {"robot": self.name, "model": self.preset.name, "world": self.world.name}

    # -- Robot hooks -----------------------------------------------------------------
    def make_clock(self, period: float) -> Clock:
        """A stepped clock: each tick advances this simulation by `period`."""
        return SimClock(period, self.advance)

    def _read(self) -> RobotState:
        laser = self.scan() if self.laser_in_state else None
        return RobotState(time=self.time, pose=self._odom, velocity=self._vel, laser=laser,
                          sonar=self.sonar() if self.sonar_in_state else None, stalled=self._stalled,
                          bumpers=(self._stalled,), true_pose=self._true, distance=self._distance,
                          extra={"collisions": float(self.collisions)})

    def _command(self, twist: Twist) -> None:
        self._cmd = twist

    def _close(self) -> None:
        self.engine.close()

    def move_to(self, pose: Pose) -> None:
        """Teleport to `pose` (as MobileSim's move-robot) and reset odometry there.

        Raises:
            WorldError: the pose is outside the world or touches an obstacle.
        """
        self._ensure_open()
        self._check_free(pose)
        self._true = self._odom = pose
        self._vel = self._cmd = Twist.ZERO
        self._stalled = self._in_contact = False
        self._scan_cache = None
        self.engine.place_robot(pose.x, pose.y, pose.theta)

    # -- simulation ------------------------------------------------------------------
    def advance(self, dt: float) -> None:
        """Advance the world by `dt` [s]: movers walk, the robot accelerates towards the command and
        moves unless that would touch an obstacle (in a `SharedWorld`, the other robots where they stand
        now, one robot moving at a time)."""
        shared = self.shared
        if shared is None:
            self._advance(dt)
            return
        with shared.lock:
            shared.sync(self)
            self._advance(dt)
            shared.moves += 1

    def _advance(self, dt: float) -> None:
        self._ensure_open()
        self._move_movers(dt)
        lim = self.limits
        v = approach(self._vel.v, self._cmd.v, lim.a_max * dt)
        w = approach(self._vel.w, self._cmd.w, lim.alpha_max * dt)
        vt, wt = self._wheel_motion(v, w)
        # split long steps so contacts are found close to where they happen (a rectangle's corners move
        # as it turns: turning in place can touch too)
        round_body = self.footprint.round
        sweep = abs(vt) + (0.0 if round_body else abs(wt) * self.footprint.swing)
        n = max(1, math.ceil(sweep * dt / (self.radius / 5)))
        h = dt / n
        blocked = False
        for _ in range(n):
            new = _integrate(self._true, vt, wt, h)
            self.engine.place_robot(new.x, new.y, new.theta)
            if (vt != 0.0 or not round_body) and self.engine.robot_collides():
                new = self._last_free(vt, wt, h)      # stop where the robot touches
                self.engine.place_robot(new.x, new.y, new.theta)
                blocked = True
            self._odometry_step(self._true, new)
            self._true = new
            if blocked:
                break
        if blocked:
            v = 0.0
            if not round_body:
                w = 0.0         # a rectangle stopped by a corner stops turning too
            if not self._in_contact:
                self.collisions += 1
                if self.engine.peer_near(CONTACT_MARGIN):
                    self.robot_collisions += 1
            self._in_contact = True
        elif self._in_contact:
            # a contact lasts until the robot is clearly away: creeping along a wall is one collision
            self._in_contact = self.engine.robot_near_obstacle(CONTACT_MARGIN)
        self._stalled = blocked
        self._vel = Twist(v, w)
        self.time += dt
        self._scan_cache = None

    def _wheel_motion(self, v: float, w: float) -> tuple[float, float]:
        """The true (v, w) of a robot whose wheels are servoed to the command on the encoders: each
        wheel turns as commanded, and its travel on the ground is that times its true diameter over
        the nominal one. Without `wheel_servo` the robot moves as commanded."""
        err = self.odometry_error
        if not (err.wheel_servo and err.wheel_mismatch):
            return v, w
        b = self.preset.wheel_base
        vl = (v - w * b / 2) * (1.0 - err.wheel_mismatch / 2)
        vr = (v + w * b / 2) * (1.0 + err.wheel_mismatch / 2)
        return (vl + vr) / 2, (vr - vl) / b

    def _last_free(self, v: float, w: float, h: float) -> Pose:
        """The farthest pose along this sub-step that does not touch (bisection to ~h/64). A round robot
        keeps turning (its heading cannot touch); a rectangle stops turning where it touches too."""
        lo, hi = 0.0, 1.0
        for _ in range(6):
            mid = (lo + hi) / 2
            p = _integrate(self._true, v, w, h * mid)
            self.engine.place_robot(p.x, p.y, p.theta)
            if self.engine.robot_collides():
                hi = mid
            else:
                lo = mid
        p = _integrate(self._true, v, w, h * lo)
        if not self.footprint.round:
            return p
        return Pose(p.x, p.y, _integrate(self._true, v, w, h).theta)

    def _odometry_step(self, old: Pose, new: Pose) -> None:
        """Integrate odometry from the true wheel travel of one step through the error model."""
        ds = math.hypot(new.x - old.x, new.y - old.y)
        fwd = math.cos(old.theta) * (new.x - old.x) + math.sin(old.theta) * (new.y - old.y)
        ds = math.copysign(ds, fwd)
        dth = wrap_angle(new.theta - old.theta)
        if ds == 0.0 and dth == 0.0:
            return
        err = self.odometry_error
        b = self.preset.wheel_base
        dl, dr = ds - dth * b / 2, ds + dth * b / 2
        if err.active:
            # the encoders count turns of wheels of diameter (1 -+ m/2) nominal and odometry
            # converts them with the nominal one: a larger right wheel under-reads its travel
            dl /= 1.0 - err.wheel_mismatch / 2
            dr /= 1.0 + err.wheel_mismatch / 2
            if err.slip_sigma:
                dl *= 1.0 + self.rng.normal(0.0, err.slip_sigma)
                dr *= 1.0 + self.rng.normal(0.0, err.slip_sigma)
        ods, odth = (dl + dr) / 2, (dr - dl) / b
        if err.heading_drift:
            odth += err.heading_drift * abs(ods)
        o = self._odom
        mid = o.theta + odth / 2
        self._odom = Pose(o.x + ods * math.cos(mid), o.y + ods * math.sin(mid), wrap_angle(o.theta + odth))
        self._distance += abs(ods)

    def _move_movers(self, dt: float) -> None:
        for i, mover in enumerate(self.world.movers):
            t = self._mover_time[i] + dt
            x, y = mover.position(t)
            self.engine.place_mover(i, x, y, mover.height)
            if self.engine.mover_touches_robot(i, 0.05):
                # a polite pedestrian: wait rather than walk into the robot
                x, y = mover.position(self._mover_time[i])
                self.engine.place_mover(i, x, y, mover.height)
            else:
                self._mover_time[i] = t

    def _place_movers(self) -> None:
        for i, mover in enumerate(self.world.movers):
            x, y = mover.position(self._mover_time[i])
            self.engine.place_mover(i, x, y, mover.height)

    @property
    def footprint(self) -> Footprint:
        """The preset's outline: the body the simulator collides with."""
        return self.preset.outline

    @property
    def true_pose(self) -> Pose:
        """Where the robot really is (not what odometry believes)."""
        return self._true

    @property
    def commanded(self) -> Twist:
        """The velocity command in force (clamped to `limits`; the robot accelerates towards it)."""
        return self._cmd

    def mover_positions(self) -> list[tuple[float, float]]:
        """Where each mover is now [m]."""
        return [m.position(t) for m, t in zip(self.world.movers, self._mover_time, strict=True)]

    def _check_free(self, pose: Pose) -> None:
        xmin, ymin, xmax, ymax = self.world.bounds or (0, 0, 0, 0)
        if not (xmin <= pose.x <= xmax and ymin <= pose.y <= ymax):
            raise WorldError(f"start pose ({pose.x:.3f}, {pose.y:.3f}) m is outside world {self.world.name!r} "
                             f"(x {xmin:.2f}..{xmax:.2f}, y {ymin:.2f}..{ymax:.2f} m)")
        self.engine.place_robot(pose.x, pose.y, pose.theta)
        collides = self.engine.robot_collides(include_movers=False)
        self.engine.place_robot(self._true.x, self._true.y, self._true.theta)
        if collides:
            raise WorldError(f"start pose ({pose.x:.3f}, {pose.y:.3f}) m in world {self.world.name!r} "
                             f"touches an obstacle ({_outline(self.footprint)}): choose a free pose")

    # -- sensors ---------------------------------------------------------------------
    def scan(self) -> LaserScan:
        """The laser scan at the current instant (cast once per instant, noise included)."""
        moves = 0 if self.shared is None else self.shared.moves     # another robot moved: the scan is new
        if self._scan_cache is not None and self._scan_cache[:2] == (self.time, moves):
            return self._scan_cache[2]
        cfg = self.laser_config
        p = self._true
        sx, sy = sensor_origin(p, cfg.offset_x)
        ranges = self._cast_fan(sx, sy, cfg.height, p.theta + self._angles, cfg.range_max)
        hit = np.isfinite(ranges)
        if cfg.sigma:
            ranges[hit] += self.rng.normal(0.0, cfg.sigma, int(hit.sum()))
        if cfg.uniform:
            ranges[hit] += self.rng.uniform(-cfg.uniform, cfg.uniform, int(hit.sum()))
        np.clip(ranges, 0.0, None, out=ranges)
        ranges[hit & (ranges >= cfg.range_max)] = np.nextafter(cfg.range_max, 0.0)
        scan = LaserScan(self._angles, ranges, cfg.range_max, cfg.offset_x)
        self._scan_cache = (self.time, moves, scan)
        return scan

    def _cast_fan(self, x: float, y: float, z: float, headings: np.ndarray, reach: float) -> np.ndarray:
        """Ranges [m] of rays of length `reach` from (x, y, z) at `headings` [rad] (inf: no hit)."""
        if self.shared is not None:
            self.shared.sync(self)
        origins = np.empty((len(headings), 2))
        origins[:, 0], origins[:, 1] = x, y
        fraction = self.engine.cast_from(origins, headings, reach, z)
        ranges = fraction * reach
        ranges[fraction >= 1.0] = np.inf
        return ranges

    def _sonar_pattern(self) -> np.ndarray:
        cfg = self.preset.sonar
        if cfg is None:
            return np.zeros((0, 0))
        k = max(cfg.rays_per_cone, 1)
        spread = np.radians(np.linspace(-cfg.cone_deg / 2, cfg.cone_deg / 2, k)) if k > 1 else np.zeros(1)
        return cfg.angles()[:, None] + spread[None, :]

    def sonar(self) -> SonarScan:
        """The sonar ring's readings: each transducer's nearest echo in its cone (inf: none)."""
        cfg = self.preset.sonar
        if cfg is None:
            raise NotImplementedError("sim: this robot preset has no sonar ring")
        p = self._true
        ring = cfg.angles()
        k = self._sonar_dirs.shape[1]
        origins = np.empty((len(ring) * k, 2))
        if cfg.offsets:                 # transducers where the robot's parameter file puts them
            c, s = math.cos(p.theta), math.sin(p.theta)
            at = self._sonar_positions
            origins[:, 0] = np.repeat(p.x + c * at[:, 0] - s * at[:, 1], k)
            origins[:, 1] = np.repeat(p.y + s * at[:, 0] + c * at[:, 1], k)
        else:
            origins[:, 0] = np.repeat(p.x + cfg.ring_radius * np.cos(p.theta + ring), k)
            origins[:, 1] = np.repeat(p.y + cfg.ring_radius * np.sin(p.theta + ring), k)
        headings = (p.theta + self._sonar_dirs).ravel()
        if self.shared is not None:
            self.shared.sync(self)
        fraction = self.engine.cast_from(origins, headings, cfg.range_max, SONAR_HEIGHT)
        fraction = fraction.reshape(len(ring), k).min(axis=1)
        ranges = np.where(fraction >= 1.0, np.inf, fraction * cfg.range_max)
        return SonarScan(ring, ranges, cfg.range_max, self._sonar_positions)

def _outline(foot: Footprint) -> str:
    """The robot's outline in words, for messages."""
    if foot.round:
        return f"robot radius {foot.width / 2:.3f} m"
    return f"robot {foot.length:.3f} x {foot.width:.3f} m"


def approach(current: float, target: float, step: float) -> float:
    """Move `current` towards `target` by at most `step`."""
    if target > current:
        return min(target, current + step)
    return max(target, current - step)


def _integrate(p: Pose, v: float, w: float, dt: float) -> Pose:
    """Exact unicycle motion from `p` with constant (v, w) for `dt`."""
    if abs(w) < 1e-9:
        return Pose(p.x + v * dt * math.cos(p.theta), p.y + v * dt * math.sin(p.theta), p.theta)
    th = p.theta + w * dt
    r = v / w
    return Pose(p.x + r * (math.sin(th) - math.sin(p.theta)),
                p.y - r * (math.cos(th) - math.cos(p.theta)), wrap_angle(th))


def _default_pose(world: World) -> Pose:
    if world.poses:
        return next(iter(world.poses.values()))
    if world.home is not None:
        return world.home
    raise WorldError(f"world {world.name!r} names no start pose: give one")


def mounted_source(sim: SimRobot, mount: Pose | None = None, lock: AbstractContextManager[Any] | None = None,
                   height: float | None = None) -> ScanSource:
    """A `ScanSource` (robotexp.laser) for a laser emulator: rays from a sensor mounted at `mount`
    (robot frame; default the robot centre, facing forward) on `sim`'s true pose, at `height` [m]
    (default the preset laser's), taken under `lock` when given (an emulator's simulator lock)."""
    m = mount or Pose(0.0, 0.0, 0.0)
    z = sim.laser_config.height if height is None else height
    guard: AbstractContextManager[Any] = lock if lock is not None else nullcontext()

    def source(angles: npt.NDArray[np.float64], reach: float) -> npt.NDArray[np.float64]:
        with guard:
            p = sim.true_pose
            c, s = math.cos(p.theta), math.sin(p.theta)
            x, y = p.x + c * m.x - s * m.y, p.y + s * m.x + c * m.y
            return sim._cast_fan(x, y, z, p.theta + m.theta + np.asarray(angles, dtype=np.float64), reach)
    return source
