"""The live view of a robot outside a run (`robotexp connect --view`): its odometry pose, laser, path
and a map built from its scans, from the states the caller reads."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.robot import RobotState
from robotexp.view.feed import Frame, ViewHub, classes_of_states

__all__ = ["StateFeed"]


class StateFeed:
    """Publishes robot states to a `ViewHub`; the page's stop button sets `stop_requested`.

    Args:
        hub: where the frames go.
        title: the page's title.
        radius: [m] the robot's footprint.
        size: [m] side of the square map centred on the first pose.
        cell: [m] map cell.
        map_rate: [1/s] most maps per wall second.
    """

    def __init__(self, hub: ViewHub, title: str, radius: float, *, size: float = 20.0, cell: float = 0.1,
                 map_rate: float = 2.0, clock: Callable[[], float] = time.monotonic) -> None:
        self.hub, self.title, self.radius, self.size, self.cell = hub, title, radius, size, cell
        self.map_period, self.clock = 1 / map_rate, clock
        self.grid: OccupancyGrid | None = None
        self.stop_requested = False
        self._t0: float | None = None
        self._next_map = -math.inf
        self._last_xy: tuple[float, float] | None = None
        hub.controls = ("stop",)
        hub.on_command = self.command

    def command(self, msg: dict[str, object]) -> None:
        """The page's stop button ends the watch."""
        if msg.get("cmd") == "stop":
            self.stop_requested = True

    def publish(self, state: RobotState) -> None:
        """Show `state` (the first one starts the view: the map is centred on its pose)."""
        p = state.pose
        if self.grid is None:
            half = self.size / 2
            geo = GridGeometry.covering(p.x - half, p.y - half, p.x + half, p.y + half, cell=self.cell)
            self.grid = OccupancyGrid(geo, range_max=state.laser.range_max if state.laser else 10.0)
            self._t0 = state.time
            self.hub.start({"geo": {"origin_x": geo.origin_x, "origin_y": geo.origin_y, "cell": geo.cell,
                                    "rows": geo.rows, "cols": geo.cols},
                            "radius": self.radius, "title": self.title, "run": self.title, "simulated": False,
                            "truth": False, "start": [p.x, p.y, p.theta]})
        frame = Frame(time=state.time - (self._t0 or 0.0), pose=(p.x, p.y, p.theta))
        sc = state.laser
        if sc is not None:
            self.grid.update(p, sc)
            frame.scan = sc
        if self._last_xy is None or math.hypot(p.x - self._last_xy[0], p.y - self._last_xy[1]) >= self.cell / 2:
            frame.path = [round(p.x, 3), round(p.y, 3)]
            self._last_xy = (p.x, p.y)
        now = self.clock()
        if now >= self._next_map:
            self._next_map = now + self.map_period
            frame.map = classes_of_states(self.grid.states())
        self.hub.publish(frame)

    def finish(self, reason: str) -> None:
        """The watch ended."""
        self.hub.finish(reason)
