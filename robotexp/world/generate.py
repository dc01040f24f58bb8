"""Procedural worlds: floor plans of offices, warehouses, caves and buildings, deterministic per seed.

The `building` kind (robotexp.world.building) draws its doors, corridors, rooms, clutter and laser
artefacts from distributions measured on maps of real buildings; the others are drawn by the rules below.

`generate_grid(kind, seed)` draws a plan (walls with doors, rooms, corridors, furniture, racks,
pillars, clutter) and rasterises it on a 5 cm occupancy grid (0 free, 100 occupied, -1 unknown);
`write_generated` saves it as a ROS map (`.yaml` + `.pgm`) or an ARIA point map (`.map`: one
DATA point per occupied cell with a non-occupied 8-neighbour, `MinPos`/`MaxPos` the grid's extent;
unknown cells are not written, a point map has none); `generated_world` gives the same grid as a
`World` (as if the `.yaml` were loaded), which `load_world("generated:KIND:SEED")` returns. The
same kind, seed, size and options give the same bytes: only numpy's seeded PCG64 draws, and
rasterising is exact.

In office, warehouse and cave every door and passage is at least `DOOR_MIN` wide (a P3-DX, 0.5 m
across, with 0.2 m on each side); a building's doors are as narrow as real ones (from 0.6 m). With
`scanned=True` the map gets the artefacts of laser-built maps: some walls one cell thin, small breaks
in walls (narrower than a robot, wide enough for a laser), one to three gaps in the outer wall onto a
band of free space outside the building, and unknown space around it all.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError, WorldError
from robotexp.mapping.geometry import GridGeometry, check_grid_size
from robotexp.world.model import World

__all__ = ["CELL", "DEFAULT_SIZES", "DOOR_MIN", "KINDS", "expand_generated", "generate_grid", "generated_world",
           "parse_generated", "write_generated"]

CELL = 0.05                 # [m] cell of the generated grid
DOOR_MIN = 0.9              # [m] narrowest door or passage
KINDS = ("office", "warehouse", "cave", "building")
DEFAULT_SIZES = {"office": (30.0, 20.0), "warehouse": (40.0, 30.0), "cave": (30.0, 24.0), "building": (36.0, 24.0)}
MIN_SIZE, MAX_SIZE = 8.0, 200.0     # [m] side of a generated world
_OUTSIDE = 3.0              # [m] band around the building in scanned maps (free near gaps, then unknown)
_SPEC = re.compile(r"generated:([a-z]+):(\d+)(?:-(\d+))?((?::[a-z0-9.x]+)*)")

Boxes = list[tuple[float, float, float, float, float]]


def _wall(boxes: Boxes, x0: float, y0: float, x1: float, y1: float, t: float,
          gaps: list[tuple[float, float]] = ()) -> None:   # type: ignore[assignment]
    """Append the boxes of an axis-aligned wall from (x0, y0) to (x1, y1) [m], `t` thick, leaving
    the `gaps` (intervals along the wall, absolute coordinates) open; the ends reach t/2 past the
    end points so walls meeting at a corner close it."""
    horizontal = y0 == y1
    a, b = (min(x0, x1), max(x0, x1)) if horizontal else (min(y0, y1), max(y0, y1))
    pieces: list[tuple[float, float]] = []
    cur = a - t / 2
    for g0, g1 in sorted(gaps):
        if g0 > cur:
            pieces.append((cur, g0))
        cur = max(cur, g1)
    if b + t / 2 > cur:
        pieces.append((cur, b + t / 2))
    for p0, p1 in pieces:
        if p1 - p0 < 1e-6:
            continue
        if horizontal:
            boxes.append(((p0 + p1) / 2, y0, (p1 - p0) / 2, t / 2, 0.0))
        else:
            boxes.append((x0, (p0 + p1) / 2, t / 2, (p1 - p0) / 2, 0.0))


def _door(rng: np.random.Generator, a: float, b: float) -> tuple[float, float]:
    """A door interval of width U(DOOR_MIN, 1.5) m within [a, b], 0.3 m from each end."""
    width = float(rng.uniform(DOOR_MIN, 1.5))
    width = min(width, max(b - a - 0.6, DOOR_MIN))
    lo, hi = a + 0.3, max(a + 0.3, b - 0.3 - width)
    start = float(rng.uniform(lo, hi))
    return (start, start + width)


def _blocked(shapes: Boxes, x0: float, y0: float, x1: float, y1: float, clearance: float) -> bool:
    """True when the box x0..x1, y0..y1 [m] grown by `clearance` overlaps an axis-aligned shape."""
    for cx, cy, hx, hy, _ in shapes:
        if (x0 - clearance < cx + hx and cx - hx < x1 + clearance and y0 - clearance < cy + hy
                and cy - hy < y1 + clearance):
            return True
    return False


def _furnish(rng: np.random.Generator, boxes: Boxes, room: tuple[float, float, float, float],
             doors: list[tuple[float, float]], t: float) -> None:
    """Desks and cabinets against the walls and maybe a table in the middle of `room` (its inner
    x0, y0, x1, y1 [m]), keeping `DOOR_MIN` + 0.1 m clear in front of each door point in `doors` and
    between pieces, so every part of the room stays reachable."""
    x0, y0, x1, y1 = room
    keep: Boxes = [(dx, dy, 0.85, 0.85, 0.0) for dx, dy in doors]      # the doors' approaches
    placed: Boxes = []
    gap = DOOR_MIN + 0.1
    for _ in range(int(rng.integers(1, 5))):
        depth, length = float(rng.uniform(0.4, 0.8)), float(rng.uniform(0.8, 1.8))
        side = int(rng.integers(4))
        for _try in range(6):
            if side in (0, 1):            # against the south / north wall
                if x1 - x0 < length + 0.2:
                    break
                cx = float(rng.uniform(x0 + length / 2, x1 - length / 2))
                cy = y0 + depth / 2 if side == 0 else y1 - depth / 2
                box = (cx, cy, length / 2, depth / 2, 0.0)
            else:                          # against the west / east wall
                if y1 - y0 < length + 0.2:
                    break
                cy = float(rng.uniform(y0 + length / 2, y1 - length / 2))
                cx = x0 + depth / 2 if side == 2 else x1 - depth / 2
                box = (cx, cy, depth / 2, length / 2, 0.0)
            bx0, by0, bx1, by1 = box[0] - box[2], box[1] - box[3], box[0] + box[2], box[1] + box[3]
            if not _blocked(keep, bx0, by0, bx1, by1, 0.0) and not _blocked(placed, bx0, by0, bx1, by1, gap):
                placed.append(box)
                break
    # a table in the middle when the room leaves DOOR_MIN around it
    w, h = x1 - x0, y1 - y0
    tw, th = float(rng.uniform(0.8, 2.0)), float(rng.uniform(0.7, 1.2))
    if rng.random() < 0.6 and w > tw + 2 * gap + 1.7 and h > th + 2 * gap + 1.7:
        cx, cy = float(rng.uniform(x0 + gap + 0.85 + tw / 2, x1 - gap - 0.85 - tw / 2)), \
            float(rng.uniform(y0 + gap + 0.85 + th / 2, y1 - gap - 0.85 - th / 2))
        box = (cx, cy, tw / 2, th / 2, 0.0)
        if not _blocked(placed + keep, cx - tw / 2, cy - th / 2, cx + tw / 2, cy + th / 2, gap):
            placed.append(box)
    boxes.extend(placed)


def _office(rng: np.random.Generator, w: float, h: float, t: float
            ) -> tuple[Boxes, list[tuple[float, float, float]], list[tuple[float, float, float, float]]]:
    """An office floor: a corridor along x (and one along y on wide floors), rooms off it with doors,
    furniture. Returns boxes, discs and the outer wall's sides as (x0, y0, x1, y1)."""
    boxes: Boxes = []
    discs: list[tuple[float, float, float]] = []
    cw = float(rng.uniform(1.6, 2.4))
    yc = float(rng.uniform(0.35 * h, 0.65 * h - cw))
    vertical = w > 20 and rng.random() < 0.7
    xc = float(rng.uniform(0.35 * w, 0.65 * w - cw)) if vertical else w + 1
    # corridor walls, with doors cut later per room
    blocks = []                # (x0, x1, y0, y1, corridor side: "north" / "south")
    xs = [(0.0, xc), (xc + cw, w)] if vertical else [(0.0, w)]
    for a, b in xs:
        blocks.append((a, b, 0.0, yc, "north"))
        blocks.append((a, b, yc + cw, h, "south"))
    corridor_doors: list[tuple[float, tuple[float, float]]] = []
    for bx0, bx1, by0, by1, side in blocks:
        wall_y = by1 if side == "north" else by0
        # rooms along x
        cuts = [bx0]
        while cuts[-1] < bx1 - 1e-9:
            nxt = cuts[-1] + float(rng.uniform(3.0, 6.0))
            if bx1 - nxt < 2.5:
                nxt = bx1
            cuts.append(nxt)
        door_gaps: list[tuple[float, float]] = []
        for i in range(len(cuts) - 1):
            rx0, rx1 = cuts[i], cuts[i + 1]
            door = _door(rng, rx0, rx1)
            door_gaps.append(door)
            doors = [((door[0] + door[1]) / 2, wall_y)]
            if i > 0:
                inner = _door(rng, by0, by1) if rng.random() < 0.3 else None
                _wall(boxes, rx0, by0, rx0, by1, t, [inner] if inner else [])
                if inner:
                    doors += [(rx0, (inner[0] + inner[1]) / 2)]
            ry0, ry1 = by0 + t / 2, by1 - t / 2
            depth = by1 - by0
            if depth > 9.0:       # a deep block: a back room behind the front one
                split = by0 + depth / 2
                back = _door(rng, rx0, rx1)
                _wall(boxes, rx0, split, rx1, split, t, [back])
                bd = ((back[0] + back[1]) / 2, split)
                if side == "north":
                    _furnish(rng, boxes, (rx0 + t / 2, split + t / 2, rx1 - t / 2, ry1), doors + [bd], t)
                    _furnish(rng, boxes, (rx0 + t / 2, ry0, rx1 - t / 2, split - t / 2), [bd], t)
                else:
                    _furnish(rng, boxes, (rx0 + t / 2, ry0, rx1 - t / 2, split - t / 2), doors + [bd], t)
                    _furnish(rng, boxes, (rx0 + t / 2, split + t / 2, rx1 - t / 2, ry1), [bd], t)
            else:
                _furnish(rng, boxes, (rx0 + t / 2, ry0, rx1 - t / 2, ry1), doors, t)
        _wall(boxes, bx0, wall_y, bx1, wall_y, t, door_gaps)
        corridor_doors += [(wall_y, d) for d in door_gaps]
    if vertical:
        # the vertical corridor's walls, open onto the horizontal corridor
        for x in (xc, xc + cw):
            _wall(boxes, x, 0.0, x, yc, t)
            _wall(boxes, x, yc + cw, x, h, t)
    # pillars half in the corridor walls, clutter against the corridor walls
    for _ in range(int(rng.integers(0, 4))):
        px = float(rng.uniform(1.0, w - 1.0))
        py = yc if rng.random() < 0.5 else yc + cw
        near_door = any(y == py and d0 - 1.2 < px < d1 + 1.2 for y, (d0, d1) in corridor_doors)
        if not (vertical and xc - 1.0 < px < xc + cw + 1.0) and not near_door:
            discs.append((px, py, float(rng.uniform(0.15, 0.25))))
    return boxes, discs, [(0.0, 0.0, w, 0.0), (0.0, h, w, h), (0.0, 0.0, 0.0, h), (w, 0.0, w, h)]


def _warehouse(rng: np.random.Generator, w: float, h: float, t: float
               ) -> tuple[Boxes, list[tuple[float, float, float]], list[tuple[float, float, float, float]]]:
    """A warehouse: rows of racks with aisles and cross aisles, pillars, an office room in a corner,
    pallets along the walls."""
    boxes: Boxes = []
    discs: list[tuple[float, float, float]] = []
    # the office in the south-west corner
    ow, oh = float(rng.uniform(4.0, 7.0)), float(rng.uniform(4.0, 6.0))
    door = _door(rng, 0.0, ow)
    _wall(boxes, 0.0, oh, ow, oh, t, [door])
    _wall(boxes, ow, 0.0, ow, oh, t)
    _furnish(rng, boxes, (t / 2, t / 2, ow - t / 2, oh - t / 2), [((door[0] + door[1]) / 2, oh)], t)
    # racks between x0..x1, y0..y1, rows along x
    margin = float(rng.uniform(2.2, 3.0))
    y = oh + margin
    racks: Boxes = []
    while y + 1.2 < h - margin:
        depth = float(rng.uniform(0.9, 1.3))
        x = margin
        while x < w - margin - 3.0:
            length = min(float(rng.uniform(6.0, 12.0)), w - margin - x)
            racks.append((x + length / 2, y + depth / 2, length / 2, depth / 2, 0.0))
            x += length + float(rng.uniform(2.0, 3.0))       # a cross aisle
        y += depth + float(rng.uniform(2.2, 3.5))            # an aisle
    boxes.extend(racks)
    # pillars on a grid, inside racks or at least 1.2 m clear of them
    step = float(rng.uniform(8.0, 10.0))
    for px in np.arange(step, w - 1.0, step):
        for py in np.arange(step, h - 1.0, step):
            px_, py_ = float(px), float(py)
            inside = any(abs(px_ - cx) < hx - 0.3 and abs(py_ - cy) < hy - 0.3 for cx, cy, hx, hy, _ in racks)
            if (inside or not _blocked(racks + boxes, px_ - 0.3, py_ - 0.3, px_ + 0.3, py_ + 0.3, DOOR_MIN + 0.3)) \
                    and not (px_ < ow + 1.5 and py_ < oh + 1.5):
                discs.append((px_, py_, 0.3))
    # pallets against the outer walls
    for _ in range(int(rng.integers(3, 9))):
        pw, pd = float(rng.uniform(0.8, 1.2)), float(rng.uniform(0.8, 1.2))
        side = int(rng.integers(4))
        along = float(rng.uniform(1.0, (w if side < 2 else h) - 1.0))
        cx, cy = {0: (along, pd / 2), 1: (along, h - pd / 2), 2: (pd / 2, along), 3: (w - pd / 2, along)}[side]
        if not _blocked(boxes, cx - pw / 2, cy - pd / 2, cx + pw / 2, cy + pd / 2, DOOR_MIN + 0.1) and \
                not _blocked([(cx_, cy_, r, r, 0.0) for cx_, cy_, r in discs], cx - pw / 2, cy - pd / 2,
                             cx + pw / 2, cy + pd / 2, DOOR_MIN + 0.1):
            boxes.append((cx, cy, pw / 2, pd / 2, 0.0))
    return boxes, discs, [(0.0, 0.0, w, 0.0), (0.0, h, w, h), (0.0, 0.0, 0.0, h), (w, 0.0, w, h)]


def _cave(rng: np.random.Generator, w: float, h: float) -> npt.NDArray[np.bool_]:
    """Rock (True) on a grid of CELL over w x h [m]: a cellular automaton on 0.25 m blocks, passages
    narrower than DOOR_MIN removed (an opening of the free space), the largest free region kept."""
    from robotexp.mapping.kernels import edt_sq, label8

    block = 5                                    # cells per 0.25 m block
    bc, br = int(round(w / CELL)) // block, int(round(h / CELL)) // block
    rock = rng.random((br, bc)) < 0.42
    for _ in range(5):                           # 4-5 rule: rock where 5 of the 9 around are rock
        padded = np.pad(rock, 1, constant_values=True).astype(np.int8)
        around = sum(padded[1 + dr:1 + dr + br, 1 + dc:1 + dc + bc] for dr in (-1, 0, 1) for dc in (-1, 0, 1))
        rock = np.asarray(around >= 5)
    rock[0, :] = rock[-1, :] = rock[:, 0] = rock[:, -1] = True
    fine = np.kron(rock, np.ones((block, block), dtype=bool))
    # the robot's centre space: cells farther than DOOR_MIN/2 from rock; its largest 8-connected part,
    # grown back by DOOR_MIN/2, is the cave (passages narrower than DOOR_MIN and pockets cut off)
    radius_sq = (DOOR_MIN / 2 / CELL) ** 2
    centres = edt_sq(fine) > radius_sq
    labels, n = label8(np.ascontiguousarray(centres))
    if n == 0:
        return np.ones_like(fine)
    sizes = np.bincount(labels.ravel())
    sizes[0] = 0
    keep = labels == int(np.argmax(sizes))
    free = (edt_sq(np.ascontiguousarray(keep)) <= radius_sq) & ~fine
    out: npt.NDArray[np.bool_] = ~free
    return out


def generate_grid(kind: str, seed: int, size: tuple[float, float] | None = None, *, scanned: bool = False
                  ) -> tuple[npt.NDArray[np.int8], GridGeometry]:
    """The occupancy grid of the generated world `kind` number `seed`.

    Args:
        kind: one of KINDS.
        seed: >= 0; the same seed gives the same grid.
        size: (width, height) [m] of the building, each in [MIN_SIZE, MAX_SIZE]; default DEFAULT_SIZES.
        scanned: add the artefacts of laser-built maps (see the module).

    Returns:
        (values, geo): int8 (rows, cols) 0 free, 100 occupied, -1 unknown, row 0 the bottom; cells of
        CELL with the building's south-west corner at (0, 0).

    Raises:
        ConfigError: unknown kind, negative seed, size out of range.
    """
    if kind not in KINDS:
        raise ConfigError(f"generated world: unknown kind {kind!r}, expected one of {', '.join(KINDS)}")
    if not (isinstance(seed, int) and 0 <= seed < 2**63):
        raise ConfigError(f"generated world: seed {seed!r}, expected a whole number >= 0")
    w, h = size if size is not None else DEFAULT_SIZES[kind]
    if not (MIN_SIZE <= w <= MAX_SIZE and MIN_SIZE <= h <= MAX_SIZE):
        raise ConfigError(f"generated world: size {w:g} x {h:g} m, expected each side in "
                          f"{MIN_SIZE:g}..{MAX_SIZE:g} m")
    w, h = round(w / CELL) * CELL, round(h / CELL) * CELL
    if kind == "building":        # laser-like already: `scanned` changes nothing
        from robotexp.world.building import generate_building

        values, geo, _ = generate_building(np.random.default_rng([seed, KINDS.index(kind)]), w, h)
        return values, geo
    rng = np.random.default_rng([seed, KINDS.index(kind), int(scanned)])
    pad = _OUTSIDE if scanned else 0.5
    geo = GridGeometry.covering(-pad, -pad, w + pad, h + pad, CELL)
    check_grid_size(geo.width, geo.height, CELL, "generated world")
    t = 0.1
    if kind == "cave":
        rock = _cave(rng, w, h)
        occ = np.zeros((geo.rows, geo.cols), dtype=bool)
        r0, c0 = geo.cell_of(CELL / 2, CELL / 2)
        occ[r0:r0 + rock.shape[0], c0:c0 + rock.shape[1]] = rock
        occ[r0 + rock.shape[0]:, :] = False
        inside = np.zeros_like(occ)
        inside[r0:r0 + rock.shape[0], c0:c0 + rock.shape[1]] = True
        outer: list[tuple[float, float, float, float]] = []
    else:
        from robotexp.world.groundtruth import occupancy

        boxes, discs, outer = (_office if kind == "office" else _warehouse)(rng, w, h, t)
        gaps: list[list[tuple[float, float]]] = [[] for _ in outer]
        if scanned:
            for _ in range(int(rng.integers(1, 4))):
                side = int(rng.integers(4))
                x0, y0, x1, y1 = outer[side]
                length = max(x1 - x0, y1 - y0)
                gaps[side].append(_door(rng, 0.5, length - 0.5))
        for (x0, y0, x1, y1), g in zip(outer, gaps, strict=True):
            _wall(boxes, x0, y0, x1, y1, 0.15, g)
        if scanned:         # one wall in five one cell thin
            thin = rng.random(len(boxes)) < 0.2
            boxes = [(cx, cy, hx if hx > hy or not th else CELL / 2, hy if hy > hx or not th else CELL / 2, yaw)
                     for (cx, cy, hx, hy, yaw), th in zip(boxes, thin, strict=True)]
        occ = occupancy(World("plan", np.array(boxes).reshape(-1, 5), np.array(discs).reshape(-1, 3)), geo)
        inside = np.zeros_like(occ)
        ri0, ci0 = geo.cell_of(0.0, 0.0)
        ri1, ci1 = geo.cell_of(w, h)
        inside[ri0:ri1 + 1, ci0:ci1 + 1] = True
    values = np.where(occ, 100, 0).astype(np.int8)
    if scanned:
        values = _scan_artefacts(rng, values, occ, inside, kind)
    return values, geo


def _scan_artefacts(rng: np.random.Generator, values: npt.NDArray[np.int8], occ: npt.NDArray[np.bool_],
                    inside: npt.NDArray[np.bool_], kind: str) -> npt.NDArray[np.int8]:
    """Breaks in walls (2-4 cells: a laser passes, a robot does not), free space seen outside the
    building within 1.5-3 m of it, unknown beyond and in unseen pockets."""
    from robotexp.mapping.kernels import edt_sq

    out = values.copy()
    walls = np.argwhere(occ & inside)
    if len(walls):
        for r, c in walls[rng.choice(len(walls), size=min(len(walls), 12), replace=False)]:
            k = int(rng.integers(2, 5))
            if rng.random() < 0.5:
                out[r:r + 1, c:c + k] = 0
            else:
                out[r:r + k, c:c + 1] = 0
    # outside: free within a seen band (distance to the building < U(1.5, 3) m), unknown beyond
    dist = np.sqrt(edt_sq(np.ascontiguousarray(inside))) * CELL
    band = float(rng.uniform(1.5, _OUTSIDE))
    out[~inside & (dist >= band)] = -1
    out[~inside & (dist < band)] = 0
    # a few unknown blotches inside (spots the scanner never saw), never on a wall
    rows, cols = out.shape
    for _ in range(int(rng.integers(0, 4))):
        r, c = int(rng.integers(rows)), int(rng.integers(cols))
        rad = int(rng.integers(4, 12))
        yy, xx = np.ogrid[:rows, :cols]
        spot = ((yy - r) ** 2 + (xx - c) ** 2 <= rad * rad) & (out == 0) & inside
        out[spot] = -1
    return out


def generated_world(kind: str, seed: int, size: tuple[float, float] | None = None, *, scanned: bool = False
                    ) -> World:
    """The generated world as a `World` (the grid as `load_ros_world` would load its `.yaml`)."""
    from robotexp.world.rosmap import world_from_grid

    values, geo = generate_grid(kind, seed, size, scanned=scanned)
    name = f"{kind}-{seed}" + ("-scanned" if scanned else "")
    w, h = size if size is not None else DEFAULT_SIZES[kind]
    world = world_from_grid(values, geo, name=name, source=f"generated:{kind}:{seed}",
                            what=f"generated {kind} {w:g} x {h:g} m, seed {seed}" + (", scanned" if scanned else ""))
    return world


def parse_generated(spec: str) -> tuple[str, list[int], tuple[float, float] | None, bool]:
    """(kind, seeds, size, scanned) of `generated:KIND:SEED[-LAST][:WxH][:scanned]`.

    Raises:
        WorldError: a malformed spec (says the form).
    """
    form = "expected 'generated:KIND:SEED' (or SEED-LAST, then optionally ':WxH' in m and ':scanned')"
    m = _SPEC.fullmatch(spec.strip())
    if not m:
        raise WorldError(f"world {spec!r}: {form}, KIND one of {', '.join(KINDS)}")
    kind, first, last, opts = m.group(1), int(m.group(2)), m.group(3), m.group(4)
    if kind not in KINDS:
        raise WorldError(f"world {spec!r}: unknown kind {kind!r}, expected one of {', '.join(KINDS)}")
    stop = int(last) if last is not None else first
    if stop < first or stop - first >= 100_000:
        raise WorldError(f"world {spec!r}: seed range {first}-{stop} is empty or too long, {form}")
    size: tuple[float, float] | None = None
    scanned = False
    for opt in filter(None, opts.split(":")):
        if opt == "scanned":
            scanned = True
        elif re.fullmatch(r"\d+(?:\.\d+)?x\d+(?:\.\d+)?", opt):
            a, b = opt.split("x")
            size = (float(a), float(b))
        else:
            raise WorldError(f"world {spec!r}: unknown option {opt!r}, {form}")
    return kind, list(range(first, stop + 1)), size, scanned


def expand_generated(spec: str) -> list[str]:
    """`generated:office:0-2:scanned` -> the names of the single worlds (`generated:office:0:scanned`, ...);
    any other name -> [spec]."""
    if not spec.startswith("generated:"):
        return [spec]
    kind, seeds, _, _ = parse_generated(spec)
    rest = spec.strip().split(":", 3)[3] if spec.strip().count(":") >= 3 else ""
    return [f"generated:{kind}:{s}" + (f":{rest}" if rest else "") for s in seeds]


def write_generated(path: str | os.PathLike[str], kind: str, seed: int, size: tuple[float, float] | None = None,
                    *, scanned: bool = False) -> list[Path]:
    """Write the generated world as a ROS map (`.yaml` + `.pgm` beside it) or an ARIA `.map`, making the
    folders of `path` that do not exist yet.

    Returns:
        The files written.

    Raises:
        ConfigError: an unknown suffix, or as `generate_grid`.
        WorldError: a file cannot be written.
    """
    from robotexp.world.rosmap import save_ros_map

    out = Path(path)
    suffix = out.suffix.lower()
    if suffix not in (".yaml", ".yml", ".map"):
        raise ConfigError(f"{out}: unknown map format {suffix or '(none)'!r}, expected FILE.yaml (ROS map_server) "
                          "or FILE.map (ARIA)")
    values, geo = generate_grid(kind, seed, size, scanned=scanned)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)     # the folders the path names, as explore --out makes
    except OSError as exc:
        raise WorldError(f"{out}: cannot make its folder {out.parent} ({exc.strerror or exc}); give a path in "
                         "a folder you can create and write") from exc
    if suffix != ".map":
        save_ros_map(out, values, geo)
        return [out, out.with_name(out.stem + ".pgm")]
    occ = values >= 50
    padded = np.pad(occ, 1, constant_values=False)
    rows, cols = occ.shape
    solid = np.ones_like(occ)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            solid &= padded[1 + dr:1 + dr + rows, 1 + dc:1 + dc + cols]
    rc = np.argwhere(occ & ~solid)            # a point map holds the surfaces a laser saw, not the rock
    mm = np.rint(geo.centers_of(rc) * 1000).astype(np.int64)
    x0, y0 = round(geo.origin_x * 1000), round(geo.origin_y * 1000)
    x1, y1 = round((geo.origin_x + geo.width) * 1000), round((geo.origin_y + geo.height) * 1000)
    head = (f"2D-Map\nMinPos: {x0} {y0}\nMaxPos: {x1} {y1}\nNumPoints: {len(mm)}\nPointsAreSorted: false\n"
            f"Resolution: {round(CELL * 1000)}\nDATA\n")
    try:
        out.write_text(head + "".join(f"{x} {y}\n" for x, y in mm.tolist()), encoding="ascii")
    except OSError as exc:
        raise WorldError(f"{out}: cannot write the map ({exc.strerror or exc}), expected a writable folder") from exc
    return [out]
