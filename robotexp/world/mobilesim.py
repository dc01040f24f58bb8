"""Load ARIA / MobileSim `.map` files (ArMap format, `formats/maps.md` §1) as a `World`.

A `.map` file is text: a `2D-Map...` intro line, metadata lines (`Key: values`, among them the
`Cairn:` map objects), then `LINES` / `DATA` sections (and `<Sensor>_LINES` / `<Sensor>_DATA` in
`2D-Map-Ex` maps) of integer coordinates in millimetres. Lines become thin wall boxes, points
become small square boxes of the map's `Resolution`, `RobotHome` / `Goal` / `GoalWithHeading` /
`Dock` cairns become named start poses.

Where ARIA is lenient we are strict, because a silently broken map is worse than a refused one
in an experiment tool: a malformed data line (ARIA skips and logs it), a cairn whose type or pose
cannot be parsed, a metadata line after the first data section, and a map without any obstacle
all raise `WorldError` naming `file:line`. Text is read as UTF-8 (with or without BOM); a file
that is not UTF-8 is read as Latin-1 (older ARIA tools wrote labels in the local 8-bit code
page), and a file with control bytes other than tab, CR and LF is refused as binary.
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

__all__ = ["DEFAULT_RESOLUTION_MM", "DEFAULT_THICKNESS", "POSE_ROOM", "load_mobilesim"]

log = logging.getLogger(__name__)

DEFAULT_RESOLUTION_MM = 20      # [mm] side of a DATA point box when the map has no Resolution
DEFAULT_THICKNESS = 0.02        # [m] thickness of a LINES wall box
POSE_ROOM = 0.5                 # [m] half side of the square around each cairn kept in the bounds

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
    `bounds` cover every obstacle and a square of +-`POSE_ROOM` around each pose; header
    bounds (`MinPos`, `LineMinPos`, ...) are advisory and not used.

    Args:
        path: the `.map` file.
        thickness: [m] thickness of the wall boxes made from line segments, > 0.

    Returns:
        The world; `name` is the file stem, `source` the path.

    Raises:
        WorldError: the file cannot be read, is binary, does not start with `2D-Map`, has a
            malformed data, `Resolution:` or `Cairn:` line, or has no obstacle at all. The
            message starts with `file:line:`.
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

    segments = _parse_ints(sections["LINES"], _LINE, 4, src, "x1 y1 x2 y2")
    points = _parse_ints(sections["DATA"], _POINT, 2, src, "x y")
    n_lines, n_points = len(segments), len(points)
    boxes = np.concatenate([_segment_boxes(segments / 1000.0, thickness),
                            _point_boxes(_unique_points(points) / 1000.0, resolution_mm / 1000.0)])
    if len(boxes) == 0:
        raise WorldError(f"{src}:{len(lines)}: the map has no obstacle (no LINES or DATA entry), "
                         "expected at least one line segment or point")

    poses, goals, home, counts = _cairn_poses(cairns, src)
    world = World(name=Path(path).stem, boxes=boxes, source=src, home=home, poses=poses,
                  goals={"cairns": goals} if goals else {},
                  bounds=_bounds(boxes, list(poses.values())))
    ignored = ", ".join(f"{counts.get(t, 0)} {t}" for t in _IGNORED_TYPES)
    other = sum(v for t, v in counts.items() if t not in _POSE_TYPES and t not in _IGNORED_TYPES)
    world.description = (
        f"{intro} map {Path(path).name}: {n_lines} lines, {n_points} points, "
        f"resolution {resolution_mm:g} mm, {len(cairns)} cairns ({len(poses)} poses; ignored: "
        f"{ignored}, {other} of other types)" + (f"; sources {' '.join(sources)}" if sources else ""))
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
                ) -> npt.NDArray[np.float64]:
    """The (n, width) float64 [mm] array of a section's integer lines; WorldError on a bad one."""
    texts = section.texts
    match = pattern.fullmatch
    bad = [i for i, text in enumerate(texts) if match(text) is None]
    if bad:
        i = bad[0]
        hint = ""
        if ":" in texts[i]:
            hint = " (metadata such as Cairn: must come before the first DATA/LINES section)"
        raise WorldError(f"{src}:{section.numbers[i]}: bad data line {texts[i][:60]!r}{hint}, "
                         f"expected {width} integers '{what}' [mm]"
                         + (f"; {len(bad)} bad lines in all" if len(bad) > 1 else ""))
    if not texts:
        return np.zeros((0, width))
    flat = np.array(" ".join(texts).split(), dtype=np.int64)
    return flat.reshape(-1, width).astype(np.float64)


def _segment_boxes(seg: npt.NDArray[np.float64], thickness: float) -> npt.NDArray[np.float64]:
    """Vectorised `segment_box` over (n, 4) segments [m]: (n, 5) boxes [cx, cy, hx, hy, yaw]."""
    dx = seg[:, 2] - seg[:, 0]
    dy = seg[:, 3] - seg[:, 1]
    length = np.hypot(dx, dy)
    yaw = np.where(length > 0, np.arctan2(dy, dx), 0.0)
    half_t = np.full(len(seg), thickness / 2)
    return np.column_stack([(seg[:, 0] + seg[:, 2]) / 2, (seg[:, 1] + seg[:, 3]) / 2,
                            length / 2 + thickness / 2, half_t, yaw])


def _point_boxes(pts: npt.NDArray[np.float64], side: float) -> npt.NDArray[np.float64]:
    """(n, 5) axis-aligned square boxes of `side` [m] centred on the (n, 2) points [m]."""
    half = np.full(len(pts), side / 2)
    return np.column_stack([pts[:, 0], pts[:, 1], half, half, np.zeros(len(pts))])


def _cairn_poses(cairns: list[tuple[int, str]], src: str
                 ) -> tuple[dict[str, Pose], list[tuple[float, float]], Pose | None, dict[str, int]]:
    """Poses by unique name, goal positions [m], the first RobotHome, and a count per type."""
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


def _bounds(boxes: npt.NDArray[np.float64], poses: list[Pose]) -> tuple[float, float, float, float]:
    """[m] (xmin, ymin, xmax, ymax) around the (n, 5) boxes and +-POSE_ROOM around each pose.

    A vectorised `World.obstacle_bounds` (which loops in Python: 0.4 s for 100k boxes).
    """
    cx, cy, hx, hy, yaw = boxes.T
    ex = np.abs(hx * np.cos(yaw)) + np.abs(hy * np.sin(yaw))
    ey = np.abs(hx * np.sin(yaw)) + np.abs(hy * np.cos(yaw))
    xmin, ymin = float(np.min(cx - ex)), float(np.min(cy - ey))
    xmax, ymax = float(np.max(cx + ex)), float(np.max(cy + ey))
    for p in poses:
        xmin, ymin = min(xmin, p.x - POSE_ROOM), min(ymin, p.y - POSE_ROOM)
        xmax, ymax = max(xmax, p.x + POSE_ROOM), max(ymax, p.y + POSE_ROOM)
    return (xmin, ymin, xmax, ymax)
