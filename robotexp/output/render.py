"""Map images: an occupancy grid drawn north-up as a PIL image, with the overlays of IfTEA's map view.

`render_map` draws the grid states (unknown grey, free white, occupied black), optionally the
ground-truth obstacles the map missed, a potential field, its gradient arrows, the cell grid, the
robot path, the current laser points and the start / end poses, plus a scale bar and a title.
`map_layout` tells where each world point lands in that image. Only numpy and pillow are used.

Pixel convention: pixel (i, j) covers the continuous image square [i, i+1) x [j, j+1); world
point (x, y) maps through `MapLayout.to_pixel` and `floor` gives the pixel that holds it.
"""

from __future__ import annotations

import functools
import math
import unicodedata
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import numpy.typing as npt
from PIL import Image, ImageDraw, ImageFont

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import GridGeometry
from robotexp.robot import Pose

if TYPE_CHECKING:
    from robotexp.run.loop import ExplorationRun

__all__ = ["COLORS", "TEAM_COLORS", "teammates_of",
           "MapLayout", "Marker", "drawable_text", "font", "map_layout", "render_field", "render_map",
           "save_png", "viridis", "laser_hits"]


def laser_hits(run: ExplorationRun) -> np.ndarray[Any, np.dtype[np.float64]] | None:
    """(n, 2) world points [m] of the finite beams of the run's last scan, from the laser's place on the robot
    at the pose the explorer got (the map's frame); None without a scan."""
    state = run.state
    if state is None or state.laser is None:
        return None
    p, sc = state.pose, state.laser
    ok = np.isfinite(sc.ranges)
    a = p.theta + sc.angles[ok]
    sx, sy = sc.origin(p)
    return np.column_stack([sx + sc.ranges[ok] * np.cos(a), sy + sc.ranges[ok] * np.sin(a)])

RGB = tuple[int, int, int]

COLORS: dict[str, RGB] = {
    "unknown": (205, 205, 205),
    "free": (255, 255, 255),
    "occupied": (0, 0, 0),
    "truth": (150, 168, 200),       # light slate: obstacles the map has not marked
    "path": (30, 90, 220),
    "laser": (255, 140, 0),
    "start": (40, 170, 60),
    "end": (220, 40, 40),
    "vector": (25, 25, 25),
    "grid": (110, 120, 140),        # blended at GRID_ALPHA over whatever lies below
    "chrome": (255, 255, 255),      # title band, footer, margins
    "frame": (120, 120, 120),       # 1 px line around the map
    "text": (30, 30, 30),
    "masked": (150, 150, 150),      # render_field: known free cells outside the field's mask
}
# a team's robots 2, 3, ... (path and pose), in turn; apart from every colour above
TEAM_COLORS: tuple[RGB, ...] = ((150, 60, 200), (0, 150, 150), (200, 60, 150), (120, 90, 30), (90, 160, 20))
GRID_ALPHA = 0.2
TITLE_FONT = 15                     # [px]
FOOTER_FONT = 12                    # [px]
TITLE_HEIGHT = 28                   # [px] band above the map when a title is given
FOOTER_HEIGHT = 26                  # [px] band below the map holding the scale bar
FRAME = 1                           # [px] frame width around the map
MIN_WIDTH = 220                     # [px] narrowest image, so the footer text fits
ROBOT_RADIUS = 0.2                  # [m] drawn radius of the start / end markers
ARROW_SPACING = 14                  # [px] minimum distance between vector-field arrows

# Viridis sampled at 0, 1/4, 1/2, 3/4, 1 (its published anchor colours); linear in between.
_VIRIDIS_ANCHORS = np.array([(68, 1, 84), (59, 82, 139), (33, 145, 140), (94, 201, 98),
                             (253, 231, 37)], dtype=np.float64)
_VIRIDIS: npt.NDArray[np.uint8] = np.round(np.stack(
    [np.interp(np.linspace(0.0, 1.0, 256), np.linspace(0.0, 1.0, 5), _VIRIDIS_ANCHORS[:, k])
     for k in range(3)], axis=1)).astype(np.uint8)


@functools.lru_cache(maxsize=16)
def font(size: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    """Pillow's built-in font at `size` [px] (Pillow >= 10.1 scales it), cached."""
    return ImageFont.load_default(size=size)


# Stand-ins for characters the built-in font lacks (it would draw a box).
_FALLBACK = {"\u2014": "-", "\u2013": "-", "\u2212": "-", "\u00d7": "x", "\u00b5": "u",
             "\u00b0": " deg", "\u2026": "...", "\u2018": "'", "\u2019": "'", "\u201c": '"',
             "\u201d": '"'}


@functools.lru_cache(maxsize=4096)
def _has_glyph(size: int, char: str) -> bool:
    f = font(size)
    if not isinstance(f, ImageFont.FreeTypeFont) or char.isspace():
        return True
    missing = f.getmask("\uffff")          # a code point no font has: the "missing" box
    mask = f.getmask(char)
    return mask.size != missing.size or bytes(mask) != bytes(missing)


def drawable_text(text: str, size: int) -> str:
    """Return `text` with the characters the built-in font at `size` [px] cannot draw replaced.

    Dashes become "-", the multiplication sign "x", accented letters their base letter and
    anything else "?", instead of the font's empty box.
    """
    out = []
    for ch in text:
        if not _has_glyph(size, ch):
            base = "".join(c for c in unicodedata.normalize("NFKD", ch) if not unicodedata.combining(c))
            if base and all(_has_glyph(size, c) for c in base):
                ch = base
            else:
                ch = _FALLBACK.get(ch, "?")
        out.append(ch)
    return "".join(out)


def viridis(values: npt.ArrayLike) -> npt.NDArray[np.uint8]:
    """Colours of a viridis-like map for `values` in [0, 1] (clipped); NaN gives white.

    Args:
        values: any shape, float.

    Returns:
        uint8 array of shape values.shape + (3,), RGB.
    """
    v = np.asarray(values, dtype=np.float64)
    idx = np.round(np.clip(np.nan_to_num(v, nan=0.0), 0.0, 1.0) * 255).astype(np.intp)
    out = _VIRIDIS[idx]
    out[np.isnan(v)] = 255
    return out


class MapLayout(NamedTuple):
    """Where the map lies in the image `render_map` makes.

    The map occupies columns [left, left + width) and rows [top, top + height) of the image;
    each grid cell is a `scale` x `scale` pixel square, north up.
    """

    geo: GridGeometry
    scale: int          # [px] per cell
    left: int           # [px] image column of the map's left edge
    top: int            # [px] image row of the map's top edge (the world's largest y)
    width: int          # [px] map width = cols * scale
    height: int         # [px] map height = rows * scale
    image_width: int    # [px]
    image_height: int   # [px]

    @property
    def pixels_per_metre(self) -> float:
        """[px/m] image pixels per world metre."""
        return self.scale / self.geo.cell

    def to_pixel(self, x: float, y: float) -> tuple[float, float]:
        """Continuous image coordinates (column, row) [px] of world point (x, y) [m]."""
        k = self.pixels_per_metre
        return (self.left + (x - self.geo.origin_x) * k,
                self.top + self.height - (y - self.geo.origin_y) * k)

    def cell_rect(self, row: int, col: int) -> tuple[int, int, int, int]:
        """Image pixel box (x0, y0, x1, y1), end exclusive, of grid cell (row, col)."""
        x0 = self.left + col * self.scale
        y0 = self.top + (self.geo.rows - 1 - row) * self.scale
        return (x0, y0, x0 + self.scale, y0 + self.scale)


def map_layout(geo: GridGeometry, *, scale: int | None = None, title: str | None = None,
               max_size: int = 1400) -> MapLayout:
    """The layout `render_map` uses for a grid of geometry `geo`.

    Args:
        geo: the grid's geometry.
        scale: pixels per cell (>= 1), or None for the largest integer scale at which the whole
            image (title band, map, footer) fits in `max_size` x `max_size` (at least 1).
        title: whether a title band is drawn (its text does not change the layout).
        max_size: [px] bound on the image's width and height when `scale` is None.

    Raises:
        ConfigError: scale < 1, max_size < 1 or an empty grid.
    """
    if geo.rows < 1 or geo.cols < 1:
        raise ConfigError(f"render_map: grid has {geo.rows} rows x {geo.cols} cols; "
                          "it needs at least one cell")
    top = (TITLE_HEIGHT if title else 0) + FRAME
    chrome_h = top + FRAME + FOOTER_HEIGHT
    if scale is None:
        if max_size < 1:
            raise ConfigError(f"render_map: max_size must be >= 1 px, got {max_size}")
        fit_w = (max_size - 2 * FRAME) // geo.cols
        fit_h = (max_size - chrome_h) // geo.rows
        scale = max(1, min(fit_w, fit_h))
    elif isinstance(scale, bool) or not isinstance(scale, (int, np.integer)) or scale < 1:
        raise ConfigError(f"render_map: scale must be an integer >= 1 px per cell, got {scale!r}")
    scale = int(scale)
    width, height = geo.cols * scale, geo.rows * scale
    image_width = max(width + 2 * FRAME, min(MIN_WIDTH, max_size))
    left = (image_width - width) // 2
    return MapLayout(geo, scale, left, top, width, height, image_width, chrome_h + height)


def _as_points(name: str, value: npt.ArrayLike) -> npt.NDArray[np.float64]:
    pts = np.asarray(value, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ConfigError(f"render_map: {name} must have shape (k, 2) [m], got {pts.shape}")
    return pts


def _check_field(name: str, value: npt.ArrayLike, geo: GridGeometry,
                 extra: tuple[int, ...] = ()) -> npt.NDArray[np.float64]:
    arr = np.asarray(value, dtype=np.float64)
    want = (geo.rows, geo.cols) + extra
    if arr.shape != want:
        raise ConfigError(f"render_map: {name} has shape {arr.shape}, expected {want} "
                          "(rows, cols of geo); compute it on the same grid")
    return arr


def _upscale(cells: npt.NDArray[np.uint8], scale: int) -> npt.NDArray[np.uint8]:
    """Per-cell array (rows, cols, ...) in world order to image pixels, north up."""
    return np.repeat(np.repeat(cells[::-1], scale, axis=0), scale, axis=1)


def _state_colors(states: npt.NDArray[np.int16]) -> npt.NDArray[np.uint8]:
    """(rows, cols, 3) RGB of grid states: < 0 unknown, 0..100 white to black."""
    level = np.round(255.0 * (1.0 - np.clip(states, 0, 100) / 100.0)).astype(np.uint8)
    rgb = np.repeat(level[:, :, None], 3, axis=2)
    rgb[states < 0] = COLORS["unknown"]
    return rgb


def _grid_lines(lay: MapLayout) -> tuple[list[int], list[int]]:
    """Canvas columns and rows of the grid lines: every cell edge when cells are >= 6 px wide,
    else every 1 m (5 m, 10 m, ... when 1 m is under 6 px), on multiples of that step."""
    if lay.scale >= 6:
        xs = list(range(0, lay.width, lay.scale))
        ys = [lay.height - 1 - r * lay.scale for r in range(lay.geo.rows)]
        return xs, ys
    k = lay.pixels_per_metre
    step = next((s for s in (1, 5, 10, 50, 100, 500) if s * k >= 6), 1000)
    geo = lay.geo
    xs = [math.floor((m * step - geo.origin_x) * k)
          for m in range(math.ceil(geo.origin_x / step), math.floor((geo.origin_x + geo.width) / step) + 1)]
    ys = [math.ceil(lay.height - (m * step - geo.origin_y) * k) - 1
          for m in range(math.ceil(geo.origin_y / step), math.floor((geo.origin_y + geo.height) / step) + 1)]
    return ([x for x in xs if 0 <= x < lay.width], [y for y in ys if 0 <= y < lay.height])


def _draw_arrows(canvas: Image.Image, lay: MapLayout, vectors: npt.NDArray[np.float64],
                 free: npt.NDArray[np.bool_]) -> None:
    """Unit-length arrows of `vectors` on a lattice of free cells, clipped to free pixels."""
    step = max(1, math.ceil(ARROW_SPACING / lay.scale))
    half = 0.4 * step * lay.scale                   # [px] half the arrow length
    layer = Image.new("RGB", canvas.size, COLORS["vector"])
    mask = Image.new("L", canvas.size, 0)
    draw = ImageDraw.Draw(mask)
    width = 1 if lay.scale * step < 30 else 2
    rows = range(step // 2, lay.geo.rows, step)
    cols = range(step // 2, lay.geo.cols, step)
    for r in rows:
        for c in cols:
            vx, vy = vectors[r, c]
            norm = math.hypot(vx, vy)
            if not free[r, c] or not norm > 0.0 or not math.isfinite(norm):
                continue
            ux, uy = vx / norm, -vy / norm          # image rows grow southwards
            cx = (c + 0.5) * lay.scale
            cy = (lay.geo.rows - r - 0.5) * lay.scale
            tip = (cx + half * ux, cy + half * uy)
            draw.line([(cx - half * ux, cy - half * uy), tip], fill=255, width=width)
            head = 0.7 * half
            for turn in (2.6, -2.6):                # [rad] barbs 30 deg off the reversed shaft
                bx = ux * math.cos(turn) - uy * math.sin(turn)
                by = ux * math.sin(turn) + uy * math.cos(turn)
                draw.line([tip, (tip[0] + head * bx, tip[1] + head * by)], fill=255, width=width)
    free_px = Image.fromarray(_upscale(free.astype(np.uint8) * 255, lay.scale), mode="L")
    mask = Image.fromarray(np.minimum(np.asarray(mask), np.asarray(free_px)), mode="L")
    canvas.paste(layer, (0, 0), mask)


def _draw_path(draw: ImageDraw.ImageDraw, lay: MapLayout, geo: GridGeometry, path: npt.ArrayLike, color: RGB,
               width: int) -> None:
    """A path [m] as a polyline (one point: a dot)."""
    k = lay.pixels_per_metre
    pts = _as_points("path", path)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    uv = [((x - geo.origin_x) * k, lay.height - (y - geo.origin_y) * k) for x, y in pts]
    if len(uv) >= 2:
        draw.line(uv, fill=color, width=width, joint="curve")
    elif uv:
        u, v = uv[0]
        draw.ellipse([u - width, v - width, u + width, v + width], fill=color)


def teammates_of(run: ExplorationRun) -> list[tuple[npt.NDArray[np.float64] | None, Pose | None]]:
    """A team run's robots 2, 3, ... as `render_map` draws them: each one's path and pose now ([] for one robot)."""
    out: list[tuple[npt.NDArray[np.float64] | None, Pose | None]] = []
    for m in getattr(run, "members", [])[1:]:
        s = m.state
        out.append((np.asarray(m.metrics.path, np.float64).reshape(-1, 2) if m.metrics.path else None,
                    None if s is None else (s.true_pose or s.pose)))
    return out


def _draw_pose(draw: ImageDraw.ImageDraw, lay: MapLayout, pose: Pose, color: RGB) -> None:
    u, v = lay.to_pixel(pose.x, pose.y)
    u, v = u - lay.left, v - lay.top
    r = max(4.0, ROBOT_RADIUS * lay.pixels_per_metre)
    dark = tuple(int(0.6 * c) for c in color)
    draw.ellipse([u - r, v - r, u + r, v + r], fill=color, outline=dark,
                 width=max(1, round(r / 6)))
    tip = (u + 1.8 * r * math.cos(pose.theta), v - 1.8 * r * math.sin(pose.theta))
    draw.line([(u, v), tip], fill=dark, width=max(2, round(r / 4)))


def _scale_bar(draw: ImageDraw.ImageDraw, lay: MapLayout) -> None:
    k = lay.pixels_per_metre
    metres = next((m for m in (1, 5, 10, 50, 100, 500) if m * k >= 40), 1000)
    if metres * k > lay.image_width - 80:           # a very zoomed map: 1 m is the shortest bar
        metres = 1
    length = max(1, round(metres * k))
    fnt = font(FOOTER_FONT)
    y = lay.image_height - FOOTER_HEIGHT // 2
    x0 = 8
    x1 = x0 + length - 1
    draw.line([(x0, y), (x1, y)], fill=COLORS["text"], width=3)
    for x in (x0, x1):
        draw.line([(x, y - 5), (x, y + 5)], fill=COLORS["text"], width=1)
    draw.text((x1 + 6, y), f"{metres} m", fill=COLORS["text"], font=fnt, anchor="lm")
    info = f"{lay.geo.cols} x {lay.geo.rows} cells of {lay.geo.cell:g} m"
    text_w = draw.textlength(info, font=fnt)
    if x1 + 60 + text_w < lay.image_width - 8:
        draw.text((lay.image_width - 8, y), info, fill=COLORS["text"], font=fnt, anchor="rm")


def _draw_title(draw: ImageDraw.ImageDraw, lay: MapLayout, title: str) -> None:
    fnt = font(TITLE_FONT)
    room = lay.image_width - 16
    text = drawable_text(title, TITLE_FONT)
    if draw.textlength(text, font=fnt) > room:
        while text and draw.textlength(text + "...", font=fnt) > room:
            text = text[:-1]
        text += "..."
    draw.text((8, TITLE_HEIGHT // 2), text, fill=COLORS["text"], font=fnt, anchor="lm")


CROP_MARGIN = 1.0       # [m] around the content of a cropped map image
CROP_SLACK = 0.1        # a crop that changes no side by more than this share of it is not made


def content_window(content: npt.NDArray[np.bool_], geo: GridGeometry, points: npt.NDArray[np.float64]
                   ) -> GridGeometry:
    """The grid window (same cells, maybe beyond `geo`) around the `content` cells and the finite
    (k, 2) `points` [m], CROP_MARGIN wider; `geo` itself when that changes no side by more than
    CROP_SLACK of it, or when there is no content at all."""
    rc = np.argwhere(content)
    pts = points[np.all(np.isfinite(points), axis=1)] if len(points) else points
    if len(pts):
        rc = np.vstack([rc, geo.cells_of(pts)])
    if len(rc) == 0:
        return geo
    pad = int(math.ceil(CROP_MARGIN / geo.cell))
    r0, c0 = rc.min(axis=0) - pad
    r1, c1 = rc.max(axis=0) + pad + 1
    # never more than 4 grids' worth of cells: a path to infinity is clipped, not drawn
    r0, c0 = max(int(r0), -geo.rows), max(int(c0), -geo.cols)
    r1, c1 = min(int(r1), 2 * geo.rows), min(int(c1), 2 * geo.cols)
    if (max(abs(r0), abs(r1 - geo.rows)) <= CROP_SLACK * geo.rows
            and max(abs(c0), abs(c1 - geo.cols)) <= CROP_SLACK * geo.cols):
        return geo
    return GridGeometry(geo.origin_x + c0 * geo.cell, geo.origin_y + r0 * geo.cell, geo.cell, r1 - r0, c1 - c0)


def _reframe(values: npt.NDArray[np.generic], geo: GridGeometry, window: GridGeometry, fill: Any
             ) -> npt.NDArray[np.generic]:
    """`values` on `geo` copied into the cells of `window` (same cell size and lattice), `fill` elsewhere."""
    out = np.full((window.rows, window.cols), fill, dtype=values.dtype)
    dr = int(round((window.origin_y - geo.origin_y) / geo.cell))
    dc = int(round((window.origin_x - geo.origin_x) / geo.cell))
    r0, r1 = max(dr, 0), min(dr + window.rows, geo.rows)
    c0, c1 = max(dc, 0), min(dc + window.cols, geo.cols)
    if r0 < r1 and c0 < c1:
        out[r0 - dr:r1 - dr, c0 - dc:c1 - dc] = values[r0:r1, c0:c1]
    return out


def render_map(states: npt.ArrayLike, geo: GridGeometry, *,  # noqa: C901, PLR0913
               truth: npt.ArrayLike | None = None, path: npt.ArrayLike | None = None,
               start: Pose | None = None, end: Pose | None = None, scale: int | None = None,
               show_grid: bool = False, laser: npt.ArrayLike | None = None,
               vectors: npt.ArrayLike | None = None, potential: npt.ArrayLike | None = None,
               title: str | None = None, max_size: int = 1400,
               content: npt.ArrayLike | None = None,
               teammates: Sequence[tuple[npt.ArrayLike | None, Pose | None]] = ()) -> Image.Image:
    """Draw an occupancy grid north-up with optional overlays, as an RGB image.

    Layers, bottom to top: states (unknown (205, 205, 205), free white, occupied black, values
    between 0 and 100 as grey levels), missed ground truth, potential, grid lines, vector arrows,
    path, laser points, start and end markers. Free cells are those with 0 <= state < 50.

    Args:
        states: int (rows, cols) grid states, -1 unknown, 0 free, 100 occupied; row 0 is the
            bottom (smallest y) of the world and is drawn at the bottom of the image.
        geo: geometry of `states` (and of every per-cell overlay).
        truth: bool (rows, cols) ground-truth obstacles, drawn in light slate where the map does
            not mark them occupied, to show what was missed.
        path: (k, 2) float world points [m] of the robot path, drawn as a blue polyline.
        start: start pose, a green disc of the robot's size with a heading tick.
        end: end pose, a red disc with a heading tick.
        scale: pixels per cell (int >= 1), or None to fit `max_size` (see `map_layout`).
        show_grid: draw thin cell edges when cells are >= 6 px, else lines every 1 m.
        laser: (n, 2) float world points [m] of the current scan's hits (orange dots).
        vectors: (rows, cols, 2) float field (x, y components, e.g. a potential gradient) drawn as
            equal-length arrows on a lattice of free cells; zero or NaN vectors are skipped.
        potential: (rows, cols) float in [0, 1] drawn as a viridis-like colour map on free cells.
        title: a line of text above the map.
        max_size: [px] bound on the image size when `scale` is None.
        teammates: a team's other robots (robots 2, 3, ...): each one's path ((k, 2) [m] or None) and pose
            now (or None), drawn as `path` and `end` are, in the colours of `TEAM_COLORS` in turn.
        content: bool (rows, cols) cells that matter (say, the known and the explorable ones): the
            image shows the box around them, the path and the poses, `CROP_MARGIN` wider, when
            that box differs from the grid by more than `CROP_SLACK` of a side (a foreign map with
            unknown space around the building; a path leaving the grid: the box grows beyond it,
            unknown there). Only without `vectors` and `potential`.

    Returns:
        An RGB `PIL.Image.Image`; `map_layout` with the same geo, scale, title and max_size gives
        the placement of the map in it (with `content`, for the geo of the window drawn: see
        `content_window`).

    Raises:
        ConfigError: an array of the wrong shape, a bad scale or max_size.
    """
    grid = np.asarray(states)
    if grid.shape != (geo.rows, geo.cols):
        raise ConfigError(f"render_map: states has shape {grid.shape} but geo is {geo.rows} rows x "
                          f"{geo.cols} cols; render with the grid's own GridGeometry")
    if not np.issubdtype(grid.dtype, np.integer):
        raise ConfigError(f"render_map: states must be integers (-1/0/100), got dtype {grid.dtype}")
    if content is not None and vectors is None and potential is None:
        poses = [(p.x, p.y) for p in (start, end, *(q for _, q in teammates)) if p is not None]
        extra = np.vstack([_as_points("path", path) if path is not None else np.zeros((0, 2)),
                           *(_as_points("path", t) for t, _ in teammates if t is not None),
                           np.array(poses, dtype=np.float64).reshape(-1, 2)])
        window = content_window(_check_field("content", content, geo) != 0, geo, extra)
        if window != geo:
            grid = _reframe(grid, geo, window, -1)
            if truth is not None:
                truth = _reframe(_check_field("truth", truth, geo) != 0, geo, window, False)
            geo = window
    lay = map_layout(geo, scale=scale, title=title, max_size=max_size)
    grid = grid.astype(np.int16)
    free = (grid >= 0) & (grid < 50)
    cells = _state_colors(grid)
    if truth is not None:
        missed = (_check_field("truth", truth, geo) != 0) & (grid < 50)
        cells[missed] = COLORS["truth"]
    if potential is not None:
        pot = _check_field("potential", potential, geo)
        cells[free] = viridis(pot[free])
    canvas_px = _upscale(cells, lay.scale)
    if show_grid:
        xs, ys = _grid_lines(lay)
        line = np.asarray(COLORS["grid"], dtype=np.float64)
        for sel in ((slice(None), xs), (ys, slice(None))):
            canvas_px[sel] = np.round((1 - GRID_ALPHA) * canvas_px[sel] + GRID_ALPHA * line)
    canvas = Image.fromarray(np.ascontiguousarray(canvas_px), mode="RGB")
    if vectors is not None:
        _draw_arrows(canvas, lay, _check_field("vectors", vectors, geo, (2,)), free)
    # PIL puts a float coordinate in the pixel it truncates to, i.e. the pixel holding that
    # continuous point, so canvas coordinates are passed unshifted.
    draw = ImageDraw.Draw(canvas)
    k = lay.pixels_per_metre
    dot = max(1.5, 0.04 * k)                        # [px] laser dot radius: 4 cm, at least 1.5 px
    line_w = max(2, round(max(lay.width, lay.height) / 500))
    for i, (trail, _) in enumerate(teammates):
        if trail is not None:
            _draw_path(draw, lay, geo, trail, TEAM_COLORS[i % len(TEAM_COLORS)], line_w)
    if path is not None:
        _draw_path(draw, lay, geo, path, COLORS["path"], line_w)
    if laser is not None:
        for x, y in _as_points("laser", laser):
            if math.isfinite(x) and math.isfinite(y):
                u, v = (x - geo.origin_x) * k, lay.height - (y - geo.origin_y) * k
                draw.ellipse([u - dot, v - dot, u + dot, v + dot], fill=COLORS["laser"])
    for pose, name in ((start, "start"), (end, "end")):
        if pose is not None:
            _draw_pose(draw, lay, pose, COLORS[name])
    for i, (_, pose) in enumerate(teammates):
        if pose is not None:
            _draw_pose(draw, lay, pose, TEAM_COLORS[i % len(TEAM_COLORS)])

    image = Image.new("RGB", (lay.image_width, lay.image_height), COLORS["chrome"])
    chrome = ImageDraw.Draw(image)
    chrome.rectangle([lay.left - FRAME, lay.top - FRAME, lay.left + lay.width - 1 + FRAME,
                      lay.top + lay.height - 1 + FRAME], outline=COLORS["frame"], width=FRAME)
    image.paste(canvas, (lay.left, lay.top))
    if title:
        _draw_title(chrome, lay, title)
    _scale_bar(chrome, lay)
    return image


class Marker(NamedTuple):
    """A point drawn over a `render_field` image: a filled disc, or a ring of width 2 px."""

    x: float                # [m] world x of the centre
    y: float                # [m] world y of the centre
    color: RGB
    radius: float = 4.0     # [px]
    ring: bool = False      # draw only the outline (what lies below stays visible inside)
    outline: RGB | None = None  # 1 px edge of a disc; None: the colour at half brightness


def render_field(field: npt.ArrayLike, geo: GridGeometry, *, mask: npt.ArrayLike | None = None,
                 states: npt.ArrayLike | None = None, limits: tuple[float, float] | None = None,
                 markers: Sequence[Marker] = (), scale: int | None = None, title: str | None = None,
                 max_size: int = 1400) -> Image.Image:
    """Draw a scalar field over a grid north-up in viridis, with point markers, as an RGB image.

    The image has `render_map`'s layout, title band and scale bar (`map_layout` with the same geo,
    scale, title and max_size places the map in it). Cell colours: inside `mask` (and where the
    field is finite), viridis((value - low) / (high - low)) clipped to [0, 1]; outside it, the
    colour of the cell's state: occupied black, unknown (205, 205, 205), known free
    `COLORS["masked"]` (150, 150, 150). Markers are drawn in order over the cells.

    Args:
        field: (rows, cols) float values, row 0 at the bottom of the world.
        geo: geometry of `field`.
        mask: (rows, cols) bool cells to colour by value; None: every cell with a finite value.
        states: (rows, cols) int grid states (-1 unknown, 0 free, 100 occupied) for the cells
            outside `mask`; None: they are all drawn unknown.
        limits: (low, high) values at the two ends of the colour map; None: the least and largest
            value inside the mask.
        markers: points to draw, in order (later ones on top).
        scale: pixels per cell (int >= 1), or None to fit `max_size` (see `map_layout`).
        title: a line of text above the map.
        max_size: [px] bound on the image size when `scale` is None.

    Returns:
        An RGB `PIL.Image.Image`.

    Raises:
        ConfigError: an array of the wrong shape, limits not finite with low < high, a bad scale.
    """
    values = _check_field("field", field, geo)
    inside = np.isfinite(values)
    if mask is not None:
        inside &= _check_field("mask", mask, geo) != 0
    base = np.full((geo.rows, geo.cols), -1, np.int16)
    if states is not None:
        base = np.asarray(_check_field("states", states, geo), dtype=np.int16)
    if limits is None:
        lo, hi = (float(values[inside].min()), float(values[inside].max())) if inside.any() else (0.0, 1.0)
    else:
        lo, hi = float(limits[0]), float(limits[1])
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ConfigError(f"render_field: limits must be finite with low < high, got {limits!r}")
    lay = map_layout(geo, scale=scale, title=title, max_size=max_size)
    image = render_map(base, geo, scale=lay.scale, title=title, max_size=max_size)
    cells = _state_colors(base)
    cells[(base >= 0) & (base < 50)] = COLORS["masked"]
    span = hi - lo if hi > lo else 1.0
    cells[inside] = viridis((values[inside] - lo) / span)
    image.paste(Image.fromarray(np.ascontiguousarray(_upscale(cells, lay.scale)), mode="RGB"), (lay.left, lay.top))
    draw = ImageDraw.Draw(image)
    for m in markers:
        u, v = lay.to_pixel(m.x, m.y)
        r = float(m.radius)
        box = [u - r, v - r, u + r, v + r]
        if m.ring:
            draw.ellipse(box, outline=m.color, width=2)
        else:
            edge = m.outline if m.outline is not None else tuple(int(0.5 * c) for c in m.color)
            draw.ellipse(box, fill=m.color, outline=edge)
    return image


def save_png(image: Image.Image, path: str | Path) -> Path:
    """Write `image` as PNG at `path`, creating missing parent folders; return the path."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    image.save(out, format="PNG")
    return out
