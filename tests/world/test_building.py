"""The `building` kind: drawn from the measured distributions, deterministic, valid for a run."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from robotexp.mapping.geometry import GridGeometry
from robotexp.world.building import (CORRIDOR_RANGE, DISTRIBUTIONS, DOOR_RANGE, OUTSIDE, PERCENTILES,
                                     draw, generate_building)
from robotexp.world.generate import generate_grid, generated_world, parse_generated
from robotexp.world.groundtruth import ground_truth
from robotexp.world.measure import measure_grid
from robotexp.world.start import default_start

SIZE = (16.0, 12.0)
MEASURED = Path(__file__).resolve().parents[2] / "benchmarks" / "results" / "buildings" / "distributions.json"


def test_the_parameters_are_the_measured_percentiles():
    corpus = json.loads(MEASURED.read_text())["corpus"]
    for key, values in DISTRIBUTIONS.items():
        assert values == pytest.approx(corpus[key], rel=1e-5), key


def test_draws_follow_the_measured_percentiles_within_their_range():
    rng = np.random.default_rng(0)
    doors = np.array([draw(rng, "door_widths") for _ in range(4000)])
    q = np.asarray(DISTRIBUTIONS["door_widths"])
    # the empirical percentiles of the draws are the measured ones (linear between them)
    for p in (25, 50, 75):
        assert abs(np.percentile(doors, p) - np.interp(p, PERCENTILES, q)) < 0.06
    held = np.array([draw(rng, "door_widths", *DOOR_RANGE) for _ in range(2000)])
    assert held.min() >= DOOR_RANGE[0] and held.max() <= DOOR_RANGE[1]
    # conditioned on the range: the share below 1.0 m is the measured share between 0.6 and 1.0 m over the range's
    f = lambda x: np.interp(x, q, PERCENTILES)      # noqa: E731
    expected = (f(1.0) - f(DOOR_RANGE[0])) / (f(DOOR_RANGE[1]) - f(DOOR_RANGE[0]))
    assert abs(np.mean(held < 1.0) - expected) < 0.04


def test_same_seed_same_building_other_seed_another():
    a, geo_a = generate_grid("building", 3, SIZE)
    b, geo_b = generate_grid("building", 3, SIZE)
    c, _ = generate_grid("building", 4, SIZE)
    assert geo_a == geo_b and np.array_equal(a, b) and not np.array_equal(a, c)
    # the spec takes the building kind; laser-like already, ":scanned" changes nothing
    assert parse_generated("generated:building:0-2:20x15")[0] == "building"
    assert np.array_equal(generate_grid("building", 3, SIZE, scanned=True)[0], a)


@pytest.mark.parametrize("seed", range(4))
def test_drawn_doors_corridors_rooms_lie_in_the_measured_ranges_and_on_the_grid(seed):
    values, geo, plan = generate_building(np.random.default_rng(seed), *SIZE)
    corpus = {k: (v[0], v[-1]) for k, v in DISTRIBUTIONS.items()}
    assert plan.doors and plan.corridors and plan.rooms
    for widths, (lo, hi), key in ((plan.doors, DOOR_RANGE, "door_widths"),
                                  (plan.corridors, CORRIDOR_RANGE, "corridor_widths")):
        assert min(widths) >= max(lo, corpus[key][0]) - 1e-9 and max(widths) <= min(hi, corpus[key][1]) + 1e-9
    # the grid: unknown outside (the image's corners), free inside, one or two fans of free space
    # seen through doors to the outside (free cells beyond the walls: an open outline)
    assert values[0, 0] == -1 and values[-1, -1] == -1
    m = measure_grid(values, geo.cell)
    assert m.open_length > 0
    outside = np.ones_like(values, dtype=bool)
    r0, c0 = geo.cell_of(0.0, 0.0)
    r1, c1 = geo.cell_of(SIZE[0] - 0.01, SIZE[1] - 0.01)
    outside[r0:r1 + 1, c0:c1 + 1] = False
    assert np.count_nonzero((values == 0) & outside) > 0
    assert geo.origin_x == pytest.approx(-OUTSIDE)


def test_measured_like_the_real_buildings():
    # the generator's grids, measured as the corpus was: door widths and room areas in the corpus' middle
    doors, rooms, corners = [], [], []
    for seed in range(3):
        values, geo = generate_grid("building", seed, SIZE)
        m = measure_grid(values, geo.cell)
        doors += m.door_widths
        rooms += m.room_areas
        corners.append(m.corners_per_m)
    pct = lambda key, p: np.interp(p, PERCENTILES, DISTRIBUTIONS[key])     # noqa: E731
    assert pct("door_widths", 20) <= np.median(doors) <= pct("door_widths", 80)
    assert pct("room_areas", 10) <= np.median(rooms) <= pct("room_areas", 80)
    assert pct("corners_per_m", 0) <= np.median(corners) <= pct("corners_per_m", 100)


def test_a_run_can_start_and_its_ground_truth_computes():
    world = generated_world("building", 1, SIZE)
    choice = default_start(world, 0.25)
    assert world.bounds is not None
    geo = GridGeometry.covering(*world.bounds, cell=0.05, margin=0.5)
    gt = ground_truth(world, geo, robot_radius=0.25, laser_range=4.0, start=choice.pose)
    r, c = geo.cell_of(choice.pose.x, choice.pose.y)
    assert gt.reachable[r, c]
    # the start's region holds most of the building's floor (16 x 12 m, less walls, furniture, closed rooms)
    assert np.count_nonzero(gt.reachable) * geo.cell ** 2 > 60.0
    assert np.count_nonzero(gt.explorable) >= np.count_nonzero(gt.reachable)
