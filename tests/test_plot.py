import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.plot import FRAME, MEDIAN, PALETTE, REFERENCE, box_plot, line_plot, nice_ticks


def find_frame(arr):
    """Rows and columns of the plot frame: the long lines in the frame colour."""
    is_frame = (arr == FRAME).all(axis=2)
    rows = np.flatnonzero(is_frame.sum(axis=1) > 0.5 * arr.shape[1])
    cols = np.flatnonzero(is_frame.sum(axis=0) > 0.5 * arr.shape[0])
    assert len(rows) == 2 and len(cols) == 2, (rows, cols)
    return rows[0], rows[1], cols[0], cols[1]


def close_to(arr, color, tol=40):
    return (np.abs(arr.astype(int) - color) <= tol).all(axis=-1)


@pytest.mark.parametrize("lo,hi,target,expected", [
    (0.0, 1.0, 5, [0.0, 0.2, 0.4, 0.6, 0.8, 1.0]),
    (0.0, 612.0, 6, [0.0, 200.0, 400.0, 600.0]),        # raw step 102 -> 200
    (-3.0, 7.0, 5, [-2.0, 0.0, 2.0, 4.0, 6.0]),
    (0.93, 1.0, 6, [0.94, 0.96, 0.98, 1.0]),            # raw 0.0117 -> 0.02
    (0.0, 1.0, 10, [round(0.1 * k, 12) for k in range(11)]),
    (5.0, 5.0, 6, [5.0]),
])
def test_nice_ticks(lo, hi, target, expected):
    assert nice_ticks(lo, hi, target) == pytest.approx(expected)


def test_nice_ticks_steps_are_1_2_5():
    rng = np.random.default_rng(0)
    for _ in range(200):
        lo = rng.normal() * 10.0 ** rng.integers(-3, 4)
        hi = lo + rng.random() * 10.0 ** rng.integers(-3, 4) + 1e-6
        ticks = nice_ticks(lo, hi, 6)
        assert 2 <= len(ticks) <= 7 or len(ticks) == 1
        if len(ticks) > 1:
            step = ticks[1] - ticks[0]
            mantissa = step / 10 ** np.floor(np.log10(step) + 1e-9)
            assert min(abs(mantissa - m) for m in (1, 2, 5, 10)) < 1e-6
            assert lo - 1e-9 * step <= ticks[0] and ticks[-1] <= hi + 1e-9 * step


def test_reference_line_at_axis_mapped_row():
    t = np.linspace(0.0, 100.0, 50)
    image = line_plot([("run", t, np.full_like(t, 0.5))], xlabel="time [s]", ylabel="coverage",
                      title="coverage", hlines=(0.99,), ylim=(0.0, 1.0))
    arr = np.asarray(image)
    assert image.size == (900, 540)
    top, bottom, left, right = find_frame(arr)
    row = round(top + (1.0 - 0.99) / (1.0 - 0.0) * (bottom - top))
    dashed = (arr[:, left + 1:right] == REFERENCE).all(axis=2)
    per_row = dashed.sum(axis=1)
    # dashes: 6 px on, 4 px off -> about 60 % of the row
    assert per_row[row] > 0.5 * (right - left)
    assert per_row[[r for r in range(arr.shape[0]) if abs(r - row) > 1]].max() < 0.1 * (right - left)


def test_series_lines_drawn_where_mapped():
    x = np.linspace(0.0, 10.0, 101)
    image = line_plot([("flat", x, np.full_like(x, 0.25)), ("ramp", x, x / 10.0)],
                      xlabel="x", ylabel="y", title="", ylim=(0.0, 1.0))
    arr = np.asarray(image)
    top, bottom, left, right = find_frame(arr)

    def to_px(xv, yv):
        return (left + xv / 10.0 * (right - left), top + (1.0 - yv) * (bottom - top))

    for xv in (1.0, 3.0, 5.0, 7.0):            # left part: the legend may sit on the right
        for k, yv in ((0, 0.25), (1, xv / 10.0)):
            u, v = to_px(xv, yv)
            patch = arr[int(v) - 1:int(v) + 2, int(u) - 1:int(u) + 2]
            assert close_to(patch, PALETTE[k]).any(), (k, xv)
    # the flat line is horizontal: its colour fills the mapped row across the plot
    _, v = to_px(0.0, 0.25)
    hit = close_to(arr[int(v) - 1:int(v) + 2, left + 1:right], PALETTE[0]).any(axis=0)
    assert hit.mean() > 0.7


def test_lines_are_clipped_to_the_frame():
    x = np.linspace(0.0, 1.0, 50)
    image = line_plot([("wild", x, 3.0 * np.sin(20 * x))], xlabel="x", ylabel="y", title="t",
                      ylim=(-1.0, 1.0))
    arr = np.asarray(image)
    top, bottom, left, right = find_frame(arr)
    blue = close_to(arr, PALETTE[0], tol=10)
    inside = np.zeros(blue.shape, bool)
    inside[top + 1:bottom, left + 1:right] = True
    assert blue[inside].sum() > 100
    # outside the frame only the legend sample (inside the frame too) could be blue: none
    assert not (blue & ~inside).any()


def test_autoscale_includes_reference_lines_and_nan_breaks():
    x = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    y = np.array([0.1, 0.2, np.nan, 0.3, 0.4])
    arr = np.asarray(line_plot([("a", x, y)], xlabel="", ylabel="", title="", hlines=(0.99,)))
    top, bottom, left, right = find_frame(arr)
    # y range = [0.1, 0.99] padded 5 %: 0.99 maps 1/1.1 of the way from the bottom
    lo, hi = 0.1 - 0.0445, 0.99 + 0.0445
    row = round(top + (hi - 0.99) / (hi - lo) * (bottom - top))
    dashed = (arr[row, left + 1:right] == REFERENCE).all(axis=1)
    assert dashed.sum() > 0.5 * (right - left)
    # no line across the NaN gap: the column at x = 2 has no series colour
    col = round(left + 2.0 / 4.0 * (right - left))
    assert not close_to(arr[top + 1:bottom, col], PALETTE[0], tol=60).any()


def test_box_plot_median_quartiles_and_outlier():
    image = box_plot([("a", [1, 2, 3, 4, 5]), ("b", [1, 2, 3, 4, 5, 20])], ylabel="path [m]",
                     title="paths", ylim=(0.0, 25.0))
    arr = np.asarray(image)
    top, bottom, left, right = find_frame(arr)

    def row_of(y):
        return top + (25.0 - y) / 25.0 * (bottom - top)

    slot = (right - left) / 2
    for g, median in ((0, 3.0), (1, 3.5)):
        cx = round(left + (g + 0.5) * slot)
        column = arr[top + 1:bottom, cx]
        med_rows = np.flatnonzero((column == MEDIAN).all(axis=1)) + top + 1
        assert med_rows.size and abs(med_rows.mean() - row_of(median)) <= 1.0, g
    # group a: box edges at the quartiles 2 and 4 in the group colour, off the centre line
    cx = round(left + 0.5 * slot)
    edge_rows = np.flatnonzero(close_to(arr[top + 1:bottom, cx + 10], PALETTE[0], 5)) + top + 1
    assert any(abs(r - row_of(4.0)) <= 1 for r in edge_rows)
    assert any(abs(r - row_of(2.0)) <= 1 for r in edge_rows)
    # group b: q1 2.25, q3 4.75, IQR 2.5 -> 20 is an outlier (circle), whisker stops at 5
    cx = round(left + 1.5 * slot)
    ring = close_to(arr[:, cx - 5:cx + 6], PALETTE[1], 60).any(axis=1)
    r20 = round(row_of(20.0))
    assert ring[r20 - 4:r20 + 5].any()
    whisker = np.flatnonzero((arr[top + 1:bottom, cx] == FRAME).all(axis=1)) + top + 1
    assert whisker.size and abs(whisker.min() - row_of(5.0)) <= 1
    assert not (abs(whisker - row_of(12.0)) <= 1).any()


def test_box_plot_handles_empty_group_and_autoscale():
    image = box_plot([("bvp", [79.8, 70.1, 88.0]), ("none", [])], ylabel="m", title="")
    assert image.size == (900, 540)
    arr = np.asarray(image)
    top, bottom, left, right = find_frame(arr)
    cx = round(left + 1.5 * (right - left) / 2)
    assert not (arr[top + 1:bottom, cx] == MEDIAN).all(axis=1).any()


def test_errors():
    with pytest.raises(ConfigError, match="series 0"):
        line_plot([("a", [1, 2, 3], [1, 2])], xlabel="", ylabel="", title="")
    with pytest.raises(ConfigError, match="ylim"):
        line_plot([("a", [1, 2], [1, 2])], xlabel="", ylabel="", title="", ylim=(1.0, 1.0))
    with pytest.raises(ConfigError, match="size"):
        box_plot([("a", [1])], ylabel="", title="", size=(50, 50))
