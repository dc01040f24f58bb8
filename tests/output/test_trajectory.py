"""Path files (thinning, round trip, written by every run) and trajectories overlaid on a map (matplotlib)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from robotexp.errors import ConfigError
from robotexp.output.figures import PALETTE, paths_figure, save_figure
from robotexp.output.trajectory import read_path_csv, thin_path, write_path_csv
from robotexp.world.model import World


def test_thin_keeps_points_a_centimetre_apart_and_the_last() -> None:
    pts = [(0.0, 0.0), (0.004, 0.0), (0.009, 0.0), (0.010, 0.0), (0.015, 0.0), (0.0199, 0.0),
           (0.02, 0.0), (0.021, 0.0)]
    # kept: 0 (first), 0.010 (10 mm from 0), 0.02 (10 mm from 0.010), then 0.021 as the last point
    assert thin_path(pts) == [(0.0, 0.0), (0.010, 0.0), (0.02, 0.0), (0.021, 0.0)]
    # distance is measured from the last kept point, in 2-D: (0.006, 0.008) is exactly 1 cm away
    assert thin_path([(0, 0), (0.006, 0.008)]) == [(0.0, 0.0), (0.006, 0.008)]
    assert thin_path([(0, 0), (0.006, 0.007), (0.001, 0.001)]) == [(0.0, 0.0), (0.001, 0.001)]
    assert thin_path([(1.0, 2.0)]) == [(1.0, 2.0)]
    assert thin_path([]) == []
    assert thin_path([(0, 0), (math.nan, 1.0), (0.5, 0.5)]) == [(0.0, 0.0), (0.5, 0.5)]
    # a robot standing still: one point, and the last one (the same place) is not repeated
    assert thin_path([(1.0, 1.0)] * 5) == [(1.0, 1.0), (1.0, 1.0)]


def test_path_csv_round_trip(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    walk = np.cumsum(rng.normal(0.0, 0.006, (500, 2)), axis=0)
    n = write_path_csv(tmp_path / "r.path.csv", walk.tolist())
    back = read_path_csv(tmp_path / "r.path.csv")
    assert (tmp_path / "r.path.csv").read_text().splitlines()[0] == "x_m,y_m"
    assert back.shape == (n, 2) and 1 < n < 500
    np.testing.assert_allclose(back, np.array(thin_path(walk.tolist())), atol=5e-5)   # 0.1 mm digits
    steps = np.hypot(*np.diff(back[:-1], axis=0).T)
    assert steps.min() >= 0.01 - 1e-4
    np.testing.assert_allclose(back[-1], walk[-1], atol=5e-5)


@pytest.mark.parametrize("text, where", [("x,y\n1,2\n", ":1:"), ("x_m,y_m\n1,2\n3\n", ":3:"),
                                         ("x_m,y_m\n1,abc\n", ":2:"), ("", ":1:")])
def test_read_path_csv_refuses_other_files(tmp_path: Path, text: str, where: str) -> None:
    f = tmp_path / "bad.path.csv"
    f.write_text(text)
    with pytest.raises(ConfigError, match=where):
        read_path_csv(f)


def test_every_run_writes_its_path_file(tmp_path: Path) -> None:
    from robotexp.run.spec import RunSpec
    from robotexp.experiment import run_experiment

    res = run_experiment(RunSpec(world="ufmg-static", method="frontier", max_time=10), tmp_path, image=False)
    f = tmp_path / f"{res.record['run']}.path.csv"
    pts = read_path_csv(f)
    full = np.array(res.run.metrics.path)
    assert len(full) > len(pts) >= 2
    np.testing.assert_allclose(pts, np.array(thin_path(res.run.metrics.path)), atol=5e-5)
    np.testing.assert_allclose(pts[0], full[0], atol=5e-5)
    np.testing.assert_allclose(pts[-1], full[-1], atol=5e-5)
    # the record has no new field: the run name finds the file
    assert not any("path_file" in k or "path_csv" in k for k in res.record)


def _png_at(fig: Any, png: Path) -> Any:
    """A function (x, y) [m] -> the RGB of the saved PNG's pixel there."""
    from robotexp.output.figures import DPI

    with Image.open(png) as im:
        px = np.asarray(im.convert("RGB"))
    ax = fig.axes[0]

    def at(x: float, y: float) -> tuple[int, ...]:
        u, v = ax.transData.transform((x, y)) * (DPI / fig.dpi)
        return tuple(int(c) for c in px[px.shape[0] - 1 - int(v), int(u)])

    return at


def _near(rgb: tuple[int, ...], hex_colour: str, tol: int = 40) -> bool:
    want = tuple(int(hex_colour[i:i + 2], 16) for i in (1, 3, 5))
    return max(abs(a - b) for a, b in zip(rgb, want, strict=True)) <= tol


def test_paths_figure_draws_each_run_in_its_colour_over_the_obstacles(tmp_path: Path) -> None:
    world = World("box", boxes=[[0.0, 0.0, 5.0, 0.05, 0.0], [0.0, 4.0, 5.0, 0.05, 0.0]])   # two walls
    a = [(-4.0, 1.0), (4.0, 1.0)]           # along y = 1
    b = [(-4.0, 3.0), (0.0, 2.0)]           # from y = 3 down to y = 2
    fig = paths_figure(world, [("run a", a), ("run b", b)], title="t", notes=["dot: start of a path"])
    (png, svg) = save_figure(fig, tmp_path / "paths", ("png", "svg"))
    ax = fig.axes[0]
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    assert x0 <= -4.0 and x1 >= 4.0 and y0 <= 0.0 and y1 >= 4.0        # the world's bounds, in metres
    assert ax.get_xlabel() == "x [m]" and ax.get_ylabel() == "y [m]"
    at = _png_at(fig, png)
    assert _near(at(1.0, 1.0), PALETTE[0])
    assert _near(at(-2.0, 2.5), PALETTE[1])           # halfway along b
    assert max(at(2.0, 0.0)) < 90                      # wall (dark grey)
    assert min(at(2.0, 2.0)) > 240                     # free, no path
    text = svg.read_text()
    for words in ("run a", "run b", "dot: start of a path", "obstacles (50 mm cells)", " m<"):
        assert words in text, words


def test_paths_figure_without_a_world_fits_the_paths(tmp_path: Path) -> None:
    fig = paths_figure(None, [("only", [(10.0, 10.0), (12.0, 11.0)])], title="t")
    ax = fig.axes[0]
    assert ax.get_xlim()[0] <= 10.0 and ax.get_xlim()[1] >= 12.0 and ax.get_xlim()[1] - ax.get_xlim()[0] < 4.0
    (png,) = save_figure(fig, tmp_path / "one", ("png",))
    assert _near(_png_at(fig, png)(11.0, 10.5), PALETTE[0])
    with pytest.raises(ConfigError, match="shape"):
        paths_figure(None, [("bad", [1.0, 2.0])], title="t")
