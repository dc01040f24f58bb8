"""A right-hand wall follower: a complete, minimal third-party robotexp explorer plugin.

Install it with `pip install -e examples/plugin`; it is then the method `wall-follow`
(`robotexp explore --method wall-follow`). It steers from the laser scan alone and ignores the map.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from robotexp import ConfigError, Done, Explorer, ExplorerContext, RobotState, Twist

if TYPE_CHECKING:
    from robotexp.mapping.grid import OccupancyGrid

__all__ = ["WallFollowExplorer"]


def _positive(name: str, value: object) -> float:
    """`value` as a float, or ConfigError naming the parameter when it is not a finite number > 0."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not (0 < value < math.inf):
        raise ConfigError(f"wall-follow: {name} must be a number > 0, got {value!r}")
    return float(value)


class WallFollowExplorer(Explorer):
    """Keep a wall on the right; done after `duration` of robot time or when back at the start.

    The robot drives straight until it meets an obstacle, then follows it: it holds `wall_distance`
    to the nearest obstacle on its right and keeps that nearest beam at -90 deg (parallel to the
    wall), turns left in place when the way ahead is blocked (a round robot cannot hit anything
    turning in place) and arcs right around corners where the wall ends.

    Args:
        duration: [s] robot time after which the run is done.
        wall_distance: [m] kept between the robot centre and the wall on its right.
        speed: [m/s] forward speed (None: the robot's maximum).
        home_radius: [m] done when this close to the start after having been 3x as far from it.

    Raises:
        ConfigError: a parameter that is not a number > 0; in `reset`, a robot without a laser or
            a `wall_distance` too small for the robot.
    """

    def __init__(self, *, duration: float = 120.0, wall_distance: float = 0.6, speed: float | None = None,
                 home_radius: float = 0.5) -> None:
        self.duration = _positive("duration", duration)
        self.wall_distance = _positive("wall_distance", wall_distance)
        self.speed = None if speed is None else _positive("speed", speed)
        self.home_radius = _positive("home_radius", home_radius)

    def reset(self, ctx: ExplorerContext) -> None:
        """Check the robot suits the parameters and forget any previous run."""
        super().reset(ctx)
        if ctx.laser_range <= 0:
            raise ConfigError("wall-follow: needs a laser scan, this robot has no laser")
        if self.wall_distance < ctx.radius + 0.15:
            raise ConfigError(f"wall-follow: wall_distance must be >= robot radius + 0.15 m = "
                              f"{ctx.radius + 0.15:.2f} m, got {self.wall_distance}")
        self.v = min(self.speed or ctx.limits.v_max, ctx.limits.v_max)
        self.t0: float | None = None     # robot time of the first step
        self.left_home = False
        self.found_wall = False

    def step(self, state: RobotState, grid: OccupancyGrid) -> Twist | Done:
        """One decision: the twist that keeps the wall on the right, or Done."""
        if self.t0 is None:
            self.t0 = state.time
        if state.time - self.t0 >= self.duration:
            return Done(f"time budget of {self.duration:g} s used", explored=False)
        away = state.pose.distance_to(self.ctx.start)
        if away > 3 * self.home_radius:
            self.left_home = True
        elif self.left_home and away < self.home_radius:
            return Done("back at the start")
        scan = state.laser
        if scan is None:                  # no scan this period: wait for the next one
            return Twist.ZERO
        a, r = scan.angles, np.minimum(scan.ranges, scan.range_max)    # inf (no hit) -> range_max
        # free way ahead: the nearest hit inside the lane the body sweeps when driving straight
        lane = (np.cos(a) > 0) & (np.abs(r * np.sin(a)) < self.ctx.radius + 0.1)
        front = float(np.min(r[lane] * np.cos(a[lane]), initial=scan.range_max))
        side = a < -math.radians(20)
        if not side.any():                # a scan that does not look right cannot follow a right wall
            return Done("the laser does not see the right side")
        nearest = int(np.argmin(np.where(side, r, np.inf)))
        right, bearing = float(r[nearest]), float(a[nearest])
        d, w_max = self.wall_distance, self.ctx.limits.w_max
        if front < d:                     # blocked: turn left in place until the way is clear
            self.found_wall = True
            return Twist(0.0, min(w_max, 1.0))
        v = self.v * min(1.0, front / d - 0.5)     # slow down near what is ahead (to half speed at d)
        if not self.found_wall:           # seek: straight on until something is near
            self.found_wall = right < 1.5 * d
            return Twist(v, 0.0)
        if right > 2 * d:                 # the wall ended: arc right around its end
            v = min(v, 0.5 * self.v)
            return Twist(v, -v / d)
        # hold the distance, and turn parallel to the wall (its nearest point at -90 deg)
        w = 1.5 * (d - right) + 1.5 * (bearing + math.pi / 2)
        return Twist(v, max(-w_max, min(w_max, w)))
