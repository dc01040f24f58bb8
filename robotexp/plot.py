"""Line and box plots as PIL images, for run curves (coverage over time) and campaign summaries.

Only numpy and pillow: axes with 1-2-5 ticks, grid, labels, legend, dashed reference lines.
Inside the plot area, value y maps to image row `top + (y_max - y) / (y_max - y_min) * (bottom - top)`,
where rows `top` and `bottom` are the frame's horizontal edges (and likewise for x and columns).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
from PIL import Image, ImageDraw

from robotexp.errors import ConfigError
from robotexp.render import drawable_text, font

__all__ = ["PALETTE", "box_plot", "line_plot", "nice_ticks"]

RGB = tuple[int, int, int]

# Tableau-10 colours: distinct, and readable on white.
PALETTE: tuple[RGB, ...] = (
    (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
    (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207),
)
BACKGROUND: RGB = (255, 255, 255)
TEXT: RGB = (30, 30, 30)
FRAME: RGB = (90, 90, 90)
GRID: RGB = (232, 232, 232)
REFERENCE: RGB = (120, 120, 120)    # dashed reference lines
MEDIAN: RGB = (20, 20, 20)
TITLE_FONT = 17                     # [px]
LABEL_FONT = 14                     # [px]
TICK_FONT = 12                      # [px]
LINE_WIDTH = 2                      # [px] series lines
DASH = (6, 4)                       # [px] on, off
SUPERSAMPLE = 3                     # series lines are drawn this much larger, then shrunk


def nice_ticks(lo: float, hi: float, target: int = 6) -> list[float]:
    """Tick values on a 1-2-5 step (x 10^k) inside [lo, hi], at most about `target` + 1 of them.

    Args:
        lo: lower end of the axis.
        hi: upper end of the axis (> lo).
        target: wanted number of intervals.

    Returns:
        The multiples of the step that lie in [lo, hi] (with a tolerance of 1e-9 steps).
    """
    span = hi - lo
    if not (math.isfinite(span) and span > 0):
        return [lo] if math.isfinite(lo) else []
    raw = span / max(1, target)
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw * (1 - 1e-9))
    first = math.ceil(lo / step - 1e-9)
    last = math.floor(hi / step + 1e-9)
    return [round(k * step, 12) for k in range(first, last + 1)]


def _fmt(value: float, ticks: Sequence[float]) -> str:
    step = abs(ticks[1] - ticks[0]) if len(ticks) > 1 else abs(value) or 1.0
    if max(abs(t) for t in ticks) >= 1e6 or step < 1e-4:
        return f"{value:.3g}"
    decimals = max(0, -math.floor(math.log10(step) + 1e-9))
    text = f"{value:.{decimals}f}"
    return "0" if float(text) == 0 else text


def _padded(lo: float, hi: float) -> tuple[float, float]:
    """Data limits widened by 5 % each side (1 unit, or 10 % of |value|, when lo == hi)."""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return 0.0, 1.0
    if hi <= lo:
        d = abs(lo) * 0.1 or 1.0
        return lo - d, hi + d
    d = 0.05 * (hi - lo)
    return lo - d, hi + d


def _check_lim(name: str, lim: tuple[float, float] | None) -> tuple[float, float] | None:
    if lim is None:
        return None
    lo, hi = float(lim[0]), float(lim[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise ConfigError(f"{name}: ylim must be two finite numbers with low < high, got {lim!r}")
    return lo, hi


def _check_size(name: str, size: tuple[int, int]) -> tuple[int, int]:
    w, h = int(size[0]), int(size[1])
    if w < 200 or h < 150:
        raise ConfigError(f"{name}: size must be at least (200, 150) px, got {size!r}")
    return w, h


class _Axes(NamedTuple):
    """The plot area: frame columns left..right, rows top..bottom, and the value ranges."""

    left: int
    top: int
    right: int
    bottom: int
    x0: float
    x1: float
    y0: float
    y1: float

    def px(self, x: Any) -> Any:
        """Image column of x (float or array)."""
        return self.left + (x - self.x0) / (self.x1 - self.x0) * (self.right - self.left)

    def py(self, y: Any) -> Any:
        """Image row of y (float or array)."""
        return self.top + (self.y1 - y) / (self.y1 - self.y0) * (self.bottom - self.top)


def _layout(draw: ImageDraw.ImageDraw, size: tuple[int, int], yticks: list[float],
            title: str, xlabel: str, ylabel: str, ylim: tuple[float, float],
            xlim: tuple[float, float]) -> _Axes:
    tick_w = max((draw.textlength(_fmt(t, yticks), font=font(TICK_FONT)) for t in yticks), default=0)
    left = 12 + (LABEL_FONT + 8 if ylabel else 0) + int(tick_w) + 10
    top = 14 + (TITLE_FONT + 12 if title else 0)
    bottom = size[1] - (12 + (LABEL_FONT + 8 if xlabel else 0) + TICK_FONT + 10)
    right = size[0] - 40
    return _Axes(left, top, right, bottom, xlim[0], xlim[1], ylim[0], ylim[1])


def _dashed_h(draw: ImageDraw.ImageDraw, x0: int, x1: int, y: int, color: RGB) -> None:
    on, off = DASH
    x = x0
    while x <= x1:
        draw.line([(x, y), (min(x + on - 1, x1), y)], fill=color, width=1)
        x += on + off


def _frame(image: Image.Image, ax: _Axes, *, title: str, xlabel: str, ylabel: str,
           yticks: list[float], xticks: list[float] | None) -> None:
    """Grid, frame, ticks, tick labels, axis labels and title (everything but the data)."""
    draw = ImageDraw.Draw(image)
    tick_font = font(TICK_FONT)
    for t in yticks:
        y = round(ax.py(t))
        if ax.top < y < ax.bottom:
            draw.line([(ax.left + 1, y), (ax.right - 1, y)], fill=GRID)
        draw.line([(ax.left - 5, y), (ax.left - 1, y)], fill=FRAME)
        draw.text((ax.left - 8, y), _fmt(t, yticks), fill=TEXT, font=tick_font, anchor="rm")
    xt = xticks or []
    for t in xt:
        x = round(ax.px(t))
        if ax.left < x < ax.right:
            draw.line([(x, ax.top + 1), (x, ax.bottom - 1)], fill=GRID)
        draw.line([(x, ax.bottom + 1), (x, ax.bottom + 5)], fill=FRAME)
        draw.text((x, ax.bottom + 8), _fmt(t, xt), fill=TEXT, font=tick_font, anchor="mt")
    draw.rectangle([ax.left, ax.top, ax.right, ax.bottom], outline=FRAME, width=1)
    if title:
        draw.text(((ax.left + ax.right) / 2, 14), drawable_text(title, TITLE_FONT), fill=TEXT,
                  font=font(TITLE_FONT), anchor="mt")
    if xlabel:
        draw.text(((ax.left + ax.right) / 2, image.height - 12), drawable_text(xlabel, LABEL_FONT),
                  fill=TEXT, font=font(LABEL_FONT), anchor="md")
    if ylabel:
        text = drawable_text(ylabel, LABEL_FONT)
        w = int(draw.textlength(text, font=font(LABEL_FONT))) + 4
        label = Image.new("RGB", (w, LABEL_FONT + 6), BACKGROUND)
        ImageDraw.Draw(label).text((2, 1), text, fill=TEXT, font=font(LABEL_FONT))
        label = label.rotate(90, expand=True)
        image.paste(label, (12, round((ax.top + ax.bottom - label.height) / 2)))


def _series_arrays(series: Sequence[tuple[str, npt.ArrayLike, npt.ArrayLike]]
                   ) -> list[tuple[str, npt.NDArray[np.float64], npt.NDArray[np.float64]]]:
    out = []
    for i, item in enumerate(series):
        label, xs, ys = item
        x = np.asarray(xs, dtype=np.float64).ravel()
        y = np.asarray(ys, dtype=np.float64).ravel()
        if x.shape != y.shape:
            raise ConfigError(f"line_plot: series {i} ({label!r}) has {x.size} x values but "
                              f"{y.size} y values; give one y per x")
        out.append((str(label), x, y))
    return out


def _finite_range(arrays: list[npt.NDArray[np.float64]], extra: Sequence[float] = ()
                  ) -> tuple[float, float]:
    vals = [a[np.isfinite(a)] for a in arrays] + [np.asarray(extra, dtype=np.float64)]
    allv = np.concatenate(vals) if vals else np.zeros(0)
    allv = allv[np.isfinite(allv)]
    if allv.size == 0:
        return math.nan, math.nan
    return float(allv.min()), float(allv.max())


def _legend(image: Image.Image, ax: _Axes, entries: list[tuple[str, RGB]],
            occupied: npt.NDArray[np.bool_]) -> None:
    """A boxed legend in the plot-area corner that hides the fewest drawn data pixels."""
    if not entries:
        return
    draw = ImageDraw.Draw(image)
    f = font(TICK_FONT)
    texts = [drawable_text(label, TICK_FONT) for label, _ in entries]
    row_h = TICK_FONT + 6
    w = int(max(draw.textlength(t, font=f) for t in texts)) + 24 + 8 + 16
    h = row_h * len(entries) + 10
    corners = [(ax.right - 8 - w, ax.bottom - 8 - h), (ax.left + 8, ax.top + 8),
               (ax.right - 8 - w, ax.top + 8), (ax.left + 8, ax.bottom - 8 - h)]

    def cost(corner: tuple[int, int]) -> int:
        x, y = corner
        return int(occupied[max(0, y):max(0, y + h), max(0, x):max(0, x + w)].sum())

    x, y = min(corners, key=cost)
    draw.rectangle([x, y, x + w, y + h], fill=BACKGROUND, outline=(200, 200, 200))
    for k, (text, (_, color)) in enumerate(zip(texts, entries, strict=True)):
        cy = y + 5 + k * row_h + row_h // 2
        draw.line([(x + 8, cy), (x + 8 + 24, cy)], fill=color, width=3)
        draw.text((x + 8 + 24 + 8, cy), text, fill=TEXT, font=f, anchor="lm")


def line_plot(series: Sequence[tuple[str, npt.ArrayLike, npt.ArrayLike]], *, xlabel: str,
              ylabel: str, title: str, hlines: Sequence[float] = (),
              ylim: tuple[float, float] | None = None,
              size: tuple[int, int] = (900, 540)) -> Image.Image:
    """Plot each (label, xs, ys) series as a coloured polyline, with a legend.

    The x axis spans the data exactly; the y axis spans `ylim`, or the data and `hlines` with 5 %
    padding. NaN points break a line. Lines are clipped to the plot area.

    Args:
        series: (label, xs, ys) with xs and ys float arrays of equal length.
        xlabel: text under the x axis.
        ylabel: text along the y axis.
        title: text above the plot.
        hlines: y values of dashed horizontal reference lines (e.g. 0.9, 0.95, 0.99), each labelled
            with its value at the right end.
        ylim: (low, high) of the y axis, or None to fit.
        size: (width, height) [px] of the image, at least (200, 150).

    Returns:
        An RGB `PIL.Image.Image` of `size`.

    Raises:
        ConfigError: xs and ys of different lengths, a bad ylim or size.
    """
    width, height = _check_size("line_plot", size)
    data = _series_arrays(series)
    refs = [float(v) for v in hlines]
    ylim = _check_lim("line_plot", ylim)
    if ylim is None:
        ylim = _padded(*_finite_range([y for _, _, y in data], refs))
    xlo, xhi = _finite_range([x for _, x, y in data])
    xlim = (xlo, xhi) if xhi > xlo else _padded(xlo, xhi)
    image = Image.new("RGB", (width, height), BACKGROUND)
    draw = ImageDraw.Draw(image)
    yticks = nice_ticks(*ylim, target=max(2, (height - 120) // 60))
    ax = _layout(draw, (width, height), yticks, title, xlabel, ylabel, ylim, xlim)
    xticks = nice_ticks(*xlim, target=max(2, (ax.right - ax.left) // 100))
    _frame(image, ax, title=title, xlabel=xlabel, ylabel=ylabel, yticks=yticks, xticks=xticks)

    ref_font = font(TICK_FONT - 1)
    for v in refs:
        y = round(ax.py(v))
        if ax.top < y < ax.bottom:
            _dashed_h(draw, ax.left + 1, ax.right - 1, y, REFERENCE)
            label = _fmt(v, [0.0, 0.01]) if abs(v) < 10 else f"{v:g}"
            draw.text((ax.right + 4, y), label, fill=REFERENCE, font=ref_font, anchor="lm")

    # Series are drawn SUPERSAMPLE times larger on a transparent canvas the size of the inside of
    # the frame, then shrunk (anti-aliased) and laid over the plot: nothing spills out of the frame.
    k = SUPERSAMPLE
    inner_w, inner_h = ax.right - ax.left - 1, ax.bottom - ax.top - 1
    inner = Image.new("RGBA", (inner_w * k, inner_h * k), (0, 0, 0, 0))
    idraw = ImageDraw.Draw(inner)
    ox, oy = ax.left + 1, ax.top + 1
    occupied = np.zeros((height, width), dtype=bool)
    for i, (_, x, y) in enumerate(data):
        color = PALETTE[i % len(PALETTE)]
        ok = np.isfinite(x) & np.isfinite(y)
        us = (ax.px(x) - ox + 0.5) * k - 0.5            # supersampled canvas coordinates
        vs = (ax.py(y) - oy + 0.5) * k - 0.5
        # Break the polyline at every non-finite point.
        for seg in np.split(np.arange(x.size), np.flatnonzero(~ok)):
            seg = seg[ok[seg]]
            pts = list(zip(us[seg].tolist(), vs[seg].tolist(), strict=True))
            if len(pts) >= 2:
                idraw.line(pts, fill=(*color, 255), width=LINE_WIDTH * k, joint="curve")
            elif pts:
                (u, v), r = pts[0], LINE_WIDTH * k
                idraw.ellipse([u - r, v - r, u + r, v + r], fill=(*color, 255))
        cols = np.clip(np.round(ax.px(x[ok])), 0, width - 1).astype(int)
        rows = np.clip(np.round(ax.py(y[ok])), 0, height - 1).astype(int)
        occupied[rows, cols] = True
    small = inner.convert("RGBa").resize((inner_w, inner_h), Image.Resampling.BOX).convert("RGBA")
    image.paste(small, (ox, oy), small)
    _legend(image, ax, [(label, PALETTE[i % len(PALETTE)]) for i, (label, _, _) in enumerate(data)],
            occupied)
    return image


def _box_stats(values: npt.NDArray[np.float64]) -> tuple[float, float, float, float, float,
                                                          npt.NDArray[np.float64]]:
    """(q1, median, q3, whisker_low, whisker_high, outliers); numpy's linear quantiles,
    whiskers at the most extreme values within 1.5 IQR of the box."""
    q1, med, q3 = (float(q) for q in np.percentile(values, [25, 50, 75]))
    iqr = q3 - q1
    inside = values[(values >= q1 - 1.5 * iqr) & (values <= q3 + 1.5 * iqr)]
    outliers = values[(values < q1 - 1.5 * iqr) | (values > q3 + 1.5 * iqr)]
    return q1, med, q3, float(inside.min()), float(inside.max()), outliers


def box_plot(groups: Sequence[tuple[str, npt.ArrayLike]], *, ylabel: str, title: str,
             ylim: tuple[float, float] | None = None,
             size: tuple[int, int] = (900, 540)) -> Image.Image:
    """One box per (label, values) group: quartile box, median line, whiskers, outliers.

    Quartiles are numpy's linear percentiles; whiskers reach the most extreme values within
    1.5 IQR of the box; values beyond are drawn as open circles. NaN values are dropped; an empty
    group keeps its slot and label.

    Args:
        groups: (label, values) per method or condition, drawn left to right.
        ylabel: text along the y axis.
        title: text above the plot.
        ylim: (low, high) of the y axis, or None to fit all values with 5 % padding.
        size: (width, height) [px] of the image, at least (200, 150).

    Returns:
        An RGB `PIL.Image.Image` of `size`.

    Raises:
        ConfigError: a bad ylim or size.
    """
    width, height = _check_size("box_plot", size)
    data = []
    for label, values in groups:
        v = np.asarray(values, dtype=np.float64).ravel()
        data.append((str(label), v[np.isfinite(v)]))
    ylim = _check_lim("box_plot", ylim)
    if ylim is None:
        ylim = _padded(*_finite_range([v for _, v in data]))
    image = Image.new("RGB", (width, height), BACKGROUND)
    draw = ImageDraw.Draw(image)
    yticks = nice_ticks(*ylim, target=max(2, (height - 120) // 60))
    ax = _layout(draw, (width, height), yticks, title, "", ylabel, ylim, (0.0, float(max(1, len(data)))))
    _frame(image, ax, title=title, xlabel="", ylabel=ylabel, yticks=yticks, xticks=None)

    inner = Image.new("RGB", (ax.right - ax.left - 1, ax.bottom - ax.top - 1), BACKGROUND)
    inner.paste(image.crop((ax.left + 1, ax.top + 1, ax.right, ax.bottom)))
    idraw = ImageDraw.Draw(inner)
    ox, oy = ax.left + 1, ax.top + 1
    slot = (ax.right - ax.left) / max(1, len(data))
    half = min(40.0, 0.3 * slot)
    tick_font = font(TICK_FONT)
    for i, (label, v) in enumerate(data):
        color = PALETTE[i % len(PALETTE)]
        cx = ax.px(i + 0.5)
        text = drawable_text(label, TICK_FONT)
        while len(text) > 1 and draw.textlength(text, font=tick_font) > slot - 4:
            text = text[:-2] + "."
        draw.text((cx, ax.bottom + 8), text, fill=TEXT, font=tick_font, anchor="mt")
        draw.line([(round(cx), ax.bottom + 1), (round(cx), ax.bottom + 5)], fill=FRAME)
        if v.size == 0:
            continue
        q1, med, q3, lo, hi, out = _box_stats(v)
        u = cx - ox
        light = tuple(round(255 - 0.35 * (255 - c)) for c in color)
        for a, b in ((lo, q1), (q3, hi)):
            idraw.line([(u, ax.py(a) - oy), (u, ax.py(b) - oy)], fill=FRAME, width=1)
        for w in (lo, hi):
            idraw.line([(u - half / 2, ax.py(w) - oy), (u + half / 2, ax.py(w) - oy)], fill=FRAME)
        idraw.rectangle([u - half, ax.py(q3) - oy, u + half, ax.py(q1) - oy], fill=light,
                        outline=color, width=2)
        ym = round(ax.py(med)) - oy
        idraw.line([(u - half + 2, ym), (u + half - 2, ym)], fill=MEDIAN, width=2)
        r = 3.5
        for o in out:
            y = ax.py(float(o)) - oy
            idraw.ellipse([u - r, y - r, u + r, y + r], outline=color, width=1)
    image.paste(inner, (ox, oy))
    return image
