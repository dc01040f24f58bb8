"""Robot trajectories: the per-run path file `NAME.path.csv` and several runs overlaid on a world's map.

A path file has a header `x_m,y_m` and one world position [m] per line, in the order the run
recorded them (one per control step), thinned so consecutive points lie at least `MIN_STEP` apart;
the run's last position is always kept.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from PIL import Image, ImageDraw

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import GridGeometry

if TYPE_CHECKING:
    from robotexp.world.model import World

__all__ = ["MIN_STEP", "PATH_HEADER", "paths_image", "read_path_csv", "thin_path", "write_path_csv"]

MIN_STEP = 0.01                 # [m] thinning distance of path files
PATH_HEADER = ("x_m", "y_m")
MAP_CELL = 0.05                 # [m] raster of the ground truth behind overlaid paths
MAP_MARGIN = 0.5                # [m] around the world's bounds (or the paths' extent)
LINE_WIDTH = 2                  # [px]
LEGEND_FONT = 12                # [px]


def thin_path(points: Iterable[tuple[float, float]], min_step: float = MIN_STEP) -> list[tuple[float, float]]:
    """The first point, then each point at least `min_step` [m] from the previously kept one, then
    the last point (when not already kept). Non-finite points are dropped."""
    if not min_step >= 0:
        raise ConfigError(f"thin_path: min_step must be >= 0 m, got {min_step}")
    kept: list[tuple[float, float]] = []
    last: tuple[float, float] | None = None      # the latest point, when it was not kept
    for px, py in points:
        x, y = float(px), float(py)
        if not (math.isfinite(x) and math.isfinite(y)):
            continue
        if not kept or math.hypot(x - kept[-1][0], y - kept[-1][1]) >= min_step:
            kept.append((x, y))
            last = None
        else:
            last = (x, y)
    if last is not None:
        kept.append(last)
    return kept


def write_path_csv(path: Path, points: Iterable[tuple[float, float]], min_step: float = MIN_STEP) -> int:
    """Write the thinned `points` [m] to `path` (columns x_m, y_m, 0.1 mm resolution).

    Returns:
        The number of points written.
    """
    kept = thin_path(points, min_step)
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(PATH_HEADER)
        for x, y in kept:
            w.writerow([f"{x:.4f}", f"{y:.4f}"])
    return len(kept)


def read_path_csv(path: Path) -> npt.NDArray[np.float64]:
    """The (k, 2) float64 points [m] of a path file written by `write_path_csv`.

    Raises:
        ConfigError: not a path file (wrong header, a line that is not two numbers).
        OSError: the file cannot be read.
    """
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    if not rows or tuple(c.strip() for c in rows[0]) != PATH_HEADER:
        raise ConfigError(f"{path}:1: not a path file: expected the header {','.join(PATH_HEADER)}")
    pts = []
    for i, row in enumerate(rows[1:], start=2):
        try:
            x, y = (float(v) for v in row)
        except ValueError:
            raise ConfigError(f"{path}:{i}: expected two numbers x_m,y_m, got {','.join(row)!r}") from None
        pts.append((x, y))
    return np.array(pts, dtype=np.float64).reshape(-1, 2)


def _extent(paths: Sequence[npt.NDArray[np.float64]]) -> tuple[float, float, float, float]:
    allp = np.concatenate([p for p in paths if p.size] or [np.zeros((1, 2))])
    return (float(allp[:, 0].min()), float(allp[:, 1].min()), float(allp[:, 0].max()), float(allp[:, 1].max()))


def paths_image(world: World | None, runs: Sequence[tuple[str, npt.ArrayLike]], *, title: str,
                notes: Sequence[str] = (), max_size: int = 1000) -> Image.Image:
    """Several runs' trajectories overlaid on a world's ground-truth obstacles, with a legend.

    Obstacles are rasterised on 5 cm cells and drawn black on white (`render_map`); each path is a
    polyline in its own colour (the `plot.PALETTE`, in order) starting at a dot; the legend, right
    of the map, names the runs in the same order.

    Args:
        world: the world whose static obstacles form the background, or None for a blank area
            fitted to the paths.
        runs: (label, points) per run, points a (k, 2) array of world positions [m].
        title: text above the map.
        notes: grey lines of text under the legend (e.g. what a mark means).
        max_size: [px] bound on the map part of the image.

    Returns:
        An RGB `PIL.Image.Image`.

    Raises:
        ConfigError: a points array not of shape (k, 2).
    """
    from robotexp.plot import PALETTE
    from robotexp.render import drawable_text, font, map_layout, render_map

    arrays = []
    for label, pts in runs:
        a = np.asarray(pts, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != 2:
            raise ConfigError(f"paths_image: the points of {label!r} must have shape (k, 2) [m], got {a.shape}")
        arrays.append(a[np.all(np.isfinite(a), axis=1)])
    if world is not None and world.bounds is not None:
        geo = GridGeometry.covering(*world.bounds, cell=MAP_CELL, margin=MAP_MARGIN)
        from robotexp.mapping.groundtruth import occupancy
        states = np.where(occupancy(world, geo), 100, 0).astype(np.int16)
    else:
        geo = GridGeometry.covering(*_extent(arrays), cell=MAP_CELL, margin=MAP_MARGIN)
        states = np.zeros((geo.rows, geo.cols), np.int16)
    base = render_map(states, geo, title=title, max_size=max_size)
    lay = map_layout(geo, title=title, max_size=max_size)

    f = font(LEGEND_FONT)
    texts = [drawable_text(label, LEGEND_FONT) for label, _ in runs]
    extra = [drawable_text(text, LEGEND_FONT) for text in notes]
    probe = ImageDraw.Draw(base)
    row_h = LEGEND_FONT + 8
    legend_w = int(max((probe.textlength(t, font=f) + 32 for t in texts), default=0))
    legend_w = max(legend_w, int(max((probe.textlength(t, font=f) for t in extra), default=0))) + 18
    legend_h = lay.top + 10 + row_h * (len(texts) + len(extra) + 1)
    image = Image.new("RGB", (base.width + legend_w, max(base.height, legend_h)), (255, 255, 255))
    image.paste(base, (0, 0))
    draw = ImageDraw.Draw(image)
    dot = max(3.0, LINE_WIDTH * 2.0)
    for i, a in enumerate(arrays):
        color = PALETTE[i % len(PALETTE)]
        uv = [lay.to_pixel(x, y) for x, y in a.tolist()]
        if len(uv) >= 2:
            draw.line(uv, fill=color, width=LINE_WIDTH, joint="curve")
        if uv:
            u, v = uv[0]
            draw.ellipse([u - dot, v - dot, u + dot, v + dot], fill=color)
    x0 = base.width + 10
    for i, text in enumerate(texts):
        color = PALETTE[i % len(PALETTE)]
        cy = lay.top + 10 + i * row_h + row_h // 2
        draw.line([(x0, cy), (x0 + 24, cy)], fill=color, width=3)
        draw.text((x0 + 32, cy), text, fill=(30, 30, 30), font=f, anchor="lm")
    for i, text in enumerate(extra, start=len(texts) + 1):
        draw.text((x0, lay.top + 10 + i * row_h + row_h // 2), text, fill=(110, 110, 110), font=f, anchor="lm")
    return image
