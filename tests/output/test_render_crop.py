"""Map images of foreign maps: cropped to the content and the path, grown when the path leaves the grid."""

from __future__ import annotations

import numpy as np

from robotexp.mapping.geometry import GridGeometry
from robotexp.output.render import COLORS, CROP_MARGIN, content_window, map_layout, render_map
from robotexp.robot import Pose

GEO = GridGeometry(-5.0, -5.0, 0.1, 200, 200)        # 20 x 20 m


def test_a_small_building_in_a_large_unknown_map_is_cropped_to_it():
    states = np.full((200, 200), -1, np.int8)
    states[90:120, 80:110] = 0                       # 3 x 3 m known, rows 90-119, cols 80-109
    window = content_window(states >= 0, GEO, np.zeros((0, 2)))
    pad = round(CROP_MARGIN / GEO.cell)
    assert (window.rows, window.cols) == (30 + 2 * pad, 30 + 2 * pad)
    assert window.origin_x == GEO.origin_x + (80 - pad) * 0.1
    assert window.origin_y == GEO.origin_y + (90 - pad) * 0.1
    image = render_map(states, GEO, content=states >= 0, scale=4)
    lay = map_layout(window, scale=4)
    assert image.size == (lay.image_width, lay.image_height)
    # the known block's centre is white in the image
    u, v = lay.to_pixel(GEO.origin_x + 9.5, GEO.origin_y + 10.5)
    assert image.getpixel((int(u), int(v))) == (255, 255, 255)


def test_a_path_that_leaves_the_grid_grows_the_window_and_is_drawn_there():
    states = np.zeros((200, 200), np.int8)           # all known: no crop on its own
    assert content_window(states >= 0, GEO, np.zeros((0, 2))) == GEO
    path = np.array([[0.0, 0.0], [10.0, 0.0], [25.0, 0.0]])     # ends 10 m east of the grid
    image = render_map(states, GEO, content=states >= 0, path=path, start=Pose(0, 0, 0), scale=2)
    window = content_window(states >= 0, GEO, path)
    assert window.origin_x + window.width >= 25.0 + CROP_MARGIN - 0.1
    lay = map_layout(window, scale=2)
    u, v = lay.to_pixel(22.0, 0.0)                   # beyond the grid, on the path
    assert image.getpixel((int(u), int(v))) == COLORS["path"]
    u, v = lay.to_pixel(22.0, 3.0)                   # beyond the grid, off the path: unknown
    assert image.getpixel((int(u), int(v))) == (205, 205, 205)


def test_a_map_filled_by_its_content_keeps_its_whole_grid():
    states = np.full((200, 200), -1, np.int8)
    states[5:195, 5:195] = 0
    plain = render_map(states, GEO, scale=2)
    assert render_map(states, GEO, content=states >= 0, scale=2).tobytes() == plain.tobytes()
