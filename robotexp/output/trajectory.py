"""Robot trajectories: the per-run path file `NAME.path.csv` (drawn by `robotexp.output.figures.paths_figure`).

A path file has a header `x_m,y_m` and one world position [m] per line, in the order the run
recorded them (one per control step), thinned so consecutive points lie at least `MIN_STEP` apart;
the run's last position is always kept.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError

__all__ = ["MIN_STEP", "PATH_HEADER", "read_path_csv", "thin_path", "write_path_csv"]

MIN_STEP = 0.01                 # [m] thinning distance of path files
PATH_HEADER = ("x_m", "y_m")


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
