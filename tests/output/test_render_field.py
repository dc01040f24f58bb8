import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import GridGeometry
from robotexp.output.render import COLORS, Marker, map_layout, render_field, viridis

# 3 rows x 4 cols, row 0 = bottom of the world; cell 1 m, drawn at 10 px per cell.
GEO = GridGeometry(0.0, 0.0, 1.0, 3, 4)
SCALE = 10
FIELD = np.array([[0.0, 2.5, 5.0, 7.5],
                  [10.0, 12.0, -3.0, 1.0],
                  [4.0, np.nan, 6.0, 9.0]])
MASK = np.array([[1, 1, 1, 1],
                 [1, 1, 1, 0],
                 [0, 1, 0, 0]], dtype=bool)
STATES = np.array([[0, 0, 0, 0],
                   [0, 0, 0, 100],
                   [-1, 0, 0, 100]], dtype=np.int8)
PURPLE, YELLOW = (68, 1, 84), (253, 231, 37)        # viridis at 0 and 1 (its published anchors)
UNKNOWN, MASKED, OCC = (205, 205, 205), (150, 150, 150), (0, 0, 0)


def cell_block(image, lay, r, c):
    x0, y0, x1, y1 = lay.cell_rect(r, c)
    return np.asarray(image)[y0:y1, x0:x1]


def test_cells_inside_mask_follow_viridis_of_the_limits_and_the_rest_their_state():
    image = render_field(FIELD, GEO, mask=MASK, states=STATES, limits=(0.0, 10.0), scale=SCALE)
    lay = map_layout(GEO, scale=SCALE)
    assert image.size == (lay.image_width, lay.image_height)
    expected = {
        (0, 0): PURPLE,                              # 0 -> low end
        (0, 1): tuple(viridis(0.25)),
        (0, 2): (33, 145, 140),                      # 0.5: viridis's middle anchor
        (0, 3): tuple(viridis(0.75)),
        (1, 0): YELLOW,                              # 10 -> high end
        (1, 1): YELLOW,                              # 12 clipped to the high end
        (1, 2): PURPLE,                              # -3 clipped to the low end
        (1, 3): OCC,                                 # outside the mask, occupied
        (2, 0): UNKNOWN,                             # outside, unknown
        (2, 1): MASKED,                              # in the mask but NaN: its state (free)
        (2, 2): MASKED,                              # outside, known free
        (2, 3): OCC,
    }
    assert tuple(viridis(0.75)) == (94, 201, 98)
    for (r, c), colour in expected.items():
        got = cell_block(image, lay, r, c)
        assert (got == colour).all(), ((r, c), got[0, 0], colour)


def test_default_limits_span_the_masked_values_and_default_states_are_unknown():
    image = render_field(FIELD, GEO, mask=MASK, scale=SCALE)
    lay = map_layout(GEO, scale=SCALE)
    assert (cell_block(image, lay, 1, 2) == PURPLE).all()        # -3, least in the mask
    assert (cell_block(image, lay, 1, 1) == YELLOW).all()        # 12, largest
    want = tuple(viridis((5.0 + 3.0) / 15.0))
    assert (cell_block(image, lay, 0, 2) == want).all()
    assert (cell_block(image, lay, 2, 2) == UNKNOWN).all()       # no states given: unknown


def test_markers_disc_and_ring_land_on_their_cell():
    red, green = (220, 40, 40), (0, 200, 70)
    markers = [Marker(0.5, 0.5, red, 3.0), Marker(2.5, 0.5, green, 4.0, ring=True)]
    image = render_field(FIELD, GEO, mask=MASK, states=STATES, limits=(0.0, 10.0), scale=SCALE,
                         markers=markers, title="t")
    lay = map_layout(GEO, scale=SCALE, title="t")
    assert image.size == (lay.image_width, lay.image_height)
    u, v = lay.to_pixel(0.5, 0.5)
    assert image.getpixel((int(u), int(v))) == red
    u, v = lay.to_pixel(2.5, 0.5)
    assert image.getpixel((int(u), int(v))) == (33, 145, 140)    # inside the ring: the cell's colour
    assert image.getpixel((int(u) - 4, int(v))) == green          # on the ring, 4 px left
    assert image.getpixel((int(u) + 4, int(v))) == green


def test_bad_input_raises_config_error():
    with pytest.raises(ConfigError, match="field has shape"):
        render_field(np.zeros((2, 4)), GEO)
    with pytest.raises(ConfigError, match="mask has shape"):
        render_field(FIELD, GEO, mask=np.ones((3, 3), bool))
    with pytest.raises(ConfigError, match="limits"):
        render_field(FIELD, GEO, limits=(1.0, 1.0))
    assert COLORS["masked"] == MASKED
