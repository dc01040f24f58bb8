import math

import numpy as np
import pytest
from PIL import Image

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import GridGeometry
from robotexp.output.render import COLORS, drawable_text, map_layout, render_map, save_png, viridis
from robotexp.robot import Pose

UNKNOWN, FREE, OCC = (205, 205, 205), (255, 255, 255), (0, 0, 0)

# 3 rows x 4 cols, row 0 = bottom of the world.
STATES = np.array([[0, 100, -1, 0],
                   [-1, -1, 0, 100],
                   [100, 0, 0, -1]], dtype=np.int8)
GEO = GridGeometry(0.0, 0.0, 1.0, 3, 4)


def px(image, x, y):
    return tuple(image.getpixel((x, y)))


def block(image, x0, y0, size):
    return np.asarray(image)[y0:y0 + size, x0:x0 + size]


def test_layout_hand_computed():
    lay = map_layout(GEO, scale=5)
    # map 20 x 15 px, widened to the 220 px minimum and centred; a 1 px frame above it.
    assert (lay.scale, lay.left, lay.top, lay.width, lay.height) == (5, 100, 1, 20, 15)
    assert (lay.image_width, lay.image_height) == (220, 1 + 15 + 1 + 26)
    assert lay.to_pixel(0.0, 3.0) == (100.0, 1.0)        # top-left corner of the world
    assert lay.to_pixel(4.0, 0.0) == (120.0, 16.0)       # bottom-right
    assert lay.cell_rect(0, 0) == (100, 11, 105, 16)
    titled = map_layout(GEO, scale=5, title="t")
    assert titled.top == 29


def test_states_colours_and_vertical_flip():
    image = render_map(STATES, GEO, scale=5)
    assert image.mode == "RGB" and image.size == (220, 43)
    colour = {-1: UNKNOWN, 0: FREE, 100: OCC}
    for r in range(3):
        for c in range(4):
            # world row r is image block row 2 - r (north up); map starts at (100, 1)
            got = block(image, 100 + 5 * c, 1 + 5 * (2 - r), 5)
            assert (got == colour[int(STATES[r, c])]).all(), (r, c)
    # the frame just outside the map
    assert px(image, 99, 1) == COLORS["frame"] and px(image, 100, 0) == COLORS["frame"]


def test_single_occupied_bottom_row_cell_lands_at_image_bottom():
    states = np.zeros((3, 4), np.int8)
    states[0, 3] = 100
    arr = np.asarray(render_map(states, GEO, scale=2))
    lay = map_layout(GEO, scale=2)
    mapped = arr[lay.top:lay.top + lay.height, lay.left:lay.left + lay.width]
    black = np.argwhere((mapped == 0).all(axis=2))
    assert sorted(set(black[:, 0])) == [4, 5] and sorted(set(black[:, 1])) == [6, 7]


def test_intermediate_values_are_grey_levels():
    states = np.array([[50, 25]], np.int8)
    image = render_map(states, GridGeometry(0, 0, 1, 1, 2), scale=3)
    lay = map_layout(GridGeometry(0, 0, 1, 1, 2), scale=3)
    assert px(image, lay.left, lay.top) == (128, 128, 128)     # round(255 * 0.5)
    assert px(image, lay.left + 3, lay.top) == (191, 191, 191)  # round(255 * 0.75)


@pytest.mark.parametrize("rows,cols,max_size", [(3, 4, 300), (120, 160, 1400), (500, 90, 800),
                                                (10, 600, 900), (7, 7, 120)])
def test_scale_fits_max_size(rows, cols, max_size):
    geo = GridGeometry(0.0, 0.0, 0.1, rows, cols)
    lay = map_layout(geo, max_size=max_size)
    image = render_map(np.zeros((rows, cols), np.int8), geo, max_size=max_size)
    assert image.size == (lay.image_width, lay.image_height)
    assert max(image.size) <= max_size
    bigger = map_layout(geo, scale=lay.scale + 1)
    assert max(bigger.image_width, bigger.image_height) > max_size


def test_scale_never_below_one_pixel():
    lay = map_layout(GridGeometry(0.0, 0.0, 0.1, 10, 1000), max_size=900)
    assert lay.scale == 1 and lay.image_width == 1002


def test_scale_fit_hand_computed():
    # width: (300 - 2) // 4 = 74; height: (300 - 28) // 3 = 90 -> 74 px per cell.
    lay = map_layout(GEO, max_size=300)
    assert lay.scale == 74 and (lay.image_width, lay.image_height) == (298, 28 + 222)


def test_path_colours_pixels_along_it():
    states = np.zeros((3, 4), np.int8)
    lay = map_layout(GEO, scale=10)
    # diagonal from the centre of cell (0, 0) to the centre of cell (2, 3)
    image = render_map(states, GEO, scale=10, path=[[0.5, 0.5], [3.5, 2.5]])
    blue = np.argwhere((np.asarray(image) == COLORS["path"]).all(axis=2))    # (row, col)
    # every point along the segment has a path pixel within 1 px of it
    for t in np.linspace(0.0, 1.0, 15):
        u, v = lay.to_pixel(0.5 + 3.0 * t, 0.5 + 2.0 * t)
        near = np.abs(blue - (math.floor(v), math.floor(u))).max(axis=1)
        assert near.min() <= 1, t
    # and every path pixel lies within 2 px of the segment (30 x 20 px from (105, 26) upwards)
    (u0, v0), (u1, v1) = lay.to_pixel(0.5, 0.5), lay.to_pixel(3.5, 2.5)
    d = np.array([u1 - u0, v1 - v0])
    rel = blue[:, ::-1] + 0.5 - (u0, v0)
    dist = np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0]) / np.hypot(*d)
    assert dist.max() <= 2.0
    assert 50 <= len(blue) <= 110             # about 36 px long x 2 px wide
    # far from the line the map stays free
    u, v = lay.to_pixel(3.5, 0.5)
    assert px(image, math.floor(u), math.floor(v)) == FREE
    # horizontal path along y = 1.5: every pixel of that row between the ends is blue
    image = render_map(states, GEO, scale=10, path=np.array([[0.5, 1.5], [2.5, 1.5], [3.5, 1.5]]))
    u0, v = lay.to_pixel(0.5, 1.5)
    u1, _ = lay.to_pixel(3.5, 1.5)
    row = np.asarray(image)[math.floor(v), math.floor(u0):math.floor(u1)]
    assert (row == COLORS["path"]).all()
    assert px(image, math.floor(u0), math.floor(v) - 4) == FREE


def test_start_and_end_markers():
    states = np.zeros((3, 4), np.int8)
    lay = map_layout(GEO, scale=20)               # 20 px/m: marker radius is the 4 px minimum
    image = render_map(states, GEO, scale=20, start=Pose(0.5, 0.5, 0.0),
                       end=Pose(3.5, 2.5, math.pi / 2))
    dark_green = tuple(int(0.6 * c) for c in COLORS["start"])
    dark_red = tuple(int(0.6 * c) for c in COLORS["end"])
    su, sv = (math.floor(a) for a in lay.to_pixel(0.5, 0.5))
    eu, ev = (math.floor(a) for a in lay.to_pixel(3.5, 2.5))
    # disc body (off the heading tick) in the marker colour
    assert px(image, su, sv + 2) == COLORS["start"]
    assert px(image, eu + 2, ev) == COLORS["end"]
    # heading tick: start faces +x (image right), end faces +y (image up)
    assert px(image, su + 6, sv) == dark_green
    assert px(image, su - 6, sv) == FREE
    assert px(image, eu, ev - 6) == dark_red
    assert px(image, eu, ev + 6) == FREE


def test_laser_points_drawn_orange():
    states = np.zeros((3, 4), np.int8)
    lay = map_layout(GEO, scale=20)
    image = render_map(states, GEO, scale=20, laser=np.array([[1.25, 2.25], [3.75, 0.25]]))
    for x, y in [(1.25, 2.25), (3.75, 0.25)]:
        u, v = lay.to_pixel(x, y)
        assert px(image, math.floor(u), math.floor(v)) == COLORS["laser"]
    u, v = lay.to_pixel(2.5, 1.5)
    assert px(image, math.floor(u), math.floor(v)) == FREE


def test_truth_drawn_only_where_missed():
    states = np.array([[0, 100, -1, 0]], np.int8)
    geo = GridGeometry(0, 0, 1, 1, 4)
    truth = np.array([[True, True, True, False]])
    image = render_map(states, geo, scale=4, truth=truth)
    lay = map_layout(geo, scale=4)
    got = [px(image, lay.left + 4 * c + 1, lay.top + 1) for c in range(4)]
    assert got == [COLORS["truth"], OCC, COLORS["truth"], FREE]


def test_potential_colours_free_cells_with_viridis():
    states = np.array([[0, 0, 0, 100, -1]], np.int8)
    geo = GridGeometry(0, 0, 1, 1, 5)
    pot = np.array([[0.0, 0.5, 1.0, 0.5, 0.5]])
    image = render_map(states, geo, scale=4, potential=pot)
    lay = map_layout(geo, scale=4)
    got = [px(image, lay.left + 4 * c + 2, lay.top + 2) for c in range(5)]
    # viridis anchors at 0, 1/2, 1; 0.5 -> index round(127.5) = 128, just past the middle anchor
    mid = tuple(int(v) for v in viridis(0.5))
    assert got == [(68, 1, 84), mid, (253, 231, 37), OCC, UNKNOWN]
    assert np.abs(np.array(mid) - (33, 145, 140)).max() <= 1


def test_viridis_table():
    out = viridis([0.0, 0.25, 1.0, np.nan, 2.0])
    assert out.dtype == np.uint8 and out.shape == (5, 3)
    assert out[0].tolist() == [68, 1, 84] and out[2].tolist() == [253, 231, 37]
    assert np.abs(out[1].astype(int) - (59, 82, 139)).max() <= 1
    assert out[3].tolist() == [255, 255, 255] and out[4].tolist() == [253, 231, 37]


def test_vectors_and_potential_change_free_cell_pixels_only():
    rng = np.random.default_rng(4)
    rows, cols, scale = 12, 16, 8
    geo = GridGeometry(-1.0, 2.0, 0.25, rows, cols)
    states = rng.choice(np.array([-1, 0, 0, 0, 100], np.int8), size=(rows, cols))
    vectors = rng.normal(size=(rows, cols, 2))
    potential = rng.random((rows, cols))
    base = np.asarray(render_map(states, geo, scale=scale))
    lay = map_layout(geo, scale=scale)
    free_px = np.zeros(base.shape[:2], bool)
    free_px[lay.top:lay.top + lay.height, lay.left:lay.left + lay.width] = np.repeat(
        np.repeat((states == 0)[::-1], scale, 0), scale, 1)
    for kwargs in ({"vectors": vectors}, {"potential": potential},
                   {"vectors": vectors, "potential": potential}):
        over = np.asarray(render_map(states, geo, scale=scale, **kwargs))
        changed = (over != base).any(axis=2)
        assert changed.any(), kwargs
        assert not (changed & ~free_px).any(), kwargs


def test_vector_arrow_points_along_field():
    # one free cell in the lattice, field pointing +x: arrow pixels right of the centre reach
    # further than those left of it (the head is at the +x end)
    geo = GridGeometry(0, 0, 1, 1, 1)
    image = render_map(np.zeros((1, 1), np.int8), geo, scale=40, vectors=np.array([[[1.0, 0.0]]]))
    lay = map_layout(geo, scale=40)
    arr = np.asarray(image)[lay.top:lay.top + 40, lay.left:lay.left + 40]
    ink = np.argwhere((arr == COLORS["vector"]).all(axis=2))
    # shaft: 0.8 of the 40 px cell, centred, along the middle rows
    shaft_rows = [r for r in range(40) if (ink[:, 0] == r).sum() > 20]
    assert shaft_rows and all(19 <= r <= 21 for r in shaft_rows)
    shaft = ink[ink[:, 0] == shaft_rows[0], 1]
    assert abs(shaft.min() - 4) <= 1 and abs(shaft.max() - 36) <= 1
    # the barbs spread vertically near the +x tip, not near the tail
    right = ink[ink[:, 1] > 30]
    left = ink[ink[:, 1] < 10]
    assert np.ptp(right[:, 0]) > np.ptp(left[:, 0])


def test_show_grid_cell_lines_when_cells_are_large():
    states = np.zeros((3, 4), np.int8)
    lay = map_layout(GEO, scale=8)
    image = render_map(states, GEO, scale=8, show_grid=True)
    line = (226, 228, 232)            # 0.8 * white + 0.2 * (110, 120, 140)
    assert px(image, lay.left + 8, lay.top + 3) == line      # left edge of column 1
    assert px(image, lay.left + 3, lay.top + 7) == line      # bottom edge of the top row
    assert px(image, lay.left + 3, lay.top + 3) == FREE


def test_show_grid_every_metre_when_cells_are_small():
    geo = GridGeometry(0.0, 0.0, 0.1, 5, 30)         # 2 px per cell, 20 px per metre
    image = np.asarray(render_map(np.zeros((5, 30), np.int8), geo, scale=2, show_grid=True))
    lay = map_layout(geo, scale=2)
    mid = lay.top + 5
    row = image[mid, lay.left:lay.left + lay.width]
    marked = np.flatnonzero((row != 255).any(axis=1))
    assert marked.tolist() == [0, 20, 40]            # x = 0, 1, 2 m


def test_scale_bar_and_title():
    geo = GridGeometry(0.0, 0.0, 0.1, 10, 30)        # scale 1 -> 10 px/m, 5 m bar = 50 px
    image = np.asarray(render_map(np.zeros((10, 30), np.int8), geo, scale=1, title="Run 1"))
    lay = map_layout(geo, scale=1, title="Run 1")
    y = lay.image_height - 13
    bar = image[y, 8:58]
    assert (bar == COLORS["text"]).all()
    assert (image[y, 59:62] == 255).all()
    band = image[:lay.top - 1]
    assert (band.sum(axis=2) < 300).sum() > 20         # dark title text in the band


def test_long_title_is_shortened():
    image = render_map(np.zeros((2, 2), np.int8), GridGeometry(0, 0, 1, 2, 2), scale=2,
                       title="x" * 400)
    assert image.width == 220


def test_drawable_text_replaces_missing_glyphs():
    assert drawable_text("dense — 5 × 5", 15) == "dense - 5 x 5"
    assert drawable_text("café", 15) == "cafe"
    assert drawable_text("plain 0.9", 15) == "plain 0.9"


def test_errors():
    with pytest.raises(ConfigError, match="states has shape"):
        render_map(np.zeros((4, 3), np.int8), GEO)
    with pytest.raises(ConfigError, match="integers"):
        render_map(np.zeros((3, 4)), GEO)
    with pytest.raises(ConfigError, match="scale"):
        render_map(STATES, GEO, scale=0)
    with pytest.raises(ConfigError, match="potential"):
        render_map(STATES, GEO, potential=np.zeros((4, 3)))
    with pytest.raises(ConfigError, match="path"):
        render_map(STATES, GEO, path=np.zeros((3, 3)))


def test_save_png_creates_folders_and_round_trips(tmp_path):
    image = render_map(STATES, GEO, scale=3)
    out = save_png(image, tmp_path / "a" / "b" / "map.png")
    assert out.exists()
    with Image.open(out) as back:
        assert back.format == "PNG"
        assert np.array_equal(np.asarray(back.convert("RGB")), np.asarray(image))
