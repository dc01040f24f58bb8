"""The `building` kind of generated world: a floor plan whose doors, corridors, rooms, clutter and laser
artefacts are drawn from what real buildings' maps measure.

The distributions below are percentiles (0, 5, ..., 100) measured on 20 maps of real buildings (offices,
labs, a hospital, a care home, houses, production halls and warehouses; laser-built and drawn) by

    python benchmarks/studies/measure_buildings.py MAPS_DIR --leave-out 'eb_*,stdr_*,turtlebot3_*,nav2_tb3_*'

(robotexp.world.measure; benchmarks/results/buildings/distributions.json holds them with the command's
commit). A value is drawn by inverting the percentiles (linear between them), within the range a
building here takes: doors `DOOR_RANGE` (narrower openings of the corpus are gaps between furniture, a
robot does not pass them), corridors `CORRIDOR_RANGE` (narrower "corridors" of the corpus are aisles
between desks, which the furniture makes), rooms `ROOM_RANGE`.

The plan is drawn on the grid's cells (CELL), so a door drawn k cells wide is k cells of free space:

- corridors: one along x, a second along y on wide floors, widths drawn; blocks of rooms between them
  and the outer walls, cut into rooms of drawn areas (a block deeper than 7 m into a front and a back row);
- doors: each front room has a door onto a corridor, each back room one into its front room, some
  neighbours one between them, all of drawn widths; a room in fifteen has none (closed: unknown inside);
- outline: a corner room in two is left out (an L-shaped building), one or two doors lead outside,
  where the space a laser sees through them is free (a fan 2-4 m deep) and all else unknown;
- furniture: shelves and cabinets against the walls, tables standing on four legs, boxes, at a drawn
  density of free-standing pieces per 100 m2, 0.7 m clear of each other and 1 m clear of doors;
- laser artefacts: bumps on the wall faces (a drawn number of corners per metre), holes of one cell
  through walls, specks of one cell in free space, unknown pockets against walls (1.6 m clear of doors),
  all at drawn rates.

Every step draws from one numpy Generator, so a seed gives the same grid.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from robotexp.mapping.geometry import GridGeometry

__all__ = ["CORRIDOR_RANGE", "DISTRIBUTIONS", "DOOR_RANGE", "OUTSIDE", "ROOM_RANGE", "Plan", "building_grid",
           "draw", "generate_building"]

CELL = 0.05
PERCENTILES = np.linspace(0.0, 100.0, 21)
# measured by benchmarks/studies/measure_buildings.py (see the module's docstring), six significant digits
DISTRIBUTIONS: dict[str, tuple[float, ...]] = {
    "door_widths": (0.375, 0.525, 0.63, 0.6962, 0.775, 0.875, 0.875, 0.8758, 0.975, 0.975, 1.0555, 1.075, 1.205,
                    1.375, 1.575, 1.7748, 1.875, 2.1335, 2.475, 3.57, 5.675),
    "corridor_widths": (0.1164, 0.4222, 0.5457, 0.6153, 0.6821, 0.7812, 0.875, 0.9206, 0.9859, 1.093, 1.1792, 1.275,
                        1.3664, 1.4621, 1.575, 1.6964, 1.7998, 1.975, 2.2233, 2.7033, 3.4764),
    "room_areas": (1.0369, 2.3577, 4.1257, 4.7192, 5.026, 5.61, 6.927, 7.7598, 9.0214, 10.4645, 11.4465, 12.4475,
                   13.6224, 16.0691, 19.5917, 25.1475, 29.7756, 43.3295, 80.8073, 138.211, 1699.75),
    "clutter_areas": (0.0101, 0.015, 0.02, 0.0225, 0.025, 0.025, 0.025, 0.0275, 0.03, 0.03, 0.0325, 0.04, 0.04, 0.045,
                      0.065, 0.0725, 0.0888, 0.1555, 0.2125, 0.2822, 568.82),
    "clutter_per_100m2": (0, 0, 0, 0, 0.2206, 0.3347, 0.919, 1.6464, 1.9822, 2.4095, 2.946, 4.0724, 6.3118, 12.0716,
                          21.0991, 24.8965, 25.8473, 26.9708, 30.6924, 31.8766, 33.5416),
    "specks_per_100m2": (0, 0, 0, 0.1867, 0.2297, 1.2693, 2.2344, 6.176, 8.9502, 10.4845, 12.0615, 14.4752, 17.0691,
                         18.8236, 24.4359, 34.6018, 40.1695, 51.7422, 58.9222, 63.1958, 68.3983),
    "wall_thickness": (0.045, 0.0663, 0.0742, 0.075, 0.075, 0.075, 0.075, 0.075, 0.075, 0.075, 0.075, 0.075, 0.075,
                       0.075, 0.0874, 0.1164, 0.1281, 0.175, 0.1833, 0.2587, 0.275),
    "corners_per_m": (1.2693, 1.7357, 2.2926, 2.656, 3.7782, 4.6157, 5.2041, 5.3866, 5.4189, 5.8444, 6.2642, 6.4802,
                      6.8017, 7.1207, 7.2888, 7.4703, 7.9113, 8.2742, 8.4423, 9.6977, 11.7067),
    "wall_gaps_per_10m": (0.0907, 0.6662, 0.7436, 1.0955, 1.3634, 2.7979, 3.6886, 4.1286, 5.0683, 5.8917, 6.8479,
                          8.1745, 9.1905, 9.6413, 9.8576, 10.4423, 11.2722, 11.7055, 12.2047, 12.4574, 13.6303),
    "pockets_per_100m2": (0, 0, 0, 0, 0, 0, 0, 0, 0, 0.1952, 0.3989, 0.5344, 0.7229, 0.8699, 1.072, 1.7334, 2.7484,
                          2.9463, 3.3591, 4.1026, 9.6956),
}
DOOR_RANGE = (0.6, 2.5)         # [m] doors drawn: a P3-DX (0.5 m) with a hand's width to spare, up to open passages
CORRIDOR_RANGE = (1.0, 3.0)     # [m]
ROOM_RANGE = (4.0, 150.0)       # [m2]
CLUTTER_RANGE = (0.01, 0.3)     # [m2] a free-standing box or post
DOOR_CLEAR = 1.0                # [m] kept free of furniture in front of a door
FURNITURE_GAP = 0.7             # [m] between free-standing pieces, and from the walls
MIN_ROOM_SIDE = 2.4             # [m]
DEEP = 7.0                      # [m] a block deeper than this holds a front and a back row of rooms
CLOSED = 1 / 15                 # share of rooms without a door (unknown inside)
POCKET_MAX = 0.6                # [m] radius of an unknown pocket
OUTSIDE = 4.5                   # [m] of grid round the building (the fans seen through its exterior doors)


def draw(rng: np.random.Generator, name: str, lo: float | None = None, hi: float | None = None) -> float:
    """A value of the measured distribution `name`, within [lo, hi] (the distribution conditioned on it)."""
    q = np.asarray(DISTRIBUTIONS[name])
    p_lo = float(np.interp(lo, q, PERCENTILES)) if lo is not None else 0.0
    p_hi = float(np.interp(hi, q, PERCENTILES)) if hi is not None else 100.0
    if p_hi - p_lo < 1e-9:       # the range holds no mass: its nearer end
        return float(np.clip(np.interp(p_lo, PERCENTILES, q), lo if lo is not None else -np.inf,
                             hi if hi is not None else np.inf))
    value = float(np.interp(rng.uniform(p_lo, p_hi), PERCENTILES, q))
    return float(np.clip(value, lo if lo is not None else value, hi if hi is not None else value))


@dataclass
class Plan:
    """What was drawn [m]: door widths, corridor widths, room areas (as planned, before furniture)."""

    doors: list[float] = field(default_factory=list)
    corridors: list[float] = field(default_factory=list)
    rooms: list[float] = field(default_factory=list)


@dataclass
class _Room:
    c0: int          # inner cells [c0, c1) x [r0, r1)
    c1: int
    r0: int
    r1: int
    doors: list[tuple[int, int, int, int]] = field(default_factory=list)     # (r0, r1, c0, c1) of each door
    closed: bool = False
    removed: bool = False


class _Canvas:
    """The grid being drawn: `occ`, `unknown` (rows, cols), the building's cells [0, cols_b) x [0, rows_b)
    at offset (r_off, c_off)."""

    def __init__(self, rows: int, cols: int, r_off: int, c_off: int, rows_b: int, cols_b: int) -> None:
        self.occ = np.zeros((rows, cols), dtype=bool)
        self.unknown = np.zeros((rows, cols), dtype=bool)
        self.fan = np.zeros((rows, cols), dtype=bool)        # free space outside, seen through exterior doors
        self.r_off, self.c_off, self.rows_b, self.cols_b = r_off, c_off, rows_b, cols_b

    def rect(self, mask: npt.NDArray[np.bool_], r0: int, r1: int, c0: int, c1: int, value: bool = True) -> None:
        """Set building cells [r0, r1) x [c0, c1) of `mask` (clipped to the grid)."""
        a, b = max(r0 + self.r_off, 0), min(r1 + self.r_off, mask.shape[0])
        c, d = max(c0 + self.c_off, 0), min(c1 + self.c_off, mask.shape[1])
        if a < b and c < d:
            mask[a:b, c:d] = value


def _cells(x: float) -> int:
    return int(round(x / CELL))


def _door_cells(rng: np.random.Generator, plan: Plan, a: int, b: int) -> tuple[int, int] | None:
    """A door of drawn width in the wall span [a, b) cells, 0.2 m from each end; None when it cannot fit."""
    margin = _cells(0.2)
    room = b - a - 2 * margin
    if room < _cells(DOOR_RANGE[0]):
        return None
    width = min(_cells(draw(rng, "door_widths", *DOOR_RANGE)), room)
    start = a + margin + int(rng.integers(0, room - width + 1))
    plan.doors.append(width * CELL)
    return start, start + width


def _rooms_along(rng: np.random.Generator, plan: Plan, c0: int, c1: int, r0: int, r1: int) -> list[_Room]:
    """Rooms cutting the block [c0, c1) x [r0, r1) (inner cells, walls between them `t` to be drawn)
    across x, each of a drawn area (its width the area over the block's depth, at least MIN_ROOM_SIDE)."""
    depth = (r1 - r0) * CELL
    rooms: list[_Room] = []
    x = c0
    while x < c1:
        width = _cells(max(draw(rng, "room_areas", *ROOM_RANGE) / depth, MIN_ROOM_SIDE))
        end = x + width
        if c1 - end < _cells(MIN_ROOM_SIDE):
            end = c1
        rooms.append(_Room(x, end, r0, r1))
        x = end
    return rooms


def _layout(rng: np.random.Generator, canvas: _Canvas, plan: Plan, t: int
            ) -> tuple[list[_Room], list[tuple[int, int, int, int]]]:
    """Outer walls, corridors and rooms with their doors. Returns the rooms and the corridors' inner
    rectangles (r0, r1, c0, c1)."""
    W, H = canvas.cols_b, canvas.rows_b
    to = max(t, 2)
    for r0, r1, c0, c1 in ((0, to, 0, W), (H - to, H, 0, W), (0, H, 0, to), (0, H, W - to, W)):
        canvas.rect(canvas.occ, r0, r1, c0, c1)
    cw = _cells(draw(rng, "corridor_widths", *CORRIDOR_RANGE))
    plan.corridors.append(cw * CELL)
    yc = int(rng.integers(int(0.3 * H), max(int(0.7 * H) - cw, int(0.3 * H) + 1)))
    corridors = [(yc, yc + cw, to, W - to)]
    xs = [(to, W - to)]
    if W * CELL > 24 and rng.random() < 0.7:
        vw = _cells(draw(rng, "corridor_widths", *CORRIDOR_RANGE))
        plan.corridors.append(vw * CELL)
        xc = int(rng.integers(int(0.35 * W), max(int(0.65 * W) - vw, int(0.35 * W) + 1)))
        corridors.append((to, H - to, xc, xc + vw))
        xs = [(to, xc - t), (xc + vw + t, W - to)]
    rooms: list[_Room] = []
    for a, b in xs:
        for r0, r1, corridor_row in ((to, yc - t, yc - t), (yc + cw + t, H - to, yc + cw)):
            rooms += _block(rng, canvas, plan, t, (a, b, r0, r1), corridor_row)
    for a, _b in xs[1:]:                      # walls of the vertical corridor, where rooms meet it
        canvas.rect(canvas.occ, to, yc, a - t, a)
        canvas.rect(canvas.occ, yc + cw, H - to, a - t, a)
    if len(xs) == 2:
        canvas.rect(canvas.occ, to, yc, xs[0][1], xs[0][1] + t)
        canvas.rect(canvas.occ, yc + cw, H - to, xs[0][1], xs[0][1] + t)
    return rooms, corridors


def _partition(canvas: _Canvas, rooms: list[_Room], t: int) -> list[_Room]:
    """Walls `t` cells thick between consecutive rooms, taken from the east room's side."""
    for room in rooms[1:]:
        canvas.rect(canvas.occ, room.r0, room.r1, room.c0, room.c0 + t)
        room.c0 += t
    return rooms


def _block(rng: np.random.Generator, canvas: _Canvas, plan: Plan, t: int, block: tuple[int, int, int, int],
           corridor_row: int) -> list[_Room]:
    """The rooms of one block [a, b) x [r0, r1) beside a corridor whose wall is the rows
    [corridor_row, corridor_row + t): walls, doors onto the corridor, back rooms, doors between rooms."""
    a, b, r0, r1 = block
    if b - a < _cells(2.0) or r1 - r0 < _cells(2.0):
        return []
    canvas.rect(canvas.occ, corridor_row, corridor_row + t, a - t, b + t)      # the corridor wall
    south = corridor_row >= r1                 # the corridor lies north of the block
    deep = (r1 - r0) * CELL > DEEP
    front_r0, front_r1 = (r0, r1) if not deep else ((r0 + r1) // 2 + t, r1) if south else (r0, (r0 + r1) // 2)
    rooms = _partition(canvas, _rooms_along(rng, plan, a, b, front_r0, front_r1), t)
    for room in rooms:
        door = _door_cells(rng, plan, room.c0, room.c1)
        if door is not None and rng.random() >= CLOSED:
            rect = (corridor_row, corridor_row + t, door[0], door[1])
            canvas.rect(canvas.occ, *rect, value=False)
            room.doors.append(rect)
        else:
            room.closed = True
    for left, right in zip(rooms, rooms[1:], strict=False):
        if rng.random() < 0.25 and not (left.closed or right.closed):
            door = _door_cells(rng, plan, front_r0, front_r1)
            if door is not None:
                rect = (door[0], door[1], right.c0 - t, right.c0)
                canvas.rect(canvas.occ, *rect, value=False)
                left.doors.append(rect)
                right.doors.append(rect)
    if deep:
        back_r0, back_r1 = (r0, front_r0 - t) if south else (front_r1 + t, r1)
        wall_row = back_r1 if south else front_r1
        canvas.rect(canvas.occ, wall_row, wall_row + t, a - t, b + t)
        back = _partition(canvas, _rooms_along(rng, plan, a, b, back_r0, back_r1), t)
        for room in back:
            fronts = [f for f in rooms if not f.closed and min(room.c1, f.c1) - max(room.c0, f.c0) > 0]
            front = max(fronts, key=lambda f: min(room.c1, f.c1) - max(room.c0, f.c0), default=None)
            lo, hi = (max(room.c0, front.c0), min(room.c1, front.c1)) if front else (0, 0)
            door = _door_cells(rng, plan, lo, hi) if front else None
            if door is not None and front is not None:
                rect = (wall_row, wall_row + t, door[0], door[1])
                canvas.rect(canvas.occ, *rect, value=False)
                room.doors.append(rect)
                front.doors.append(rect)
            else:
                room.closed = True
        rooms += back
    return rooms


def _near_door(room: _Room, r0: int, r1: int, c0: int, c1: int, clear: int) -> bool:
    """True when the cells [r0, r1) x [c0, c1) come within `clear` cells of one of the room's doors."""
    return any(r0 < d1 + clear and d0 - clear < r1 and c0 < e1 + clear and e0 - clear < c1
               for d0, d1, e0, e1 in room.doors)


def _furnish(rng: np.random.Generator, canvas: _Canvas, room: _Room, density: float) -> None:
    """Shelves against the walls, then free-standing tables (four legs) and boxes at `density` pieces per
    100 m2, each FURNITURE_GAP clear of the others and of the walls."""
    gap = _cells(FURNITURE_GAP)
    for _ in range(int(rng.integers(0, 3))):                  # shelves and cabinets against a wall
        depth, length = _cells(rng.uniform(0.3, 0.6)), _cells(rng.uniform(0.8, 2.0))
        for _try in range(5):
            if int(rng.integers(2)) == 0 and room.c1 - room.c0 > length:          # along a south/north wall
                c0 = int(rng.integers(room.c0, room.c1 - length + 1))
                r0 = room.r0 if rng.random() < 0.5 else room.r1 - depth
                box = (r0, r0 + depth, c0, c0 + length)
            elif room.r1 - room.r0 > length:
                r0 = int(rng.integers(room.r0, room.r1 - length + 1))
                c0 = room.c0 if rng.random() < 0.5 else room.c1 - depth
                box = (r0, r0 + length, c0, c0 + depth)
            else:
                break
            if not _near_door(room, *box, _cells(DOOR_CLEAR)) and _clear_inside(canvas, room, box, gap):
                canvas.rect(canvas.occ, *box)
                break
    area = (room.r1 - room.r0) * (room.c1 - room.c0) * CELL * CELL
    pieces = int(rng.poisson(density * area / 100.0))
    while pieces > 0:
        if pieces >= 4 and rng.random() < 0.3:                   # a table on four legs: four pieces
            tw, th, leg = _cells(rng.uniform(0.8, 1.6)), _cells(rng.uniform(0.6, 1.0)), _cells(0.1)
            pieces -= 4
        else:
            pieces -= 1
            side = max(_cells(np.sqrt(draw(rng, "clutter_areas", *CLUTTER_RANGE))), 1)
            tw, th, leg = side, side, 0
        if room.r1 - room.r0 < th + 2 * gap or room.c1 - room.c0 < tw + 2 * gap:
            continue
        r0 = int(rng.integers(room.r0 + gap, room.r1 - gap - th + 1))
        c0 = int(rng.integers(room.c0 + gap, room.c1 - gap - tw + 1))
        box = (r0, r0 + th, c0, c0 + tw)
        if _near_door(room, *box, _cells(DOOR_CLEAR)) or not _clear_inside(canvas, room, box, gap):
            continue
        if leg:
            for rr, cc in ((r0, c0), (r0 + th - leg, c0), (r0, c0 + tw - leg), (r0 + th - leg, c0 + tw - leg)):
                canvas.rect(canvas.occ, rr, rr + leg, cc, cc + leg)
        else:
            canvas.rect(canvas.occ, r0, r0 + th, c0, c0 + tw)


def _clear_inside(canvas: _Canvas, room: _Room, box: tuple[int, int, int, int], gap: int) -> bool:
    """No obstacle within `gap` cells of `box`, looking inside the room only (the walls do not count)."""
    r0, r1, c0, c1 = box
    a, b = max(r0 - gap, room.r0) + canvas.r_off, min(r1 + gap, room.r1) + canvas.r_off
    c, d = max(c0 - gap, room.c0) + canvas.c_off, min(c1 + gap, room.c1) + canvas.c_off
    return not canvas.occ[a:b, c:d].any()


def _outline(rng: np.random.Generator, canvas: _Canvas, plan: Plan, rooms: list[_Room],
             corridors: list[tuple[int, int, int, int]], t: int) -> list[tuple[int, int, int, int]]:
    """Closed rooms unknown inside, a corner room left out (unknown) in one building of two, one or two doors
    to the outside with the fan of free space a laser sees through each. Returns the exterior doors' cells."""
    W, H = canvas.cols_b, canvas.rows_b
    to = max(t, 2)
    corner = [r for r in rooms if (r.c0 == to or r.c1 == W - to) and (r.r0 == to or r.r1 == H - to)]
    if corner and rng.random() < 0.5:
        room = corner[int(rng.integers(len(corner)))]
        room.removed = True
        rows = (0, room.r1) if room.r0 == to else (room.r0, H)
        cols = (0, room.c1) if room.c0 == to else (room.c0, W)
        for d in room.doors:
            canvas.rect(canvas.occ, *d)                # its doors closed: a wall of the outline
        canvas.rect(canvas.occ, *rows, *cols, value=False)
        canvas.rect(canvas.unknown, *rows, *cols)
    for room in rooms:
        if room.closed and not room.removed:
            canvas.rect(canvas.unknown, room.r0, room.r1, room.c0, room.c1)
    exits: list[tuple[int, int, int, int]] = []
    r0, r1, _, _ = corridors[0]                     # the main corridor's west or east end
    west = rng.random() < 0.5
    width = min(_cells(draw(rng, "door_widths", *DOOR_RANGE)), r1 - r0)
    d0 = r0 + int(rng.integers(0, r1 - r0 - width + 1))
    exits.append((d0, d0 + width, 0, to) if west else (d0, d0 + width, W - to, W))
    plan.doors.append(width * CELL)
    outer = [r for r in rooms if not (r.closed or r.removed) and (r.r0 == to or r.r1 == H - to)]
    if outer and rng.random() < 0.5:
        room = outer[int(rng.integers(len(outer)))]
        door = _door_cells(rng, plan, room.c0, room.c1)
        if door is not None:
            exit_ = (0, to, *door) if room.r0 == to else (H - to, H, *door)
            exits.append(exit_)
            room.doors.append(exit_)
    for ex in exits:
        canvas.rect(canvas.occ, *ex, value=False)
        _fan(rng, canvas, ex)
    return exits


def _fan(rng: np.random.Generator, canvas: _Canvas, door: tuple[int, int, int, int]) -> None:
    """Free cells outside the exterior `door` that a laser inside sees: a fan 2-4 m deep widening at 35 deg."""
    W, H = canvas.cols_b, canvas.rows_b
    r0, r1, c0, c1 = door
    depth = _cells(rng.uniform(2.0, 4.0))
    spread = 0.7
    for k in range(1, depth + 1):
        s = int(k * spread)
        if c0 == 0:                        # west wall: the fan goes to negative columns
            canvas.rect(canvas.fan, r0 - s, r1 + s, -k, -k + 1)
        elif c1 == W:
            canvas.rect(canvas.fan, r0 - s, r1 + s, W + k - 1, W + k)
        elif r0 == 0:
            canvas.rect(canvas.fan, -k, -k + 1, c0 - s, c1 + s)
        else:
            canvas.rect(canvas.fan, H + k - 1, H + k, c0 - s, c1 + s)


def _faces(canvas: _Canvas, inside: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """Free cells inside the building 4-adjacent to an occupied cell."""
    occ = canvas.occ
    p = np.pad(occ, 1, constant_values=False)
    touch = p[:-2, 1:-1] | p[2:, 1:-1] | p[1:-1, :-2] | p[1:-1, 2:]
    return touch & ~occ & ~canvas.unknown & inside


def _keep_doors(canvas: _Canvas, rooms: list[_Room], exits: list[tuple[int, int, int, int]], grow: int
                ) -> npt.NDArray[np.bool_]:
    """The cells within `grow` cells of a door: artefacts keep off them, so doors keep their drawn widths."""
    keep = np.zeros_like(canvas.occ)
    for r0, r1, c0, c1 in {d for room in rooms for d in room.doors} | set(exits):
        canvas.rect(keep, r0 - grow, r1 + grow, c0 - grow, c1 + grow)
    return keep


def _artefacts(rng: np.random.Generator, canvas: _Canvas, inside: npt.NDArray[np.bool_],
               keep: npt.NDArray[np.bool_], far: npt.NDArray[np.bool_]) -> None:
    """Bumps on wall faces (drawn corners per metre, 4 corners a bump), one-cell holes through walls
    (drawn per 10 m of face) and specks in free space off the cells `keep`, unknown pockets against walls
    (drawn per 100 m2) off the cells `far` (a pocket beside a door would narrow the way to it)."""
    faces = _faces(canvas, inside) & ~keep
    cells = np.argwhere(faces)
    face_m = len(cells) * CELL
    free_m2 = float(np.count_nonzero(inside & ~canvas.occ & ~canvas.unknown)) * CELL * CELL
    n_bumps = min(int(draw(rng, "corners_per_m") * face_m / 4), len(cells))
    for r, c in cells[rng.choice(len(cells), size=n_bumps, replace=False)] if n_bumps else ():
        canvas.occ[r, c] = True
    _holes(rng, canvas, inside, keep, int(round(draw(rng, "wall_gaps_per_10m") * face_m / 10)))
    free = np.argwhere(inside & ~canvas.occ & ~canvas.unknown & ~keep)
    n_specks = min(int(rng.poisson(draw(rng, "specks_per_100m2") * free_m2 / 100)), len(free))
    for r, c in free[rng.choice(len(free), size=n_specks, replace=False)] if n_specks else ():
        canvas.occ[r, c] = True
    spots = np.argwhere(_faces(canvas, inside) & ~far)
    rows, cols = canvas.occ.shape
    for _ in range(min(int(rng.poisson(draw(rng, "pockets_per_100m2") * free_m2 / 100)), len(spots))):
        r, c = spots[int(rng.integers(len(spots)))]
        rad = _cells(rng.uniform(0.3, POCKET_MAX))
        yy, xx = np.ogrid[max(r - rad, 0):min(r + rad + 1, rows), max(c - rad, 0):min(c + rad + 1, cols)]
        disc = (yy - r) ** 2 + (xx - c) ** 2 <= rad * rad
        win = (slice(max(r - rad, 0), min(r + rad + 1, rows)), slice(max(c - rad, 0), min(c + rad + 1, cols)))
        canvas.unknown[win] |= disc & ~canvas.occ[win] & inside[win] & ~keep[win]


def _holes(rng: np.random.Generator, canvas: _Canvas, inside: npt.NDArray[np.bool_], keep: npt.NDArray[np.bool_],
           n: int) -> None:
    """`n` holes of one cell through walls at most 3 cells thick, between free cells of the building; a hole
    that cut a piece of wall off the rest (two holes in one stretch of wall) is filled again, so the
    walls stay one piece (a piece standing alone would be clutter)."""
    occ = canvas.occ
    walls = np.argwhere(occ & inside & ~keep)
    rows, cols = occ.shape
    holes: list[list[tuple[int, int]]] = []
    for _try in range(20 * n):
        if len(holes) >= n or not len(walls):
            break
        r, c = walls[int(rng.integers(len(walls)))]
        dr, dc = ((1, 0), (0, 1))[int(rng.integers(2))]
        lo, hi = 0, 0                                   # the wall's extent across, through (r, c)
        while lo < 3 and occ[r - (lo + 1) * dr, c - (lo + 1) * dc]:
            lo += 1
        while hi < 3 and occ[r + (hi + 1) * dr, c + (hi + 1) * dc]:
            hi += 1
        a = (r - (lo + 1) * dr, c - (lo + 1) * dc)
        b = (r + (hi + 1) * dr, c + (hi + 1) * dc)
        if lo + hi + 1 > 3 or not all(0 <= p[0] < rows and 0 <= p[1] < cols for p in (a, b)):
            continue
        if all(inside[p] and not occ[p] and not canvas.unknown[p] for p in (a, b)):
            cut = [(int(r + k * dr), int(c + k * dc)) for k in range(-lo, hi + 1)]
            for cell in cut:
                occ[cell] = False
            holes.append(cut)
    _mend(canvas, holes)


def _mend(canvas: _Canvas, holes: list[list[tuple[int, int]]]) -> None:
    """Fill the holes next to a piece of wall the holes cut off the building's walls (the largest piece)."""
    from scipy import ndimage  # type: ignore[import-untyped]  # scipy: a dependency (statistics)

    if not holes:
        return
    parts, _ = ndimage.label(canvas.occ, structure=np.ones((3, 3), dtype=bool))
    sizes = np.bincount(parts.ravel())
    sizes[0] = 0
    main = int(np.argmax(sizes))
    rows, cols = canvas.occ.shape
    for cut in holes:
        r0, c0 = min(p[0] for p in cut) - 1, min(p[1] for p in cut) - 1
        r1, c1 = max(p[0] for p in cut) + 2, max(p[1] for p in cut) + 2
        around = parts[max(r0, 0):min(r1, rows), max(c0, 0):min(c1, cols)]
        if np.any((around > 0) & (around != main)):
            for cell in cut:
                canvas.occ[cell] = True


def building_grid(rng: np.random.Generator, shape: tuple[int, int], offset: tuple[int, int],
                  size: tuple[int, int]) -> tuple[npt.NDArray[np.int8], Plan]:
    """A building of `size` (rows, cols) cells of CELL, its south-west cell at `offset` (row, col) of a grid
    of `shape`: values 0 free, 100 occupied, -1 unknown (everything outside the building but the fans
    seen through its exterior doors), and the plan's drawn widths and areas."""
    canvas = _Canvas(*shape, *offset, *size)
    plan = Plan()
    t = max(1, _cells(draw(rng, "wall_thickness", 0.05, 0.2)))
    rooms, corridors = _layout(rng, canvas, plan, t)
    plan.rooms = [(r.r1 - r.r0) * (r.c1 - r.c0) * CELL * CELL for r in rooms]
    density = draw(rng, "clutter_per_100m2")
    for room in rooms:
        if not room.closed:
            _furnish(rng, canvas, room, density)
    exits = _outline(rng, canvas, plan, rooms, corridors, t)
    inside = np.zeros_like(canvas.occ)
    canvas.rect(inside, 0, canvas.rows_b, 0, canvas.cols_b)
    inside &= ~canvas.unknown
    _artefacts(rng, canvas, inside, _keep_doors(canvas, rooms, exits, 2),
               _keep_doors(canvas, rooms, exits, _cells(DOOR_CLEAR + POCKET_MAX)))
    values = np.where(canvas.occ, 100, 0).astype(np.int8)
    values[canvas.unknown | (~inside & ~canvas.fan & ~canvas.occ)] = -1
    values[canvas.fan & ~inside] = 0
    return values, plan


def generate_building(rng: np.random.Generator, width: float, height: float
                      ) -> tuple[npt.NDArray[np.int8], GridGeometry, Plan]:
    """A building of `width` x `height` [m] (rounded to cells), its south-west corner at (0, 0), on a grid
    reaching OUTSIDE beyond it: (values, geo, plan) as `building_grid`."""
    cols_b, rows_b = _cells(width), _cells(height)
    geo = GridGeometry.covering(-OUTSIDE, -OUTSIDE, cols_b * CELL + OUTSIDE, rows_b * CELL + OUTSIDE, CELL)
    offset = geo.cell_of(CELL / 2, CELL / 2)
    values, plan = building_grid(rng, (geo.rows, geo.cols), offset, (rows_b, cols_b))
    return values, geo, plan
