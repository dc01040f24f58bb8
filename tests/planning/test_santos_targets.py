import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.planning.objective import INFEASIBLE
from robotexp.output.render import map_layout, viridis

PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "studies" / "santos_targets.py"


@pytest.fixture(scope="module")
def santos():
    spec = importlib.util.spec_from_file_location("santos_targets", PATH)
    module = importlib.util.module_from_spec(spec)
    sys.modules["santos_targets"] = module
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        del sys.modules["santos_targets"]


@pytest.fixture(scope="module")
def state(santos):
    """60 x 40 cells of 5 cm: a room walled on three sides, open (unknown) beyond column 39."""
    geo = GridGeometry(0.0, 0.0, 0.05, 40, 60)
    grid = OccupancyGrid(geo)
    free = np.zeros(grid.shape, bool)
    free[1:39, 1:40] = True
    walls = np.zeros(grid.shape, bool)
    walls[0, :41] = walls[39, :41] = True
    walls[:, 0] = True
    grid.mark_free(free)
    grid.mark_occupied(walls)
    visited = np.zeros(grid.shape, bool)
    visited[20, 5:11] = True
    return santos.MapState("box", grid, (10.5, 20.5), visited, radius=0.25)


@pytest.fixture(scope="module")
def studies(santos, state):
    return santos.study_state(state, ("proportional", "basic"), seeds=4)


def test_frontier_is_the_open_side(state):
    front = state.grid.frontier()
    assert front[1:39, 39].all() and np.count_nonzero(front) == 38


def test_optimum_is_the_argmin_of_the_surface_near_the_frontier(studies):
    for study in studies:
        surface = study.objective.surface
        r, c = np.unravel_index(np.argmin(surface), surface.shape)
        assert study.optimum.cell == (r, c)
        assert study.optimum.value == surface.min() < 0
        assert study.reachable[r, c]
        assert 35 <= c <= 39                       # the attraction of a frontier reaches ~4.5 cells
        assert (surface[~study.reachable] == INFEASIBLE).all()
        assert np.isfinite(surface[study.reachable]).all() and (surface[study.reachable] < INFEASIBLE).all()


def test_distances_are_those_of_the_decoded_cells(studies):
    hits = 0
    for study in studies:
        r0, c0 = study.optimum.cell
        for alg, found in (("ga", study.ga), ("fa", study.fa)):
            d = study.distances(alg)
            assert len(d) == 4 and (d >= 0).all()
            for res, di in zip(found, d, strict=True):
                assert di == pytest.approx(math.hypot(res.cell[0] - r0, res.cell[1] - c0))
                assert (di == 0) == (res.cell == (r0, c0))
                assert res.value >= study.optimum.value
                hits += res.cell == (r0, c0)
            q = study.ratios(alg)
            assert np.allclose(q, [f.value / study.optimum.value for f in found])
            assert (q <= 1 + 1e-12).all()          # a negative optimum: every other value is >= it
    assert hits > 0                                # seeded: some target is the optimum itself
    with pytest.raises(ConfigError, match="'ga' or 'fa'"):
        studies[0].distances("pso")


def test_summary_row(santos, state, studies):
    study = studies[0]
    row = santos.summary(state, study)
    d = study.distances("fa")
    assert row["form"] == "proportional" and row["opt_value"] == study.optimum.value
    assert row["fa_d_max"] == d.max() and row["fa_d_median"] == np.median(d)
    assert row["fa_at_opt"] == np.mean(d == 0)


def test_surface_image_size_and_markers(santos, state, studies):
    study = studies[0]
    image = santos.surface_image(state, study, scale=4)
    lay = map_layout(state.grid.geo, scale=4, title="x")
    assert image.size == (lay.image_width, lay.image_height)
    geo = state.grid.geo
    u, v = lay.to_pixel(*geo.center_of(*study.optimum.cell))
    assert image.getpixel((int(u) - 9, int(v))) == santos.OPTIMUM_COLOR      # the ring, 9 px left
    u, v = lay.to_pixel(geo.origin_x + state.robot[0] * geo.cell, geo.origin_y + state.robot[1] * geo.cell)
    assert image.getpixel((int(u), int(v))) == santos.ROBOT_COLOR
    # a reachable cell away from every marker: viridis of the symlog value between its limits
    field = santos.symlog(np.where(study.reachable, study.objective.surface, 0.0))
    lo, hi = field[study.reachable].min(), field[study.reachable].max()
    r, c = 20, 25
    assert study.reachable[r, c]
    x0, y0, _, _ = lay.cell_rect(r, c)
    assert image.getpixel((x0 + 1, y0 + 1)) == tuple(viridis((field[r, c] - lo) / (hi - lo)))
    # an unreachable known cell next to the wall is dark grey, a wall black, unknown light grey
    for (r, c), colour in (((2, 20), (150, 150, 150)), ((0, 20), (0, 0, 0)), ((20, 50), (205, 205, 205))):
        x0, y0, _, _ = lay.cell_rect(r, c)
        assert image.getpixel((x0 + 1, y0 + 1)) == colour, (r, c)
