"""Figures for a thesis, on matplotlib: vector (SVG, PDF) and raster (PNG) output, text in points at a
page's width, axes with units. The fast raster path (`robotexp.output.render`) stays for frames, video and the
live view; these figures are the images a run, a campaign and `robotexp figure` write.

`map_figure`: an occupancy map cropped to its content and path, with a legend (free, occupied, unknown,
obstacles not mapped, path, start, end; the estimated path beside the true one when they differ),
axes in metres, a scale bar, the cell size and, for a potential field, a colour bar.
`curve_figure`: coverage (or any) curves, one colour per label. `paths_figure`: trajectories of several
runs over a world's obstacles. `box_figure`: one box per group with every run drawn as a point over it
(a group of fewer than `MIN_BOX` runs gets its points only: a box of two values says nothing), the y
axis from 0 with its unit, n under each label. Titles follow one convention: "world - method" with the
method's registered name (`figure_title`, `run_title`), whether the run came from the CLI, Lua or a
campaign.

Only `matplotlib.figure.Figure` is used (never pyplot): no GUI backend is chosen, PNG goes through Agg,
so figures can be drawn in campaign worker processes and threads; matplotlib's settings are global, so
figures are made and saved under one lock (`_style`).
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import GridGeometry
from robotexp.output.render import COLORS, TEAM_COLORS, content_window, laser_hits

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from robotexp.run.loop import ExplorationRun
    from robotexp.robot import Pose
    from robotexp.world.model import World

__all__ = ["map_figure", "run_map_figure", "curve_figure", "run_coverage_figure", "paths_figure", "box_figure",
           "campaign_figures", "save_figure", "save_run_figures", "figure_title", "run_title", "FORMATS",
           "PAGE_WIDTH", "DPI", "write_figure", "apart"]

FORMATS = ("png", "svg", "pdf")
PAGE_WIDTH = 6.3        # [in] a thesis's text width (16 cm): figures are drawn at it, text in points
FONT_SIZE = 9           # [pt]
DPI = 200               # PNG pixels per inch: a page-wide figure is 1260 px wide
MIN_BOX = 5             # fewer runs than this in a group: points only, no box
EST_APART = 0.01        # [m] an estimated path this far from the true one somewhere is drawn beside it
LASER = "#17becf"            # the last scan's hits (the estimated path has the raster's laser orange)
POTENTIAL_PATH = "#e7298a"   # the path over a potential field (magenta: apart from every viridis colour)
LEGEND_COLUMNS = 4      # entries per legend row under a map
LEGEND_ROW = 0.2        # [in] height of a legend row at FONT_SIZE
ARROWS_ACROSS = 40      # vector-field arrows along the wider side of the view
PATHS_CELL = 0.05       # [m] raster of the world's obstacles behind overlaid trajectories
PATHS_MARGIN = 0.5      # [m] around the world's bounds (or the paths' extent)
# Tableau-10: distinct colours, readable on white and on a grey map
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
           "#17becf")

_LOCK = threading.RLock()


def _rgb(name: str) -> tuple[float, float, float]:
    r, g, b = COLORS[name]
    return (r / 255, g / 255, b / 255)


def figure_title(world: str, method: str, extra: str = "") -> str:
    """The one title convention of figures: "world - method" (the plugin's name), then `extra`."""
    return f"{world} - {method}" + (f" ({extra})" if extra else "")


def run_title(run: ExplorationRun, extra: str = "") -> str:
    """`figure_title` of a run: its world (or robot) and its method as registered, the same whether the run
    came from the CLI, a Lua script or a campaign."""
    return figure_title(run.info.world or "robot", run.info.method or type(run.explorer).__name__, extra)


def apart(est: npt.NDArray[np.float64] | None, true: npt.NDArray[np.float64] | None) -> bool:
    """Whether an estimated path (k, 2+) [m] is worth drawing beside the true one sampled at the same moments:
    somewhere more than EST_APART from it."""
    if est is None or true is None or len(est) != len(true) or len(est) < 2:
        return False
    return bool(np.hypot(est[:, 0] - true[:, 0], est[:, 1] - true[:, 1]).max() > EST_APART)


def _nice_length(span: float) -> float:
    """A 1-2-5 length [m] near a fifth of `span`."""
    target = max(span / 5, 1e-6)
    k = 10 ** math.floor(math.log10(target))
    return min((k * m for m in (1, 2, 5, 10)), key=lambda v: abs(v - target))


@contextlib.contextmanager
def _style() -> Iterator[None]:
    """matplotlib's defaults with the figures' text settings (text drawn when the figure is made takes them
    then), under the module's lock: matplotlib's settings are global to the process, so two threads never draw
    at once."""
    import matplotlib

    with _LOCK, matplotlib.rc_context():
        matplotlib.rcdefaults()         # a user's matplotlibrc (savefig.bbox: tight, a style) changes nothing here
        with matplotlib.rc_context({"font.size": FONT_SIZE, "axes.titlesize": FONT_SIZE + 1, "svg.fonttype": "none",
                                    "pdf.fonttype": 42, "svg.hashsalt": "robotexp"}):
            yield


def _points(name: str, value: npt.ArrayLike | None) -> npt.NDArray[np.float64]:
    if value is None:
        return np.zeros((0, 2))
    pts = np.asarray(value, np.float64)
    if pts.size == 0:
        return np.zeros((0, 2))
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ConfigError(f"map_figure: {name} must have shape (k, 2) [m], got {pts.shape}")
    return pts[np.all(np.isfinite(pts), axis=1)]


def _field(name: str, value: npt.ArrayLike, geo: GridGeometry, extra: tuple[int, ...] = ()
           ) -> npt.NDArray[np.float64]:
    arr = np.asarray(value, np.float64)
    if arr.shape != (geo.rows, geo.cols) + extra:
        raise ConfigError(f"map_figure: {name} has shape {arr.shape}, expected {(geo.rows, geo.cols) + extra} "
                          "(rows, cols of geo)")
    return arr


def map_figure(states: npt.ArrayLike, geo: GridGeometry, *, truth: npt.ArrayLike | None = None,  # noqa: PLR0913
               path: npt.ArrayLike | None = None, est_path: npt.ArrayLike | None = None,
               start: Pose | None = None, end: Pose | None = None, potential: npt.ArrayLike | None = None,
               vectors: npt.ArrayLike | None = None, laser: npt.ArrayLike | None = None, grid: bool = False,
               title: str | None = None, note: str | None = None, content: npt.ArrayLike | None = None,
               labels: tuple[str, str] = ("true path", "estimated path"), width: float = PAGE_WIDTH,
               others: Sequence[npt.ArrayLike] = ()) -> Figure:
    """An occupancy map as a thesis figure (see the module's docstring).

    Args:
        states: int (rows, cols): -1 unknown, 0 free, 100 occupied (row 0 = smallest y).
        geo: its geometry.
        truth: bool (rows, cols) ground-truth obstacles: those not marked occupied are drawn in slate.
        path: (k, 2) [m] the robot's (true) path.
        est_path: (k, 2) [m] the path the explorer believed (odometry or localization), drawn dashed beside
            `path` and both labelled ("true path", "estimated path").
        start, end: poses drawn as green and red discs with a heading tick.
        potential: (rows, cols) values on free cells, with a colour bar: a potential in [0, 1] (0 at the
            goals, 1 at obstacles, as BVP's) spanning more than two decades of 1 - p is drawn as 1 - p on a
            log scale (a harmonic potential falls off exponentially from its goals), any other linearly.
        vectors: (rows, cols, 2) a vector field (x, y) drawn as unit arrows on a lattice of free cells.
        laser: (n, 2) [m] the last scan's hits (orange dots).
        grid: draw cell edges (lines every metre when more than 120 cells would be crossed).
        title: the figure's title (`figure_title`).
        note: a second title line; default "cell N mm".
        content: bool (rows, cols) the cells that matter (default: the known ones); the view is cropped to
            them and the path (`robotexp.output.render.content_window`).
        labels: the legend's names of `path` and `est_path` when both are drawn (a CARMEN log's reference poses
            are "logged path").
        width: [in] the figure's width.
        others: (k, 2) [m] paths of a team's other robots: each in its colour (`TEAM_COLORS`), a disc where it
            ends, and in the legend as "robot 2", "robot 3", ... (`path` is then "robot 1").

    Raises:
        ConfigError: arrays of the wrong shape.
    """
    with _style():
        return _map_figure(states, geo, truth=truth, path=path, est_path=est_path, start=start, end=end,
                           potential=potential, vectors=vectors, laser=laser, grid=grid, title=title, note=note,
                           content=content, labels=labels, width=width, others=others)


def _potential_layer(fig: Figure, ax: Axes, cbar: Axes | None, potential: npt.ArrayLike, geo: GridGeometry,
                     free: npt.NDArray[np.bool_], extent: tuple[float, float, float, float]) -> None:
    from matplotlib.colors import LogNorm, Normalize

    pot = _field("potential", potential, geo)
    ok = free & np.isfinite(pot)
    vals = pot[ok]
    q = 1.0 - vals
    log = bool(vals.size) and float(vals.min()) >= 0.0 and float(vals.max()) <= 1.0 and bool((q > 0).any())
    if log:
        lo = float(q[q > 0].min())
        log = lo < 1e-2 * float(q.max())
    if log:
        shown = np.ma.masked_where(~ok | (pot >= 1.0), 1.0 - pot)
        norm: Any = LogNorm(vmin=max(lo, 1e-300), vmax=float(q.max()))
        label = "1 - potential (log scale; 1 at the goals)"
    else:
        shown = np.ma.masked_where(~ok, pot)
        norm = Normalize(vmin=float(vals.min()) if vals.size else 0.0, vmax=float(vals.max()) if vals.size else 1.0)
        label = "potential"
    im = ax.imshow(shown, origin="lower", extent=extent, interpolation="nearest", cmap="viridis", norm=norm)
    fig.colorbar(im, cax=cbar, label=label)


def _vector_layer(ax: Axes, vectors: npt.ArrayLike, geo: GridGeometry, free: npt.NDArray[np.bool_],
                  window: GridGeometry) -> None:
    vec = _field("vectors", vectors, geo, (2,))
    step = max(1, math.ceil(max(window.rows, window.cols) / ARROWS_ACROSS))
    r = np.arange(step // 2, geo.rows, step)
    c = np.arange(step // 2, geo.cols, step)
    rr, cc = np.meshgrid(r, c, indexing="ij")
    v = vec[rr, cc]
    norm = np.hypot(v[..., 0], v[..., 1])
    ok = free[rr, cc] & np.isfinite(norm) & (norm > 0)
    if not ok.any():
        return
    x, y = geo.origin_x + (cc[ok] + 0.5) * geo.cell, geo.origin_y + (rr[ok] + 0.5) * geo.cell
    u, w = v[..., 0][ok] / norm[ok], v[..., 1][ok] / norm[ok]
    length = 0.7 * step * geo.cell
    ax.quiver(x, y, u * length, w * length, angles="xy", scale_units="xy", scale=1, pivot="middle",
              color=_rgb("vector"), width=0.0025, headwidth=4, zorder=3)


def _scale_bar(ax: Axes, width: float, height: float) -> None:
    """A 1-2-5 scale bar near a tenth of the view's `width` [m], above the map's upper right corner (the title
    is left-aligned), or beside it when the map was narrowed to fit, so it never hides a part of the map."""
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar   # untyped: Any ([tool.mypy] overrides)

    length = _nice_length(width / 2)
    # a map narrowed to fit the figure's height leaves room on its right, and its title runs past the axes'
    # right edge: the bar goes beside the map's upper right corner instead of above it
    beside = ax.get_position().x1 < 0.8
    ax.add_artist(AnchoredSizeBar(ax.transData, length, f"{length:g} m", "upper left" if beside else "lower right",
                                  pad=0.1, borderpad=0.2, color="black", frameon=False, size_vertical=height / 120,
                                  label_top=True, bbox_to_anchor=(1.02, 1.0) if beside else (1.0, 1.0),
                                  bbox_transform=ax.transAxes, fontproperties={"size": FONT_SIZE}))


def _map_axes(figure: Any, width: float, aspect: float, *, legend_rows: int, colour_bar: bool
              ) -> tuple[Figure, Axes, Axes | None]:
    """A figure `width` [in] wide holding map axes of `aspect` (height / width) with fixed margins (no layout
    engine: it costs more than the drawing): title above, tick labels and axis labels left and below, the legend
    in `legend_rows` rows at the bottom, and the axes of a colour bar on the right when asked. The figure is as
    tall as the map needs, at most 1.6 x `width` (a tall map is then narrower)."""
    left, right, top = 0.7, (1.25 if colour_bar else 0.15), 0.55
    bottom = 0.55 + LEGEND_ROW * legend_rows + 0.1
    axes_w = width - left - right
    axes_h = axes_w * aspect
    height = min(top + axes_h + bottom, 1.6 * width)
    if top + axes_h + bottom > height:          # too tall: narrower axes of the same aspect, centred
        axes_h = height - top - bottom
        axes_w = axes_h / aspect
        left = (width - right - axes_w + left) / 2
    fig = figure(figsize=(width, height))
    ax = fig.add_axes((left / width, bottom / height, axes_w / width, axes_h / height))
    cbar = fig.add_axes(((left + axes_w + 0.2) / width, (bottom + 0.1 * axes_h) / height, 0.15 / width,
                         0.8 * axes_h / height)) if colour_bar else None
    return fig, ax, cbar


def _grid_lines(ax: Axes, geo: GridGeometry, x0: float, x1: float, y0: float, y1: float) -> None:
    step = geo.cell if max(x1 - x0, y1 - y0) / geo.cell <= 120 else 1.0
    xs = geo.origin_x + step * np.arange(math.ceil((x0 - geo.origin_x) / step),
                                         math.floor((x1 - geo.origin_x) / step) + 1)
    ys = geo.origin_y + step * np.arange(math.ceil((y0 - geo.origin_y) / step),
                                         math.floor((y1 - geo.origin_y) / step) + 1)
    kw: dict[str, Any] = {"color": _rgb("grid"), "linewidth": 0.3, "alpha": 0.6, "zorder": 1.5}
    ax.vlines(xs, y0, y1, **kw)
    ax.hlines(ys, x0, x1, **kw)


def _map_figure(states: npt.ArrayLike, geo: GridGeometry, *, truth: npt.ArrayLike | None,  # noqa: PLR0913
                path: npt.ArrayLike | None, est_path: npt.ArrayLike | None, start: Pose | None, end: Pose | None,
                potential: npt.ArrayLike | None, vectors: npt.ArrayLike | None, laser: npt.ArrayLike | None,
                grid: bool, title: str | None, note: str | None, content: npt.ArrayLike | None,
                labels: tuple[str, str], width: float, others: Sequence[npt.ArrayLike] = ()) -> Figure:
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    cells = np.asarray(states)
    if cells.shape != (geo.rows, geo.cols):
        raise ConfigError(f"map_figure: states has shape {cells.shape} but geo is {geo.rows} x {geo.cols}")
    rgb = np.empty((*cells.shape, 3), np.uint8)
    rgb[:] = COLORS["unknown"]
    free = (cells >= 0) & (cells < 50)
    rgb[free] = COLORS["free"]
    rgb[cells >= 50] = COLORS["occupied"]
    missed = None
    if truth is not None:
        missed = (_field("truth", truth, geo) != 0) & (cells < 50)
        rgb[missed] = COLORS["truth"]
    pts, est, hits = _points("path", path), _points("est_path", est_path), _points("laser", laser)
    team = [_points("others", o) for o in others]
    poses = np.array([(p.x, p.y) for p in (start, end) if p is not None]).reshape(-1, 2)
    view = content_window(_field("content", content, geo) != 0 if content is not None else cells >= 0, geo,
                          np.vstack([pts, est, poses, *team]))
    x0, y0 = view.origin_x, view.origin_y
    x1, y1 = x0 + view.cols * view.cell, y0 + view.rows * view.cell
    n_legend = 3 + (missed is not None and bool(missed.any())) + (len(pts) >= 2) + (len(est) >= 2 and len(pts) >= 2) \
        + bool(len(hits)) + (start is not None) + (end is not None) + sum(len(t) >= 2 for t in team)
    fig, ax, cbar = _map_axes(Figure, width, (y1 - y0) / (x1 - x0), legend_rows=math.ceil(n_legend / LEGEND_COLUMNS),
                              colour_bar=potential is not None)
    extent = (geo.origin_x, geo.origin_x + geo.cols * geo.cell, geo.origin_y, geo.origin_y + geo.rows * geo.cell)
    ax.imshow(rgb, origin="lower", extent=extent, interpolation="antialiased")
    handles: list[Any] = [Patch(facecolor=_rgb("free"), edgecolor="0.5", label="free"),
                          Patch(facecolor=_rgb("occupied"), label="occupied"),
                          Patch(facecolor=_rgb("unknown"), label="unknown")]
    if missed is not None and missed.any():
        handles.append(Patch(facecolor=_rgb("truth"), label="obstacle not mapped"))
    if potential is not None:
        _potential_layer(fig, ax, cbar, potential, geo, free, extent)
    if grid:
        _grid_lines(ax, geo, x0, x1, y0, y1)
    if vectors is not None:
        _vector_layer(ax, vectors, geo, free, view)
    two = len(est) >= 2 and len(pts) >= 2
    line = POTENTIAL_PATH if potential is not None else _rgb("path")    # blue is lost on viridis
    if len(pts) >= 2:
        ax.plot(pts[:, 0], pts[:, 1], color=line, linewidth=1.2, zorder=4)
        handles.append(Line2D([], [], color=line, linewidth=1.2,
                              label="robot 1" if team else labels[0] if two else "path"))
    for i, other in enumerate(team):        # a team's other robots
        if len(other) >= 2:
            r, g, b = TEAM_COLORS[i % len(TEAM_COLORS)]         # as the view and the video draw this robot
            colour = (r / 255, g / 255, b / 255)
            ax.plot(other[:, 0], other[:, 1], color=colour, linewidth=1.0, zorder=4)
            ax.plot(other[-1:, 0], other[-1:, 1], "o", color=colour, markersize=5, markeredgecolor="white", zorder=5)
            handles.append(Line2D([], [], color=colour, linewidth=1.0, label=f"robot {i + 2}"))
    if two:
        ax.plot(est[:, 0], est[:, 1], color=_rgb("laser"), linewidth=1.0, linestyle=(0, (4, 2)), zorder=4)
        handles.append(Line2D([], [], color=_rgb("laser"), linewidth=1.0, linestyle=(0, (4, 2)),
                              label=labels[1]))
    if len(hits):
        ax.plot(hits[:, 0], hits[:, 1], ".", color=LASER, markersize=2, zorder=4)
        handles.append(Line2D([], [], marker=".", linestyle="", color=LASER, label="laser"))
    tick = 0.04 * max(x1 - x0, y1 - y0)
    for pose, name in ((start, "start"), (end, "end")):
        if pose is not None:
            ax.plot([pose.x, pose.x + tick * math.cos(pose.theta)], [pose.y, pose.y + tick * math.sin(pose.theta)],
                    color=_rgb(name), linewidth=1.5, zorder=5)
            ax.plot([pose.x], [pose.y], "o", color=_rgb(name), markersize=6, markeredgecolor="white", zorder=5)
            handles.append(Line2D([], [], marker="o", linestyle="", color=_rgb(name), label=name))
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_facecolor(_rgb("unknown"))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    _scale_bar(ax, x1 - x0, y1 - y0)
    fig.legend(handles=handles, loc="lower center", bbox_to_anchor=(0.5, 0.0), ncol=min(len(handles), LEGEND_COLUMNS),
               frameon=False, borderaxespad=0.3)
    detail = note if note is not None else f"cell {geo.cell * 1000:g} mm"
    if title or detail:
        ax.set_title("\n".join(t for t in (title, detail) if t), loc="left")
    return fig


def run_map_figure(run: ExplorationRun, *, show: Sequence[str] = (), potential: bool = False,
                   path: bool = True, width: float = PAGE_WIDTH) -> Figure:
    """`map_figure` of a run that ended: its map, ground truth, path (the estimated path too where it differs
    from the true one), start and end, and the `show` overlays (grid, laser, vectors, potential; `potential`
    True is the same as naming it), titled by `run_title` with the cell size, path length, coverage and ATE
    under it."""

    m = run.metrics
    states = run.grid.states()
    state = run.state
    overlays = run.explorer.overlays()
    wanted = set(show) | ({"potential"} if potential else set())
    true_path = np.array(m.path) if m.path and path else None
    est = np.array(m.estimated) if m.estimated and path else None
    if not apart(est, true_path):
        est = None
    laser = laser_hits(run) if "laser" in wanted else None
    parts = [f"cell {run.grid.geo.cell * 1000:g} mm", f"path {m.path_length:.1f} m"]
    cov = run.coverage()
    if cov is not None:
        parts.append(f"coverage {cov * 100:.1f} %")
    ate = run.info.extra.get("ate_m")
    if est is not None and isinstance(ate, (int, float)):
        parts.append(f"ATE {ate:.2f} m")
    paths = [np.asarray(p, np.float64).reshape(-1, 2) for p in getattr(run, "paths", [])] if path else []
    if len(paths) > 1:
        parts.append(f"{len(paths)} robots")
    fig = map_figure(states, run.grid.geo, truth=None if run.truth is None else run.truth.occupied,
                     path=true_path, est_path=est, start=run.start_pose,
                     end=None if state is None else (state.true_pose or state.pose),
                     potential=overlays.get("potential") if "potential" in wanted else None,
                     vectors=overlays.get("vectors") if "vectors" in wanted else None,
                     laser=laser, grid="grid" in wanted,
                     content=(states >= 0) if run.truth is None else (states >= 0) | run.truth.explorable,
                     title=run_title(run), note=", ".join(parts), width=width, others=paths[1:])
    return fig


def curve_figure(series: Sequence[tuple[str, npt.ArrayLike, npt.ArrayLike]], *, xlabel: str, ylabel: str,
                 title: str, hlines: Sequence[float] = (), ylim: tuple[float, float] | None = None,
                 width: float = PAGE_WIDTH) -> Figure:
    """Curves (label, xs, ys), one colour per label (runs sharing a label share its colour and legend
    entry), dashed reference lines at `hlines` labelled at the right, `xlabel`/`ylabel` with their units.
    The x axis starts at 0.

    Raises:
        ConfigError: xs and ys of different lengths, no series.
    """
    if not series:
        raise ConfigError("curve_figure: no curve to draw")
    with _style():
        from matplotlib.figure import Figure

        height = width * 0.5                # fixed margins [in] (no layout engine: it costs more than the drawing)
        fig = Figure(figsize=(width, height))
        ax = fig.add_axes((0.75 / width, 0.5 / height, (width - 0.75 - 0.5) / width, (height - 0.5 - 0.3) / height))
        colours: dict[str, str] = {}
        right = 0.0
        for label, xs, ys in series:
            x, y = np.asarray(xs, np.float64).ravel(), np.asarray(ys, np.float64).ravel()
            if x.shape != y.shape:
                raise ConfigError(f"curve_figure: {label!r} has {x.size} x values but {y.size} y values")
            first = label not in colours
            colour = colours.setdefault(label, PALETTE[len(colours) % len(PALETTE)])
            ax.plot(x, y, color=colour, linewidth=1.2, alpha=0.85, label=label if first else "_")
            if x.size and np.isfinite(x).any():
                right = max(right, float(np.nanmax(x)))
        unit = " %" if "[%]" in ylabel else ""
        for v in hlines:
            ax.axhline(v, color="0.55", linewidth=0.8, linestyle=(0, (4, 3)), zorder=0)
            ax.annotate(f"{v:g}{unit}", (1, v), xycoords=("axes fraction", "data"), xytext=(3, 0),
                        textcoords="offset points", va="center", color="0.4", fontsize=FONT_SIZE - 1)
        ax.set_xlim(0, right if right > 0 else 1)
        if ylim is not None:
            ax.set_ylim(*ylim)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        ax.grid(color="0.9")
        ax.set_axisbelow(True)
        if len(colours) > 1:
            ax.legend(loc="lower right", frameon=True, fontsize=FONT_SIZE - 1)
        return fig


def run_coverage_figure(run: ExplorationRun, width: float = PAGE_WIDTH) -> Figure | None:
    """The coverage curve of a run over robot time (None when coverage is unknown: no ground truth)."""
    curve = run.metrics.curve
    if not curve or curve[-1][2] < 0:
        return None
    minutes = curve[-1][0] > 300
    ts = [c[0] / (60 if minutes else 1) for c in curve]
    return curve_figure([("coverage", ts, [c[2] * 100 for c in curve])],
                        xlabel="robot time [min]" if minutes else "robot time [s]",
                        ylabel=f"coverage [%] ({run.grid.geo.cell * 1000:g} mm cells)",
                        title=f"{run_title(run)}: coverage of the explorable free space", hlines=(90, 95, 99),
                        ylim=(0, 100), width=width)


def paths_figure(world: World | None, runs: Sequence[tuple[str, npt.ArrayLike]], *, title: str,
                 notes: Sequence[str] = (), width: float = PAGE_WIDTH) -> Figure:
    """Several runs' trajectories over a world's ground-truth obstacles (rasterised on `PATHS_CELL` cells),
    one colour per run (a dot at its start), a legend naming the runs in order, axes in metres and a scale
    bar; `notes` are lines under the legend. Without a world (or bounds) the view fits the paths.

    Raises:
        ConfigError: a points array not of shape (k, 2), no run.
    """
    if not runs:
        raise ConfigError("paths_figure: no path to draw")
    arrays = []
    for label, pts in runs:
        a = np.asarray(pts, np.float64)
        if a.ndim != 2 or a.shape[1] != 2:
            raise ConfigError(f"paths_figure: the points of {label!r} must have shape (k, 2) [m], got {a.shape}")
        arrays.append(a[np.all(np.isfinite(a), axis=1)])
    allp = np.concatenate([a for a in arrays if len(a)] or [np.zeros((1, 2))])
    if world is not None and world.bounds is not None:
        from robotexp.world.groundtruth import occupancy

        geo = GridGeometry.covering(*world.bounds, cell=PATHS_CELL, margin=PATHS_MARGIN)
        walls = occupancy(world, geo)
    else:
        geo = GridGeometry.covering(float(allp[:, 0].min()), float(allp[:, 1].min()), float(allp[:, 0].max()),
                                    float(allp[:, 1].max()), cell=PATHS_CELL, margin=PATHS_MARGIN)
        walls = np.zeros((geo.rows, geo.cols), bool)
    with _style():
        from matplotlib.figure import Figure
        from matplotlib.lines import Line2D
        from matplotlib.patches import Patch

        x0, x1 = geo.origin_x, geo.origin_x + geo.cols * geo.cell
        y0, y1 = geo.origin_y, geo.origin_y + geo.rows * geo.cell
        fig, ax, _ = _map_axes(Figure, width, (y1 - y0) / (x1 - x0),
                               legend_rows=math.ceil((1 + len(runs) + len(notes)) / 2), colour_bar=False)
        ax.imshow(np.where(walls, 0.2, 1.0), origin="lower", extent=(x0, x1, y0, y1), cmap="gray", vmin=0, vmax=1,
                  interpolation="antialiased")
        handles: list[Any] = [Patch(facecolor="0.2", label=f"obstacles ({PATHS_CELL * 1000:g} mm cells)")]
        for i, ((label, _), a) in enumerate(zip(runs, arrays, strict=True)):
            colour = PALETTE[i % len(PALETTE)]
            if len(a):
                ax.plot(a[:, 0], a[:, 1], color=colour, linewidth=1.0, alpha=0.9)
                ax.plot(a[:1, 0], a[:1, 1], "o", color=colour, markersize=5, markeredgecolor="white")
            handles.append(Line2D([], [], color=colour, linewidth=1.5, label=label))
        handles += [Line2D([], [], linestyle="", label=text) for text in notes]
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        _scale_bar(ax, x1 - x0, y1 - y0)
        fig.legend(handles=handles, loc="lower center", bbox_to_anchor=(0.5, 0.0), ncol=min(len(handles), 2),
                   frameon=False, borderaxespad=0.3)
        ax.set_title(title, loc="left")
        return fig


def box_figure(groups: Sequence[tuple[str, npt.ArrayLike]], *, ylabel: str, title: str,
               width: float = PAGE_WIDTH, seed: int = 0) -> Figure:
    """Box plots with every value as a point (see the module's docstring); `ylabel` names the
    quantity with its unit ("path length [m]").

    Raises:
        ConfigError: no group.
    """
    if not groups:
        raise ConfigError("box_figure: no group to draw")
    with _style():
        return _box_figure(groups, ylabel=ylabel, title=title, width=width, seed=seed)


def _box_figure(groups: Sequence[tuple[str, npt.ArrayLike]], *, ylabel: str, title: str, width: float,
                seed: int) -> Figure:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, width * 0.55), layout="constrained")
    ax = fig.add_subplot()
    rng = np.random.default_rng(seed)
    top = 0.0
    for i, (_, values) in enumerate(groups, start=1):
        v = np.asarray(values, np.float64)
        v = v[np.isfinite(v)]
        if len(v) >= MIN_BOX:
            ax.boxplot([v], positions=[i], widths=0.5, showfliers=False,
                       medianprops={"color": _rgb("end")}, boxprops={"color": "0.3"})
        if len(v):
            ax.plot(i + rng.uniform(-0.12, 0.12, len(v)), v, "o", color=_rgb("path"), alpha=0.7, markersize=4)
            top = max(top, float(v.max()))
    ax.set_xticks(range(1, len(groups) + 1),
                  [f"{label}\nn = {np.count_nonzero(np.isfinite(np.asarray(v, np.float64)))}" for label, v in groups])
    ax.set_xlim(0.4, len(groups) + 0.6)
    ax.set_ylim(0, top * 1.08 if top > 0 else 1)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(axis="y", color="0.85")
    ax.set_axisbelow(True)
    return fig


def save_figure(fig: Figure, stem: Path, formats: Sequence[str] = FORMATS, dpi: float = DPI) -> list[Path]:
    """Write `fig` as stem.png, stem.svg and stem.pdf (the `formats` given); returns the paths.

    Raises:
        ConfigError: an unknown format.
    """
    bad = sorted(set(formats) - set(FORMATS))
    if bad:
        raise ConfigError(f"figure format(s) {', '.join(bad)} unknown; use {', '.join(FORMATS)}")
    return [write_figure(fig, stem.with_name(f"{stem.name}.{fmt}"), fmt, dpi) for fmt in formats]


def write_figure(fig: Figure, path: Path, fmt: str = "png", dpi: float = DPI) -> Path:
    """Write `fig` to `path` as `fmt` (png, svg, pdf; PNG pixels: `dpi` per inch of the figure), creating
    missing parent folders; returns `path`.

    Raises:
        ConfigError: an unknown format.
    """
    if fmt not in FORMATS:
        raise ConfigError(f"figure format {fmt!r} unknown; use {', '.join(FORMATS)}")
    path.parent.mkdir(parents=True, exist_ok=True)
    _displayable_texts(fig)
    with _style():
        fig.savefig(path, dpi=dpi, format=fmt)
    return path


def displayable(text: str) -> str:
    """`text` with the lone surrogates a file name that is not UTF-8 decodes to (os.fsdecode of
    b"map\xff") as U+FFFD: no font draws them, and SVG and PDF cannot encode them."""
    try:
        text.encode("utf-8")
        return text
    except UnicodeEncodeError:
        try:
            raw = text.encode("utf-8", "surrogateescape")
        except UnicodeEncodeError:
            raw = text.encode("utf-8", "replace")
        return raw.decode("utf-8", "replace")


def _displayable_texts(fig: Figure) -> None:
    """Every text of `fig` (titles, labels, ticks, legends) made `displayable`."""
    from matplotlib.text import Text

    for artist in fig.findobj(Text):
        assert isinstance(artist, Text)
        text = artist.get_text()
        shown = displayable(text)
        if shown != text:
            artist.set_text(shown)


def save_run_figures(run: ExplorationRun, out: Path, name: str, formats: Sequence[str] = ("png",),
                     show: Sequence[str] = ()) -> tuple[Path, Path | None]:
    """A run's map figure (`run_map_figure` with the `show` overlays) as out/NAME.png (and .svg/.pdf, the
    `formats` given) and its coverage figure as out/NAME.coverage.png (etc.; none without ground truth).
    Returns the two PNG paths (or the first format's)."""
    maps = save_figure(run_map_figure(run, show=show), out / name, formats)
    cov = run_coverage_figure(run)
    plots = save_figure(cov, out / f"{name}.coverage", formats) if cov is not None else [None]
    return maps[0], plots[0]


METRICS = (("coverage", "coverage [%]", 100.0), ("path_length_m", "path length [m]", 1.0),
           ("robot_time_s", "robot time [s]", 1.0), ("visited_cells", "visited cells [cells]", 1.0))


def campaign_figures(records: Sequence[Any], out: Path, formats: Sequence[str] = FORMATS, *,
                     include_incomplete: bool = False) -> list[Path]:
    """Box figures of a campaign's records: per world (and cell size), one per metric of `METRICS`,
    one box per method; written as out/box_<metric>_<world>.<format> (the world as `safe_name` makes it a
    file name). Returns the paths.

    The runs are those `robotexp campaign report` and `campaign plot` count: interrupted runs are left
    out, and runs cut short (time limit, stalled, ...) unless `include_incomplete`.

    Raises:
        ConfigError: no record, or no run left to draw.
    """
    from robotexp.run.record import EndReason, RunRecord
    from robotexp.output.safefile import safe_name

    every = [r if isinstance(r, RunRecord) else RunRecord.from_dict(r) for r in records]
    if not every:
        raise ConfigError("no run to draw: the results file has no usable record")
    finished = [r for r in every if r.end is not EndReason.INTERRUPTED]
    recs = [r for r in finished if include_incomplete or r.completed]
    if not recs:
        raise ConfigError(f"no run to draw: of {len(every)} run(s), {len(every) - len(finished)} were interrupted "
                          f"and {len(finished)} cut short (--include-incomplete draws the runs cut short)")
    written: list[Path] = []
    by_world: dict[tuple[str, float], list[RunRecord]] = {}
    for r in recs:
        by_world.setdefault((r.world, r.cell_m or 0.0), []).append(r)
    for (world, cell), runs in sorted(by_world.items()):
        methods = sorted({r.method for r in runs})
        for key, label, factor in METRICS:
            groups = [(m, [float(r[key]) * factor for r in runs if r.method == m and r[key] is not None])
                      for m in methods]
            if not any(len(v) for _, v in groups):
                continue
            title = f"{world} - {label.split(' [')[0]}" + (f" (cell {cell * 1000:g} mm)" if cell else "")
            fig = box_figure(groups, ylabel=label, title=title)
            written += save_figure(fig, out / f"box_{key}_{safe_name(world)}", formats)   # a world: one file name
    return written
