"""`FrameCorrection`: how loop closure moved the poses an explorer was given.

With online loop closure (`robotexp explore --localize slam`) the pose the explorer gets is the localizer's,
in the frame of the keyframe that was the latest when the pose was given. When loop closure corrects the
keyframes and the run's map is rebuilt, every pose given since the start moves rigidly with its keyframe:
a point [m] the explorer derived from a pose given at robot time `t` (a tree node, a target, a path) now
lies at `correction.points(xy, t)`. The run hands one to `Explorer.map_rebuilt`; it maps the explorer's
coordinates as they were at the previous rebuild (or the start) to the rebuilt map's.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.robot import Pose, wrap_angle

__all__ = ["FrameCorrection"]


class FrameCorrection:
    """Rigid corrections by the robot time a pose was given.

    Args:
        times: [s] increasing robot times (`RobotState.time`) from which each correction applies, to the next.
        moves: (n, 3) the rigid motion (dx [m], dy [m], dtheta [rad]) of each: a point p becomes
            R(dtheta) p + (dx, dy). A time before the first applies the first.
    """

    def __init__(self, times: npt.ArrayLike, moves: npt.ArrayLike) -> None:
        self.times = np.asarray(times, np.float64).reshape(-1)
        self.moves = np.asarray(moves, np.float64).reshape(-1, 3)
        if len(self.times) != len(self.moves) or len(self.times) == 0:
            raise ConfigError(f"frame correction: {len(self.times)} times for {len(self.moves)} moves (>= 1 each)")
        if np.any(np.diff(self.times) < 0):
            raise ConfigError("frame correction: times must not decrease")

    @classmethod
    def identity(cls) -> FrameCorrection:
        """Nothing moved."""
        return cls([0.0], [[0.0, 0.0, 0.0]])

    def move(self, t: float) -> tuple[float, float, float]:
        """(dx, dy, dtheta) of what was given at robot time `t` [s]."""
        i = max(int(np.searchsorted(self.times, t, side="right")) - 1, 0)
        dx, dy, dth = self.moves[i]
        return float(dx), float(dy), float(dth)

    def points(self, xy: npt.ArrayLike, t: float) -> npt.NDArray[np.float64]:
        """(k, 2) [m] the points `xy` (k, 2), derived from a pose given at `t`, in the rebuilt map's frame."""
        p = np.asarray(xy, np.float64).reshape(-1, 2)
        dx, dy, dth = self.move(t)
        c, s = math.cos(dth), math.sin(dth)
        return np.column_stack([c * p[:, 0] - s * p[:, 1] + dx, s * p[:, 0] + c * p[:, 1] + dy])

    def point(self, x: float, y: float, t: float) -> tuple[float, float]:
        """(x, y) [m] one point, as `points`."""
        q = self.points([[x, y]], t)[0]
        return float(q[0]), float(q[1])

    def pose(self, pose: Pose, t: float) -> Pose:
        """A pose given at `t`, in the rebuilt map's frame."""
        x, y = self.point(pose.x, pose.y, t)
        return Pose(x, y, wrap_angle(pose.theta + self.move(t)[2]))
