"""Load ARIA / MobileSim `.map` files (ArMap format, docs/maps-format.md §1) as a `World`.

A `.map` file is text: a `2D-Map...` intro line, metadata lines (`Key: values`, among them the
`Cairn:` map objects), then `LINES` / `DATA` sections (and `<Sensor>_LINES` / `<Sensor>_DATA` in
`2D-Map-Ex` maps) of integer coordinates in millimetres. Lines become thin wall boxes, points
become square boxes of the map's `Resolution` (runs of points one resolution apart merged into one
rectangle: a laser-built map of 60 k points is a few thousand boxes), `RobotHome` / `Goal` /
`GoalWithHeading` / `Dock` cairns become named start poses.

A malformed data line is skipped with a warning naming `file:line`, as ARIA does (maps made by
other tools have them). Everything else is strict, because a silently broken map is worse than a
refused one in an experiment tool: a cairn whose type or pose cannot be parsed, a metadata line
after the first data section, a map without any obstacle, and a `RobotHome` outside the map's
obstacles raise `WorldError` naming `file:line` (other pose cairns outside are dropped with a
warning). Text is read as UTF-8 (with or without BOM); a file that is not UTF-8 is read as
Latin-1 (older ARIA tools wrote labels in the local 8-bit code page), and a file with control
bytes other than tab, CR and LF is refused as binary.
"""

from __future__ import annotations

import logging
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError, WorldError
from robotexp.robot import Pose, wrap_angle
from robotexp.world.model import World

__all__ = ["DEFAULT_RESOLUTION_MM", "DEFAULT_THICKNESS", "load_mobilesim"]

log = logging.getLogger(__name__)

DEFAULT_RESOLUTION_MM = 20      # [mm] side of a DATA point box when the map has no Resolution
DEFAULT_THICKNESS = 0.02        # [m] thickness of a LINES wall box

# Cairn types that become start poses, with the name given to unlabelled ones.
_POSE_TYPES = {"RobotHome": "home", "Goal": "goal", "GoalWithHeading": "goal", "Dock": "dock"}
_IGNORED_TYPES = ("ForbiddenLine", "ForbiddenArea")   # robot-software rules, not obstacles

_SECTION = re.compile(r"(?:(\S+)_)?(DATA|LINES)")
_POINT = re.compile(r"[+-]?\d{1,9}[ \t]+[+-]?\d{1,9}", re.ASCII)
_LINE = re.compile(r"[+-]?\d{1,9}[ \t]+[+-]?\d{1,9}[ \t]+[+-]?\d{1,9}[ \t]+[+-]?\d{1,9}", re.ASCII)
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?", re.ASCII)
_TOKEN = re.compile(r'"([^"]*)"|(\S+)')
_BINARY = re.compile(rb"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")
_MAX_MM = 1e9                   # [mm] 1000 km: larger coordinates are a corrupted file
_MAX_WARNINGS = 10              # malformed data lines named one by one, then counted
_DECLARED = ("MinPos", "MaxPos", "LineMinPos", "LineMaxPos")


@dataclass
class _Section:
    """The data lines of one `LINES`/`DATA` section kind, with their 1-based line numbers."""

    texts: list[str] = field(default_factory=list)
    numbers: list[int] = field(default_factory=list)


def load_mobilesim(path: str | os.PathLike[str], *, thickness: float = DEFAULT_THICKNESS) -> World:
    """Load an ARIA / MobileSim `.map` file as a `World` in metres.

    Every `LINES` / `<Sensor>_LINES` segment becomes a wall box of `thickness` (see
    `segment_box`), every `DATA` / `<Sensor>_DATA` point a square box of the map's `Resolution`
    (20 mm when absent) centred on it (duplicate points give one box). `RobotHome`, `Goal`,
    `GoalWithHeading` and `Dock` cairns become `poses` named by their label (unlabelled ones
    "home", "home2", "goal", ...; a repeated label gets 2, 3, ... appended); the first
    `RobotHome` is also `home`; goal positions in file order are `goals["cairns"]`.
    `ForbiddenLine` / `ForbiddenArea` and other cairn types are counted in `description` only.
    `bounds` cover every obstacle; a pose cairn outside them is dropped with a warning, a
    `RobotHome` outside them refuses the map. Header bounds (`MinPos`/`MaxPos`,
    `LineMinPos`/`LineMaxPos`) are kept as `World.declared` (the union of those present).
    Malformed data lines are skipped with a warning naming `file:line`.

    Args:
        path: the `.map` file.
        thickness: [m] thickness of the wall boxes made from line segments, > 0.

    Returns:
        The world; `name` is the file stem, `source` the path.

    Raises:
        WorldError: the file cannot be read, is binary, does not start with `2D-Map`, has a
            malformed `Resolution:`, `*Pos:` or `Cairn:` line, a `RobotHome` outside its
            obstacles, or has no obstacle at all. The message starts with `file:line:`.
        ConfigError: `thickness` is not a positive finite number.
    """
    if not (math.isfinite(thickness) and thickness > 0):
        raise ConfigError(f"load_mobilesim: thickness must be a positive number [m], got {thickness}")
    src = str(path)
    lines = _read_lines(Path(path), src)
    if not lines or not lines[0].strip().lower().startswith("2d-map"):
        got = lines[0].strip()[:40] if lines else ""
        raise WorldError(f"{src}:1: not an ARIA map file (first line {got!r}), expected a first "
                         "line starting with '2D-Map' (2D-Map, 2D-Map-Ex2, ...)")
    intro = lines[0].strip()[:40]

    resolution_mm = float(DEFAULT_RESOLUTION_MM)
    sources: list[str] = []
    cairns: list[tuple[int, str]] = []
    declared: dict[str, tuple[float, float]] = {}
    sections = {"LINES": _Section(), "DATA": _Section()}
    current: _Section | None = None
    for number, raw in enumerate(lines[1:], start=2):
        text = raw.strip()
        if not text:
            continue
        if text[-1] in "AS":
            match = _SECTION.fullmatch(text)
            if match:
                current = sections[match.group(2)]
                continue
        if current is not None:
            current.texts.append(text)
            current.numbers.append(number)
            continue
        key, colon, rest = text.partition(":")
        if not colon:
            continue                      # ARIA keeps unknown metadata verbatim; we ignore it
        if key == "Cairn":
            cairns.append((number, rest))
        elif key == "Resolution":
            resolution_mm = _resolution(rest, src, number)
        elif key == "Sources":
            sources = rest.split()
        elif key in _DECLARED:
            declared[key] = _position(rest, key, src, number)

    segments, bad_lines = _parse_ints(sections["LINES"], _LINE, 4, src, "x1 y1 x2 y2")
    points, bad_points = _parse_ints(sections["DATA"], _POINT, 2, src, "x y")
    n_lines, n_points = len(segments), len(points)
    point_boxes = _point_boxes(_unique_points(points), resolution_mm)
    boxes = np.concatenate([_segment_boxes(segments / 1000.0, thickness), point_boxes])
    if len(boxes) == 0:
        raise WorldError(f"{src}:{len(lines)}: the map has no obstacle (no valid LINES or DATA entry), "
                         "expected at least one line segment or point")

    bounds = _bounds(boxes)
    poses, goals, home, counts = _cairn_poses(cairns, src, bounds)
    world = World(name=Path(path).stem, boxes=boxes, source=src, home=home, poses=poses,
                  goals={"cairns": goals} if goals else {}, bounds=bounds, collision="index",
                  declared=_declared(declared))
    ignored = ", ".join(f"{counts.get(t, 0)} {t}" for t in _IGNORED_TYPES)
    other = sum(v for t, v in counts.items() if t not in _POSE_TYPES and t not in _IGNORED_TYPES)
    skipped = bad_lines + bad_points
    world.description = (
        f"{intro} map {Path(path).name}: {n_lines} lines, {n_points} points ({len(point_boxes)} boxes), "
        f"resolution {resolution_mm:g} mm, {len(cairns)} cairns ({len(poses)} poses; ignored: "
        f"{ignored}, {other} of other types)" + (f"; sources {' '.join(sources)}" if sources else "")
        + (f"; {skipped} malformed data lines skipped" if skipped else ""))
    log.debug("loaded %s", world.description)
    return world


def _read_lines(path: Path, src: str) -> list[str]:
    """The file's lines (CRLF, CR or LF endings), decoded; WorldError when unreadable or binary."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise WorldError(f"{src}:0: cannot read the map file ({exc.strerror or exc}), "
                         "expected a readable ARIA .map file") from exc
    binary = _BINARY.search(data)
    if binary:
        line = data.count(b"\n", 0, binary.start()) + 1
        raise WorldError(f"{src}:{line}: binary byte 0x{data[binary.start()]:02x} in the file, "
                         "expected a text ARIA .map file")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        log.warning("%s:%d: not UTF-8 (byte 0x%02x), reading the map as Latin-1",
                    src, line, data[exc.start])
        text = data.decode("latin-1")
    return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")


def _resolution(rest: str, src: str, number: int) -> float:
    """[mm] the value of a `Resolution:` line; <= 0 (ARIA's -1 means unset) gives the default."""
    value = rest.strip()
    if not _NUMBER.fullmatch(value) or not math.isfinite(float(value)) or float(value) > _MAX_MM:
        raise WorldError(f"{src}:{number}: bad Resolution {value[:40]!r}, expected a number of mm "
                         "(e.g. 'Resolution: 20')")
    res = float(value)
    return res if res > 0 else float(DEFAULT_RESOLUTION_MM)


def _parse_ints(section: _Section, pattern: re.Pattern[str], width: int, src: str, what: str
                ) -> tuple[npt.NDArray[np.float64], int]:
    """The (n, width) float64 [mm] array of a section's well-formed integer lines, and how many
    malformed lines were skipped (each logged as a warning naming `file:line`, as ARIA does; past
    `_MAX_WARNINGS`, one summary line)."""
    texts = section.texts
    match = pattern.fullmatch
    bad = [i for i, text in enumerate(texts) if match(text) is None]
    for i in bad[:_MAX_WARNINGS]:
        hint = ""
        if ":" in texts[i]:
            hint = " (metadata such as Cairn: must come before the first DATA/LINES section)"
        log.warning("%s:%d: skipped malformed data line %r%s, expected %d integers '%s' [mm] of at most 9 "
                    "digits (1000 km)", src, section.numbers[i], texts[i][:60], hint, width, what)
    if len(bad) > _MAX_WARNINGS:
        log.warning("%s: %d more malformed data lines skipped", src, len(bad) - _MAX_WARNINGS)
    if bad:
        skip = set(bad)
        texts = [text for i, text in enumerate(texts) if i not in skip]
    if not texts:
        return np.zeros((0, width)), len(bad)
    flat = np.array(" ".join(texts).split(), dtype=np.int64)
    return flat.reshape(-1, width).astype(np.float64), len(bad)


def _segment_boxes(seg: npt.NDArray[np.float64], thickness: float) -> npt.NDArray[np.float64]:
    """Vectorised `segment_box` over (n, 4) segments [m]: (n, 5) boxes [cx, cy, hx, hy, yaw]."""
    dx = seg[:, 2] - seg[:, 0]
    dy = seg[:, 3] - seg[:, 1]
    length = np.hypot(dx, dy)
    yaw = np.where(length > 0, np.arctan2(dy, dx), 0.0)
    half_t = np.full(len(seg), thickness / 2)
    return np.column_stack([(seg[:, 0] + seg[:, 2]) / 2, (seg[:, 1] + seg[:, 3]) / 2,
                            length / 2 + thickness / 2, half_t, yaw])


def _point_boxes(pts: npt.NDArray[np.float64], side_mm: float) -> npt.NDArray[np.float64]:
    """(k, 5) axis-aligned boxes [m] covering the squares of `side_mm` centred on the distinct (n, 2)
    integer points [mm]: points one side apart along x are merged into runs, and equal runs in rows
    one side apart into rectangles (their union is exactly the union of the squares)."""
    if len(pts) == 0:
        return np.zeros((0, 5))
    x, y = pts[:, 0], pts[:, 1]
    order = np.lexsort((x, y))
    x, y = x[order], y[order]
    new_run = np.ones(len(x), dtype=bool)
    new_run[1:] = (y[1:] != y[:-1]) | (x[1:] - x[:-1] != side_mm)
    first = np.flatnonzero(new_run)
    last = np.append(first[1:], len(x)) - 1
    rx0, rx1, ry = x[first], x[last], y[first]
    order = np.lexsort((ry, rx1, rx0))
    rx0, rx1, ry = rx0[order], rx1[order], ry[order]
    new_box = np.ones(len(ry), dtype=bool)
    new_box[1:] = (rx0[1:] != rx0[:-1]) | (rx1[1:] != rx1[:-1]) | (ry[1:] - ry[:-1] != side_mm)
    first = np.flatnonzero(new_box)
    last = np.append(first[1:], len(ry)) - 1
    x0, x1, y0, y1 = rx0[first], rx1[first], ry[first], ry[last]
    return np.column_stack([(x0 + x1) / 2000.0, (y0 + y1) / 2000.0, (x1 - x0 + side_mm) / 2000.0,
                            (y1 - y0 + side_mm) / 2000.0, np.zeros(len(x0))])


def _cairn_poses(cairns: list[tuple[int, str]], src: str, bounds: tuple[float, float, float, float]
                 ) -> tuple[dict[str, Pose], list[tuple[float, float]], Pose | None, dict[str, int]]:
    """Poses by unique name, goal positions [m], the first RobotHome, and a count per type.

    A pose cairn outside `bounds` [m] (the obstacles' box) is dropped with a warning; a RobotHome
    there raises WorldError (the robot would start outside the building)."""
    poses: dict[str, Pose] = {}
    goals: list[tuple[float, float]] = []
    home: Pose | None = None
    counts: dict[str, int] = {}
    for number, rest in cairns:
        kind, x_mm, y_mm, theta_deg, label = _parse_cairn(rest, src, number)
        counts[kind] = counts.get(kind, 0) + 1
        if kind not in _POSE_TYPES:
            continue
        theta = 0.0 if kind == "Goal" else wrap_angle(math.radians(theta_deg))
        pose = Pose(x_mm / 1000.0, y_mm / 1000.0, theta)
        xmin, ymin, xmax, ymax = bounds
        if not (xmin <= pose.x <= xmax and ymin <= pose.y <= ymax):
            where = (f"{src}:{number}: {kind} ({x_mm:g}, {y_mm:g}) mm lies outside the map's obstacles "
                     f"(x {xmin * 1000:.0f}..{xmax * 1000:.0f}, y {ymin * 1000:.0f}..{ymax * 1000:.0f} mm)")
            if kind == "RobotHome":
                raise WorldError(f"{where}, expected a home inside the map (move the cairn or remove it)")
            log.warning("%s; dropped", where)
            continue
        base = label or _POSE_TYPES[kind]
        name, k = base, 2
        while name in poses:
            name, k = f"{base}{k}", k + 1
        poses[name] = pose
        if kind == "RobotHome" and home is None:
            home = pose
        if kind in ("Goal", "GoalWithHeading"):
            goals.append((pose.x, pose.y))
    return poses, goals, home, counts


def _parse_cairn(rest: str, src: str, number: int) -> tuple[str, float, float, float, str]:
    """(type, x [mm], y [mm], theta [deg], label) of `Cairn: Type X Y Th "" ICON "Label" ...`."""
    expected = 'expected \'Cairn: Type X Y Theta "" ICON "Label"\' with X, Y [mm] and Theta [deg]'
    if rest.count('"') % 2:
        raise WorldError(f"{src}:{number}: unbalanced quote in cairn {rest.strip()[:60]!r}, {expected}")
    tokens = [(m.group(1), True) if m.group(1) is not None else (m.group(2), False)
              for m in _TOKEN.finditer(rest)]
    if len(tokens) < 4 or tokens[0][1]:
        raise WorldError(f"{src}:{number}: incomplete cairn {rest.strip()[:60]!r}, {expected}")
    values: list[float] = []
    for (text, quoted), what in zip(tokens[1:4], ("X", "Y", "Theta"), strict=True):
        limit = _MAX_MM if what != "Theta" else 1e6
        if quoted or not _NUMBER.fullmatch(text) or not abs(float(text)) <= limit:
            raise WorldError(f"{src}:{number}: bad cairn {what} {text[:30]!r}, {expected}")
        values.append(float(text))
    label = tokens[6][0] if len(tokens) > 6 else ""
    return tokens[0][0], values[0], values[1], values[2], label


def _unique_points(points: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """The (n, 2) integer-valued points [mm] without repeats, in order of first appearance."""
    if len(points) == 0:
        return points
    # |coordinate| <= _MAX_MM < 2**30, so one int64 key per point is exact and sorts fast
    shifted = points.astype(np.int64) + int(_MAX_MM)
    _, first = np.unique(shifted[:, 0] * 2**31 + shifted[:, 1], return_index=True)
    unique: npt.NDArray[np.float64] = points[np.sort(first)]
    return unique


def _bounds(boxes: npt.NDArray[np.float64]) -> tuple[float, float, float, float]:
    """[m] (xmin, ymin, xmax, ymax) around the (n, 5) boxes.

    A vectorised `World.obstacle_bounds` (which loops in Python: 0.4 s for 100k boxes).
    """
    cx, cy, hx, hy, yaw = boxes.T
    ex = np.abs(hx * np.cos(yaw)) + np.abs(hy * np.sin(yaw))
    ey = np.abs(hx * np.sin(yaw)) + np.abs(hy * np.cos(yaw))
    return (float(np.min(cx - ex)), float(np.min(cy - ey)), float(np.max(cx + ex)), float(np.max(cy + ey)))


def _position(rest: str, key: str, src: str, number: int) -> tuple[float, float]:
    """(x, y) [mm] of a `MinPos: X Y`-style header line; WorldError when malformed."""
    parts = rest.split()
    if (len(parts) != 2 or not all(_NUMBER.fullmatch(p) for p in parts)
            or not all(abs(float(p)) <= _MAX_MM for p in parts)):
        raise WorldError(f"{src}:{number}: bad {key} {rest.strip()[:40]!r}, expected two numbers "
                         f"'X Y' [mm] within +-{_MAX_MM:g}")
    return float(parts[0]), float(parts[1])


def _declared(declared: dict[str, tuple[float, float]]) -> tuple[float, float, float, float] | None:
    """[m] the union of the header's MinPos..MaxPos and LineMinPos..LineMaxPos boxes (those given in
    full and not inverted), or None."""
    boxes = [(declared[lo], declared[hi]) for lo, hi in (("MinPos", "MaxPos"), ("LineMinPos", "LineMaxPos"))
             if lo in declared and hi in declared and declared[lo][0] <= declared[hi][0]
             and declared[lo][1] <= declared[hi][1]]
    if not boxes:
        return None
    return (min(b[0][0] for b in boxes) / 1000.0, min(b[0][1] for b in boxes) / 1000.0,
            max(b[1][0] for b in boxes) / 1000.0, max(b[1][1] for b in boxes) / 1000.0)
