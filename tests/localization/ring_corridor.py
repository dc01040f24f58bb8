"""A small ring corridor and a scripted robot driving round it with odometry error, for the loop-closure
tests: scans ray cast against boxes (`robotexp.world.raycast.RayIndex`), no simulator."""

from __future__ import annotations

import math

import numpy as np

from robotexp.robot import LaserScan, Limits, Pose, Robot, RobotState, Twist
from robotexp.world.raycast import RayIndex

OUTER, INNER = 10.0, (1.6, 8.4)        # [m] the ring: a 10 m square around a 6.8 m block, 1.6 m corridors
# walls (cx, cy, half_x, half_y, yaw), 0.1 m thick, and a few bumps on them so that no stretch is a
# featureless corridor end to end
WALLS = [(5.0, -0.05, 5.1, 0.05, 0.0), (5.0, 10.05, 5.1, 0.05, 0.0), (-0.05, 5.0, 0.05, 5.1, 0.0),
         (10.05, 5.0, 0.05, 5.1, 0.0), (5.0, 5.0, 3.4, 3.4, 0.0)]
BUMPS = [(2.0, 0.1, 0.2, 0.1, 0.0), (6.5, 0.15, 0.3, 0.15, 0.0), (9.85, 3.0, 0.15, 0.25, 0.0),
         (9.9, 7.2, 0.1, 0.3, 0.0), (7.0, 9.85, 0.25, 0.15, 0.0), (3.5, 9.9, 0.2, 0.1, 0.0),
         (0.15, 6.0, 0.15, 0.3, 0.0), (0.1, 2.5, 0.1, 0.2, 0.0), (5.0, 1.6, 0.3, 0.1, 0.0),
         (8.4, 5.5, 0.1, 0.3, 0.0), (4.0, 8.4, 0.3, 0.1, 0.0), (1.6, 4.0, 0.1, 0.3, 0.0)]
BEAMS = np.radians(np.arange(-90.0, 90.5, 1.0))
RANGE = 4.0


def ring_path(laps: float = 1.2, step: float = 0.1, turn: float = math.radians(10.0)) -> list[Pose]:
    """True poses round the corridor's centre line (0.8 m from the outer wall), counter-clockwise,
    turning in place at the corners."""
    c0, c1 = 0.8, OUTER - 0.8
    corners = [(c0, c0), (c1, c0), (c1, c1), (c0, c1)]
    out: list[Pose] = []
    total = laps * 4 * (c1 - c0)
    x, y, th, done = c0, c0, 0.0, 0.0
    k = 0
    while done < total:
        tx, ty = corners[(k + 1) % 4]
        side = math.hypot(tx - x, ty - y)
        n = max(int(round(side / step)), 1)
        for m in range(n):
            if done >= total:
                break
            out.append(Pose(x + (tx - x) * m / n, y + (ty - y) * m / n, th))
            done += side / n
        x, y = tx, ty
        target = th + math.pi / 2
        while th < target - 1e-9 and done < total:
            out.append(Pose(x, y, th))
            th = min(th + turn, target)
        k += 1
    return out


def drifted(truth: list[Pose], scale: float, drift: float) -> list[Pose]:
    """Odometry of `truth`: distances times `scale`, `drift` [rad/m] of heading error per metre."""
    out = [truth[0]]
    for a, b in zip(truth[:-1], truth[1:], strict=True):
        c, s = math.cos(a.theta), math.sin(a.theta)
        dx, dy = b.x - a.x, b.y - a.y
        lx, ly = c * dx + s * dy, -s * dx + c * dy
        d = math.hypot(lx, ly)
        p = out[-1]
        dth = b.theta - a.theta + drift * d
        lx, ly = lx * scale, ly * scale
        cp, sp = math.cos(p.theta), math.sin(p.theta)
        out.append(Pose(p.x + cp * lx - sp * ly, p.y + sp * lx + cp * ly, p.theta + dth))
    return out


class RingRobot(Robot):
    """Replays `truth` with odometry `odom` and ray-cast scans, one state per read."""

    name = "ring"

    def __init__(self, truth: list[Pose], odom: list[Pose]) -> None:
        self.truth, self.odom = truth, odom
        self.index = RayIndex(WALLS + BUMPS, np.zeros((0, 3)), 1.0)
        self.k = 0
        self.limits = Limits(0.5, 1.0, 1.0, 2.0)
        super().__init__()

    def _read(self) -> RobotState:
        k = min(self.k, len(self.truth) - 1)
        self.k += 1
        t = self.truth[k]
        heads = t.theta + BEAMS
        frac = self.index.cast(np.tile([t.x, t.y], (len(BEAMS), 1)), heads, RANGE, 0.5)
        ranges = np.where(frac < 1.0, frac * RANGE, np.inf)
        return RobotState(time=0.1 * k, pose=self.odom[k], velocity=Twist(0.0, 0.0),
                          laser=LaserScan(BEAMS.copy(), ranges, RANGE), true_pose=t)

    def _command(self, twist: Twist) -> None:
        pass

    def _close(self) -> None:
        pass
