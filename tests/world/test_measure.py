"""measure_grid on maps drawn by hand: door widths, rooms, corridors, clutter, walls, unknown, open outline."""

from __future__ import annotations

import numpy as np
import pytest

from robotexp.world.measure import measure_grid


def cells(m: float, cell: float) -> int:
    return int(round(m / cell))


def two_rooms(cell: float, door: float) -> np.ndarray:
    """Two 4 x 5 m rooms side by side, one wall cell between them, a door `door` wide in it; walls round."""
    n = lambda m: cells(m, cell)          # noqa: E731
    v = np.full((n(5) + 2, n(8) + 3), 100, np.int8)
    v[1:1 + n(5), 1:1 + n(4)] = 0
    v[1:1 + n(5), 2 + n(4):2 + n(8)] = 0
    v[1 + n(2):1 + n(2) + n(door), 1 + n(4)] = 0
    return v


@pytest.mark.parametrize("cell", [0.05, 0.03])
@pytest.mark.parametrize("door", [0.6, 0.75, 0.9, 1.2])
def test_a_door_between_two_rooms_is_measured_within_half_a_cell(cell, door):
    v = two_rooms(cell, door)
    m = measure_grid(v, cell)
    width = cells(door, cell) * cell                  # the door as drawn on the cells
    assert len(m.door_widths) == 1 and abs(m.door_widths[0] - width) <= cell / 2 + 1e-9
    # the two rooms, 20 m2 each, split at the door (its few cells go to either side)
    assert len(m.room_areas) == 2 and m.corridor_widths == []
    assert sum(m.room_areas) == pytest.approx(np.count_nonzero(v == 0) * cell * cell)
    assert all(abs(a - 20.0) < 0.5 for a in m.room_areas)
    assert m.wall_thickness == pytest.approx(0.5 * cell + cell, abs=1e-9)     # one cell: 2 d - cell / 2, d = 1 cell


def test_a_corridor_with_rooms_off_it():
    cell = 0.05
    n = lambda m: cells(m, cell)          # noqa: E731
    v = np.full((n(7) + 3, n(20) + 2), 100, np.int8)
    v[1:1 + n(1.5), 1:1 + n(20)] = 0                       # the corridor, 1.5 x 20 m
    for k in range(4):                                     # four rooms 4.9 x 4 m with 0.8 m doors
        x0 = 1 + k * n(5)
        v[2 + n(1.5):2 + n(1.5) + n(4), x0:x0 + n(4.9)] = 0
        v[1 + n(1.5), x0 + n(1):x0 + n(1) + n(0.8)] = 0
    m = measure_grid(v, cell)
    assert m.door_widths == pytest.approx([0.8] * 4, abs=cell / 2 + 1e-9)
    assert m.corridor_widths == pytest.approx([1.5], abs=cell / 2 + 1e-9)
    assert len(m.room_areas) == 4 and all(abs(a - 19.6) < 0.3 for a in m.room_areas)
    assert m.clutter_areas == [] and m.pockets == 0 and m.open_length == 0.0 and m.unknown_share == 0.0


def test_clutter_specks_unknown_pockets_and_an_open_outline():
    cell = 0.05
    v = np.full((202, 202), 100, np.int8)
    v[1:-1, 1:-1] = 0                                      # a 10 x 10 m room
    v[50:56, 50:58] = 100                                  # a box 0.3 x 0.4 m: clutter
    v[150, 150] = 100                                      # a speck
    v[100:110, 1:11] = 100                                 # against the wall: part of the walls, not clutter
    v[150:170, 30:50] = -1                                 # an unknown pocket of 1 m2
    v[0, 120:140] = 0                                      # a 1 m gap in the outer wall onto the image edge
    m = measure_grid(v, cell)
    assert sorted(m.clutter_areas) == pytest.approx([cell * cell, 0.12])
    assert m.specks == 1 and m.clutter_per_100m2 == pytest.approx(100 / m.free_area)
    assert m.pockets == 1 and m.pocket_area == pytest.approx(1.0)
    assert m.open_length == pytest.approx(20 * cell)       # the 20 free cells on the image edge
    assert m.unknown_share == pytest.approx(400 / v.size)
    assert m.wall_gaps_per_10m == 0.0
    # a straight room with a box has few corners per metre of wall face; bumps on the walls add 4 each
    bumpy = v.copy()
    bumpy[1, 20:180:4] = 100
    assert measure_grid(bumpy, cell).corners_per_m > m.corners_per_m + 0.5
