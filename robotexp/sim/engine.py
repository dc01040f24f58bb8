"""The pybullet side of the simulator: one DIRECT-mode physics client holding a world's obstacles.

Static obstacles become static bodies (boxes and cylinders) when the world asks for bodies (the
built-in worlds); a world with `collision="index"` (map files: tens of thousands of boxes) gets no
static body, and the robot is tested against its shapes exactly by `RayIndex.near` (distance from
the robot's centre to each box or disc in the buckets around it). Movers are kinematic cylinders,
and the robot a cylinder that is placed, never pushed: the robot's motion is integrated by
`SimRobot` and pybullet answers the contact questions. Rays (laser, sonar) are cast against the
same shapes by the exact kernel of `robotexp.world.raycast`, which agrees with pybullet's ray test
(checked by the tests) at a fraction of its cost; `rays="pybullet"` casts them with pybullet.
"""

from __future__ import annotations

import contextlib
import ctypes
import math
import os
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.robot import Footprint
from robotexp.signals import held
from robotexp.world.raycast import RayIndex
from robotexp.world.model import World

__all__ = ["Engine"]

WALL_HEIGHT = 1.0       # [m] every static obstacle reaches above the sensors


@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Silence the C-level stdout and stderr (pybullet prints its build time to stderr on import,
    which would break the CLI's one-line error messages). A Ctrl-C or SIGTERM meanwhile acts once both are
    back (`robotexp.signals.held`): one that cut the switch short left them on the null device for good, and
    the command's last line unseen."""
    with held():
        saved: list[int] = []
        try:
            for fd in (1, 2):
                saved.append(os.dup(fd))
        except OSError:
            for copy in saved:
                os.close(copy)
            yield
            return
        libc = ctypes.CDLL(None)
        c_stdout = ctypes.c_void_p.in_dll(libc, "stdout")
        for stream in (sys.stdout, sys.stderr):
            if stream is not None:
                stream.flush()
        try:
            with open(os.devnull, "w") as null:
                os.dup2(null.fileno(), 1)
                os.dup2(null.fileno(), 2)
                yield
                libc.fflush(c_stdout)   # a message may sit in C's stdout buffer until flushed
        finally:
            for fd, copy in zip((1, 2), saved, strict=True):
                os.dup2(copy, fd)
                os.close(copy)


with _quiet_stdout():
    import pybullet as pb


class Engine:
    """A pybullet client with the static obstacles of `world`, its movers and one robot body (a cylinder,
    or a box for a rectangular footprint).

    Args:
        world: the environment.
        robot_radius, robot_height: [m] the robot cylinder.
        rays: "exact" (the `robotexp.world.raycast` kernel, default) or "pybullet" (Bullet's ray test).
        footprint: the robot's outline (None: a disc of `robot_radius`).
    """

    def __init__(self, world: World, robot_radius: float, robot_height: float, rays: str = "exact",
                 footprint: Footprint | None = None) -> None:
        if rays not in ("exact", "pybullet"):
            raise ConfigError(f"sim: rays must be 'exact' or 'pybullet', got {rays!r}")
        self.rays = rays
        self._bodies = world.collision == "bodies"
        if not self._bodies and rays != "exact":
            raise ConfigError(f"sim: world {world.name!r} has no pybullet bodies for its obstacles "
                              "(collision 'index'): rays must be 'exact'")
        self._index = RayIndex(world.boxes, world.discs, WALL_HEIGHT) if rays == "exact" else None
        self._movers = np.array([[*m.position(0.0), m.radius, m.height] for m in world.movers],
                                dtype=np.float64).reshape(-1, 4)
        with _quiet_stdout():      # pybullet prints its build time on the first connect
            self.client = pb.connect(pb.DIRECT)
        self._robot_z = robot_height / 2
        self._foot = footprint or Footprint.disc(robot_radius)
        self._robot_radius = self._foot.swing        # the disc that holds the body whatever its heading
        self._robot_xy = (0.0, 0.0)
        self._robot_theta = 0.0
        self._peers = np.zeros((0, 4))      # the other robots of a team: [x, y, radius, height] [m]
        self.statics: list[int] = []
        try:
            if self._bodies:
                self._add_statics(world)
            self._static_set = frozenset(self.statics)
            if self._foot.round:
                shape = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=self._foot.width / 2, height=robot_height,
                                                physicsClientId=self.client)
            else:
                shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[self._foot.length / 2, self._foot.width / 2,
                                                                          robot_height / 2],
                                                physicsClientId=self.client)
            self.robot = pb.createMultiBody(0, shape, basePosition=[0, 0, self._robot_z],
                                            physicsClientId=self.client)
            # Out of every collision-filter group: ray casts skip it (they start inside it and Bullet
            # would test it for every beam, 40% of a scan's time), while getClosestPoints, which
            # ignores filters, still finds its contacts.
            pb.setCollisionFilterGroupMask(self.robot, -1, 0, 0, physicsClientId=self.client)
            self.movers: list[int] = []
            for mover in world.movers:
                ms = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=mover.radius, height=mover.height,
                                             physicsClientId=self.client)
                x, y = mover.position(0.0)
                self.movers.append(pb.createMultiBody(0, ms, basePosition=[x, y, mover.height / 2],
                                                      physicsClientId=self.client))
        except Exception:
            self.close()
            raise

    def _add_statics(self, world: World) -> None:
        # One body per obstacle: pybullet's broadphase keeps ray casts and contact queries fast,
        # and (unlike a compound shape) every child keeps exactly the pose we give it.
        shapes: dict[tuple[float, float], int] = {}
        for cx, cy, hx, hy, yaw in world.boxes:
            key = (round(hx, 9), round(hy, 9))
            if key not in shapes:
                shapes[key] = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[hx, hy, WALL_HEIGHT / 2],
                                                      physicsClientId=self.client)
            self.statics.append(pb.createMultiBody(
                0, shapes[key], basePosition=[cx, cy, WALL_HEIGHT / 2],
                baseOrientation=[0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)], physicsClientId=self.client))
        for cx, cy, r in world.discs:
            shape = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=r, height=WALL_HEIGHT,
                                            physicsClientId=self.client)
            self.statics.append(pb.createMultiBody(0, shape, basePosition=[cx, cy, WALL_HEIGHT / 2],
                                                   physicsClientId=self.client))

    def place_robot(self, x: float, y: float, theta: float = 0.0) -> None:
        """Put the robot at (x, y) [m] heading `theta` [rad] (a round robot's heading does not matter)."""
        self._robot_xy = (x, y)
        self._robot_theta = theta
        quat = [0.0, 0.0, 0.0, 1.0] if self._foot.round else [0.0, 0.0, math.sin(theta / 2), math.cos(theta / 2)]
        pb.resetBasePositionAndOrientation(self.robot, [x, y, self._robot_z], quat, physicsClientId=self.client)

    def place_mover(self, index: int, x: float, y: float, height: float) -> None:
        """Put mover `index` at (x, y) [m]."""
        self._movers[index] = (x, y, self._movers[index, 2], height)
        pb.resetBasePositionAndOrientation(self.movers[index], [x, y, height / 2], [0, 0, 0, 1],
                                           physicsClientId=self.client)

    def set_peers(self, discs: npt.NDArray[np.float64]) -> None:
        """The other robots of a team where they stand now, (k, 4) [x, y, radius, height] [m]: the rays see
        them (as cylinders, like movers) and the robot touching one collides. Rays cast by pybullet
        (`rays="pybullet"`) do not see them."""
        self._peers = np.asarray(discs, np.float64).reshape(-1, 4)

    def peer_near(self, margin: float) -> bool:
        """True when another robot of the team (a disc) is within `margin` [m] of the robot's body."""
        if not len(self._peers):
            return False
        x, y = self._robot_xy
        p = self._peers
        c, s = math.cos(self._robot_theta), math.sin(self._robot_theta)
        dx, dy = p[:, 0] - x, p[:, 1] - y
        gap = self._foot.distance(c * dx + s * dy, -s * dx + c * dy)
        return bool((gap < p[:, 2] + margin).any())

    def robot_collides(self, include_movers: bool = True) -> bool:
        """True when the robot's body, where it was last placed, touches an obstacle."""
        return self.robot_near_obstacle(0.0, include_movers)

    def robot_near_obstacle(self, margin: float, include_movers: bool = True) -> bool:
        """True when an obstacle is within `margin` [m] of the robot's body."""
        x, y = self._robot_xy
        if include_movers and self.peer_near(margin):
            return True
        if not self._bodies:
            assert self._index is not None
            foot = self._foot
            if (self._index.near(x, y, foot.width / 2 + margin) if foot.round else
                    self._index.near_box(x, y, self._robot_theta, foot.length / 2, foot.width / 2, margin)):
                return True
            return include_movers and any(pb.getClosestPoints(self.robot, body, margin, physicsClientId=self.client)
                                          for body in self.movers)
        reach = self._robot_radius + margin + 1e-3
        near = pb.getOverlappingObjects([x - reach, y - reach, 0.0], [x + reach, y + reach, WALL_HEIGHT],
                                        physicsClientId=self.client) or ()
        bodies = {b for b, _ in near if b in self._static_set}
        if include_movers:
            bodies.update(self.movers)
        return any(pb.getClosestPoints(self.robot, body, margin, physicsClientId=self.client)
                   for body in bodies)

    def mover_touches_robot(self, index: int, margin: float) -> bool:
        """True when mover `index` is within `margin` [m] of the robot."""
        return bool(pb.getClosestPoints(self.robot, self.movers[index], margin, physicsClientId=self.client))

    def cast(self, origins: list[list[float]], ends: list[list[float]]) -> npt.NDArray[np.float64]:
        """Cast rays from `origins` to `ends` (n lists of [x, y, z] [m]); return the hit fraction (n,),
        1.0 for no hit. Plain lists cross into pybullet faster than arrays.

        The robot's body is filtered out of ray tests, so the robot never sees itself.
        """
        hits: Any = pb.rayTestBatch(origins, ends, physicsClientId=self.client)
        return np.array([h[2] if h[0] >= 0 else 1.0 for h in hits], dtype=np.float64)

    def cast_from(self, origins: npt.NDArray[np.float64], headings: npt.NDArray[np.float64], reach: float,
                  z: float) -> npt.NDArray[np.float64]:
        """Hit fractions (n,) of rays from `origins` (n, 2) [m] along `headings` (n,) [rad], `reach` [m] long,
        at height `z` [m]; 1.0 for no hit. The robot never sees itself."""
        if self._index is not None:
            movers = self._movers if not len(self._peers) else np.vstack((self._movers, self._peers))
            return self._index.cast(origins, headings, reach, z, movers)
        n = len(headings)
        starts = np.empty((n, 3))
        starts[:, :2] = origins
        starts[:, 2] = z
        ends = starts.copy()
        ends[:, 0] += reach * np.cos(headings)
        ends[:, 1] += reach * np.sin(headings)
        return self.cast(starts.tolist(), ends.tolist())

    def close(self) -> None:
        """Disconnect the physics client. Safe to call twice."""
        if self.client >= 0:
            with contextlib.suppress(Exception):
                pb.disconnect(physicsClientId=self.client)
            self.client = -1

