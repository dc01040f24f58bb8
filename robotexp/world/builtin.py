"""The built-in worlds: `dense` (an office), `sparse` (a hall), `ufmg-static` and `ufmg-dynamic`.

They are drawn here in metres, after the thesis's MobileSim maps (Ribacki 2011, Fig. 4.5) and the
UFMG practical work's CoppeliaSim scenes: the same kind of places at the same scale, not copies.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from robotexp.errors import WorldError
from robotexp.robot import Pose
from robotexp.world.model import Mover, World, segment_box

__all__ = ["BUILTIN", "DOOR_CENTRES", "builtin_world", "builtin_names", "rooms_in_a_row"]

WALL = 0.10     # [m] thickness of built-in walls


class _Drawing:
    """Collects the boxes and discs of a world while it is drawn."""

    def __init__(self) -> None:
        self.boxes: list[tuple[float, ...]] = []
        self.discs: list[tuple[float, float, float]] = []

    def wall(self, x0: float, y0: float, x1: float, y1: float,
             doors: Sequence[tuple[float, float]] = ()) -> None:
        """An axis-aligned wall from (x0, y0) to (x1, y1) with door gaps given as (from, to) along it."""
        horizontal = y0 == y1
        lo, hi = (min(x0, x1), max(x0, x1)) if horizontal else (min(y0, y1), max(y0, y1))
        cuts = sorted(doors)
        start = lo
        pieces = []
        for a, b in cuts:
            pieces.append((start, a))
            start = b
        pieces.append((start, hi))
        for a, b in pieces:
            if b - a <= 1e-9:
                continue
            if horizontal:
                self.boxes.append(segment_box(a, y0, b, y0, WALL))
            else:
                self.boxes.append(segment_box(x0, a, x0, b, WALL))

    def rect(self, cx: float, cy: float, width: float, depth: float, yaw_deg: float = 0.0) -> None:
        """A piece of furniture: a `width` x `depth` [m] box centred at (cx, cy)."""
        self.boxes.append((cx, cy, width / 2, depth / 2, math.radians(yaw_deg)))

    def pillar(self, cx: float, cy: float, r: float) -> None:
        """A round pillar of radius `r` [m]."""
        self.discs.append((cx, cy, r))

    def room(self, x0: float, y0: float, x1: float, y1: float) -> None:
        """The four outer walls of a closed rectangle."""
        self.wall(x0, y0, x1, y0)
        self.wall(x0, y1, x1, y1)
        self.wall(x0, y0, x0, y1)
        self.wall(x1, y0, x1, y1)


def _poses(*items: tuple[str, float, float, float]) -> dict[str, Pose]:
    return {name: Pose(x, y, math.radians(th)) for name, x, y, th in items}


def _dense() -> World:
    """A 20 m x 15 m office: a 2 m east-west corridor at y = 7.5 m, four rooms north of it, three
    south, doors of 1.2 m, desks, cabinets and shelves."""
    d = _Drawing()
    d.room(-10, 0, 10, 15)
    # corridor walls (y = 6.5 and 8.5) with one door per room
    d.wall(-10, 8.5, 10, 8.5, doors=[(-8.0, -6.8), (-3.2, -2.0), (1.6, 2.8), (6.4, 7.6)])
    d.wall(-10, 6.5, 10, 6.5, doors=[(-7.0, -5.8), (-0.6, 0.6), (6.0, 7.2)])
    for xn in (-5.0, 0.0, 5.0):                 # north rooms, 5 m wide
        d.wall(xn, 8.5, xn, 15)
    for xs in (-3.5, 3.5):                      # south rooms
        d.wall(xs, 0, xs, 6.5)
    # room N1 (-10..-5): two desks and a cabinet
    d.rect(-8.6, 12.8, 1.6, 0.8)
    d.rect(-6.2, 11.0, 0.8, 1.6)
    d.rect(-9.6, 10.0, 0.6, 1.2)
    # room N2 (-5..0): meeting table, shelf
    d.rect(-2.5, 12.0, 2.4, 1.2)
    d.rect(-4.6, 14.2, 0.6, 1.2)
    d.rect(-0.5, 10.0, 0.8, 0.8)
    # room N3 (0..5): L of desks
    d.rect(2.0, 13.6, 2.0, 0.8)
    d.rect(4.4, 12.2, 0.8, 2.0)
    d.rect(1.0, 10.4, 1.0, 1.0)
    # room N4 (5..10): store room with shelves
    d.rect(9.6, 12.0, 0.6, 3.0)
    d.rect(7.0, 13.2, 1.6, 0.6)
    d.rect(6.2, 10.6, 0.8, 0.8)
    # room S1 (-10..-3.5): open plan with four desks
    for cx, cy in ((-8.2, 2.0), (-5.4, 2.0), (-8.2, 4.2), (-5.4, 4.2)):
        d.rect(cx, cy, 1.6, 0.8)
    # room S2 (-3.5..3.5): lab benches and a pillar
    d.rect(-2.0, 3.0, 0.8, 2.4)
    d.rect(2.0, 3.0, 0.8, 2.4)
    d.pillar(0.0, 1.4, 0.3)
    d.rect(0.0, 5.2, 1.2, 0.6)
    # room S3 (3.5..10): kitchen: counter along the wall, table
    d.rect(9.6, 3.0, 0.6, 4.0)
    d.rect(6.4, 2.4, 1.2, 1.2)
    d.rect(4.2, 0.5, 1.2, 0.6)
    # corridor furniture: a bench and a plant
    d.rect(-9.0, 7.0, 1.2, 0.4)
    d.pillar(8.6, 8.1, 0.2)
    poses = _poses(("1", -5.0, 7.5, 0), ("2", -1.6, 7.5, 0), ("3", 2.7, 7.5, 0),
                   ("4", -7.5, 11.5, 90), ("5", -2.5, 9.8, 0), ("6", 2.5, 11.5, 180),
                   ("7", -7.0, 3.2, 0), ("8", 0.0, 3.0, 90), ("9", 7.0, 4.5, -90))
    return World("dense", np.array(d.boxes), np.array(d.discs).reshape(-1, 3), poses=poses,
                 description="office, 20 x 15 m: corridor, 7 rooms, furniture")


def _sparse() -> World:
    """A 30 m x 20 m hall with six pillars, two short partition walls and a few crates."""
    d = _Drawing()
    d.room(-15, -10, 15, 10)
    for cx, cy in ((-7.5, -4.0), (0.0, -4.0), (7.5, -4.0), (-7.5, 4.0), (0.0, 4.0), (7.5, 4.0)):
        d.pillar(cx, cy, 0.35)
    d.wall(-15, 0.0, -11, 0.0)                  # a partition from the west wall
    d.wall(11, -10, 11, -6)                     # and one from the south wall
    d.rect(12.5, 7.5, 1.2, 1.2)
    d.rect(-12.0, -8.0, 2.0, 1.0)
    d.rect(3.5, 8.6, 1.0, 1.0)
    poses = _poses(("1", -12.0, -4.0, 0), ("2", -3.5, 0.0, 0), ("3", 4.0, -7.5, 90),
                   ("4", 12.0, 2.0, 180), ("5", -4.0, 7.5, -90))
    return World("sparse", np.array(d.boxes), np.array(d.discs).reshape(-1, 3), poses=poses,
                 description="hall, 30 x 20 m: 6 pillars, 2 partitions, 3 crates")


def _ufmg(dynamic: bool) -> World:
    """The UFMG practical work's scene: a 10 m x 10 m room with boxes and a shelf, and (dynamic)
    a person walking back and forth across it at 0.5 m/s."""
    d = _Drawing()
    d.room(-5, -5, 5, 5)
    d.rect(-2.5, -2.0, 1.0, 1.0)
    d.rect(2.5, 2.0, 1.5, 0.6)
    d.rect(-3.0, 3.0, 0.6, 1.8)
    d.rect(3.2, -3.0, 1.2, 1.2)
    d.pillar(0.0, 0.0, 0.25)
    d.wall(1.0, -5, 1.0, -2.5)
    poses = _poses(("path1", -4.2, -4.2, 45), ("path2", 4.2, 4.2, -135))
    goals = {"path1": [(-4.0, 1.0), (-1.0, 4.0), (4.0, 4.0), (4.0, 0.0), (2.5, -4.0), (0.0, -2.0),
                       (-1.2, -4.2)],
             "path2": [(1.0, 4.2), (-4.2, 4.2), (-4.2, -0.5), (-1.5, -4.0), (-0.2, -2.0), (2.5, -1.0),
                       (4.2, -1.5)]}
    movers = []
    if dynamic:
        movers.append(Mover(radius=0.25, speed=0.5, path=np.array([[-3.8, 1.2], [3.8, 0.8]])))
    name = "ufmg-dynamic" if dynamic else "ufmg-static"
    desc = "room 10 x 10 m" + (", a person walking across it" if dynamic else ", static")
    return World(name, np.array(d.boxes), np.array(d.discs).reshape(-1, 3), poses=poses, movers=movers,
                 goals=goals, description=desc)


DOOR_CENTRES = (0.93, 3.04, 1.27, 2.71)    # [m] y of the doors' centres, room after room: off the middle,
#                                           off the 10 cm grid, alternating sides


def rooms_in_a_row(door: float, rooms: int = 5, size: float = 4.0) -> World:
    """`rooms` square rooms of `size` [m] in a row along x, each joined to the next by a door `door` [m]
    wide in a wall 0.1 m thick, the doors off the middle of the walls (`DOOR_CENTRES`, cycled): the test of
    whether explorers drive through the doors a robot fits through. Inner faces: x 0..rooms*size,
    y 0..size, less half a wall; the door's jambs lie exactly `door` apart.
    """
    d = _Drawing()
    length = rooms * size
    d.room(0.0, 0.0, length, size)
    for k in range(1, rooms):
        yc = DOOR_CENTRES[(k - 1) % len(DOOR_CENTRES)] * size / 4.0
        d.wall(k * size, 0.0, k * size, size, doors=[(yc - door / 2 - WALL / 2, yc + door / 2 + WALL / 2)])
    return World(f"rooms-in-a-row-{door:g}", np.array(d.boxes), poses={"first room": Pose(size / 2, size / 2, 0.0)})


BUILTIN: dict[str, Callable[[], World]] = {
    "dense": _dense,
    "sparse": _sparse,
    "ufmg-static": lambda: _ufmg(False),
    "ufmg-dynamic": lambda: _ufmg(True),
}


def builtin_names() -> list[str]:
    """Names of the built-in worlds."""
    return list(BUILTIN)


def builtin_world(name: str) -> World:
    """A fresh copy of the built-in world `name`. Raises WorldError listing the available ones."""
    try:
        factory = BUILTIN[name]
    except KeyError:
        raise WorldError(f"unknown world {name!r}: use one of {', '.join(BUILTIN)} "
                         "or the path of a .map or ROS .yaml file") from None
    return factory()
