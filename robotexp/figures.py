"""Figures for a thesis, on matplotlib: vector (SVG, PDF) and raster (PNG) output, text in points at a
page's width, axes with units. The fast raster path (`robotexp.render`) stays for frames and the live view.

`map_figure`: an occupancy map cropped to its content and path, with a legend (free, occupied, unknown,
obstacles not mapped, path, start, end), axes in metres, a scale bar and, for a potential field, a
colour bar. `box_figure`: one box per group with every run drawn as a point over it (a group of fewer
than `MIN_BOX` runs gets its points only: a box of two values says nothing), the y axis from 0 with its
unit, n under each label. Titles follow one convention: "world - method" with the plugin's name
(`figure_title`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.mapping.geometry import GridGeometry
from robotexp.render import COLORS, content_window

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from robotexp.explorer import ExplorationRun
    from robotexp.robot import Pose

__all__ = ["map_figure", "run_map_figure", "box_figure", "campaign_figures", "save_figure", "figure_title",
           "FORMATS", "PAGE_WIDTH"]

FORMATS = ("png", "svg", "pdf")
PAGE_WIDTH = 6.3        # [in] a thesis's text width (16 cm): figures are drawn at it, text in points
FONT_SIZE = 9           # [pt]
MIN_BOX = 5             # fewer runs than this in a group: points only, no box


def _rgb(name: str) -> tuple[float, float, float]:
    r, g, b = COLORS[name]
    return (r / 255, g / 255, b / 255)


def figure_title(world: str, method: str, extra: str = "") -> str:
    """The one title convention of figures: "world - method" (the plugin's name), then `extra`."""
    return f"{world} - {method}" + (f" ({extra})" if extra else "")


def _nice_length(span: float) -> float:
    """A 1-2-5 length [m] near a fifth of `span`."""
    target = max(span / 5, 1e-6)
    k = 10 ** math.floor(math.log10(target))
    return min((k * m for m in (1, 2, 5, 10)), key=lambda v: abs(v - target))


def _style() -> Any:
    """The figures' text settings (text drawn when the figure is made takes them then)."""
    import matplotlib

    return matplotlib.rc_context({"font.size": FONT_SIZE, "svg.fonttype": "none", "pdf.fonttype": 42})


def map_figure(states: npt.ArrayLike, geo: GridGeometry, *, truth: npt.ArrayLike | None = None,
               path: npt.ArrayLike | None = None, start: Pose | None = None, end: Pose | None = None,
               potential: npt.ArrayLike | None = None, title: str | None = None,
               content: npt.ArrayLike | None = None, width: float = PAGE_WIDTH) -> Figure:
    """An occupancy map as a thesis figure (see the module's docstring).

    Args:
        states: int (rows, cols): -1 unknown, 0 free, 100 occupied (row 0 = smallest y).
        geo: its geometry.
        truth: bool (rows, cols) ground-truth obstacles: those not marked occupied are drawn in slate.
        path: (k, 2) [m] the robot's path.
        start, end: poses drawn as green and red discs.
        potential: (rows, cols) values on free cells, drawn with viridis and a colour bar.
        title: the figure's title.
        content: bool (rows, cols) the cells that matter (default: the known ones); the view is cropped to
            them and the path (`robotexp.render.content_window`).
        width: [in] the figure's width.

    Raises:
        ConfigError: arrays of the wrong shape.
    """
    with _style():
        return _map_figure(states, geo, truth=truth, path=path, start=start, end=end, potential=potential,
                           title=title, content=content, width=width)


def _map_figure(states: npt.ArrayLike, geo: GridGeometry, *, truth: npt.ArrayLike | None,
                path: npt.ArrayLike | None, start: Pose | None, end: Pose | None, potential: npt.ArrayLike | None,
                title: str | None, content: npt.ArrayLike | None, width: float) -> Figure:
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar  # type: ignore[import-untyped]

    grid = np.asarray(states)
    if grid.shape != (geo.rows, geo.cols):
        raise ConfigError(f"map_figure: states has shape {grid.shape} but geo is {geo.rows} x {geo.cols}")
    rgb = np.empty((*grid.shape, 3))
    rgb[:] = _rgb("unknown")
    free = (grid >= 0) & (grid < 50)
    rgb[free] = _rgb("free")
    rgb[grid >= 50] = _rgb("occupied")
    missed = None
    if truth is not None:
        missed = (np.asarray(truth) != 0) & (grid < 50)
        rgb[missed] = _rgb("truth")
    pts = np.zeros((0, 2)) if path is None else np.asarray(path, np.float64).reshape(-1, 2)
    extra = np.vstack([pts, np.array([(p.x, p.y) for p in (start, end) if p is not None]).reshape(-1, 2)])
    window = content_window(np.asarray(content) != 0 if content is not None else grid >= 0, geo, extra)
    x0, y0 = window.origin_x, window.origin_y
    x1, y1 = x0 + window.cols * window.cell, y0 + window.rows * window.cell
    aspect = (y1 - y0) / (x1 - x0)
    fig = Figure(figsize=(width, min(width * aspect + 1.3, 1.6 * width)), layout="constrained")
    ax = fig.add_subplot()
    extent = (geo.origin_x, geo.origin_x + geo.cols * geo.cell, geo.origin_y, geo.origin_y + geo.rows * geo.cell)
    ax.imshow(rgb, origin="lower", extent=extent, interpolation="nearest")
    if potential is not None:
        pot = np.ma.masked_where(~free, np.asarray(potential, np.float64))
        im = ax.imshow(pot, origin="lower", extent=extent, interpolation="nearest", cmap="viridis")
        fig.colorbar(im, ax=ax, label="potential", shrink=0.8)
    ax.set_facecolor(_rgb("unknown"))
    handles: list[Any] = [Patch(facecolor=_rgb("free"), edgecolor="0.5", label="free"),
                          Patch(facecolor=_rgb("occupied"), label="occupied"),
                          Patch(facecolor=_rgb("unknown"), label="unknown")]
    if missed is not None:
        handles.append(Patch(facecolor=_rgb("truth"), label="obstacle not mapped"))
    if len(pts) >= 2:
        ax.plot(pts[:, 0], pts[:, 1], color=_rgb("path"), linewidth=1.2)
        handles.append(Line2D([], [], color=_rgb("path"), linewidth=1.2, label="path"))
    for pose, name in ((start, "start"), (end, "end")):
        if pose is not None:
            ax.plot([pose.x], [pose.y], "o", color=_rgb(name), markersize=6, markeredgecolor="white")
            handles.append(Line2D([], [], marker="o", linestyle="", color=_rgb(name), label=name))
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    length = _nice_length(x1 - x0)
    ax.add_artist(AnchoredSizeBar(ax.transData, length, f"{length:g} m", "lower right", pad=0.4,
                                  color="black", frameon=True, size_vertical=(y1 - y0) / 150,
                                  fontproperties={"size": FONT_SIZE}))
    fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 4), frameon=False)
    if title:
        ax.set_title(f"{title}\ncell {geo.cell * 1000:g} mm")
    return fig


def run_map_figure(run: ExplorationRun, *, potential: bool = False, width: float = PAGE_WIDTH) -> Figure:
    """`map_figure` of a run that ended: its map, ground truth, path, start and end, titled by
    `figure_title` (with the potential field of explorers that have one, when asked)."""
    states = run.grid.states()
    state = run.state
    pot = run.explorer.overlays().get("potential") if potential else None
    return map_figure(states, run.grid.geo, truth=None if run.truth is None else run.truth.occupied,
                      path=np.array(run.metrics.path) if run.metrics.path else None, start=run.start_pose,
                      end=None if state is None else (state.true_pose or state.pose), potential=pot,
                      content=(states >= 0) if run.truth is None else (states >= 0) | run.truth.explorable,
                      title=figure_title(run.info.world, run.info.method), width=width)


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


def save_figure(fig: Figure, stem: Path, formats: Sequence[str] = FORMATS, dpi: int = 200) -> list[Path]:
    """Write `fig` as stem.png, stem.svg and stem.pdf (the `formats` given); returns the paths.

    Raises:
        ConfigError: an unknown format.
    """
    bad = sorted(set(formats) - set(FORMATS))
    if bad:
        raise ConfigError(f"figure format(s) {', '.join(bad)} unknown; use {', '.join(FORMATS)}")
    out = []
    with _style():
        for fmt in formats:
            path = stem.with_name(f"{stem.name}.{fmt}")
            fig.savefig(path, dpi=dpi)
            out.append(path)
    return out


METRICS = (("coverage", "coverage [%]", 100.0), ("path_length_m", "path length [m]", 1.0),
           ("robot_time_s", "robot time [s]", 1.0))


def campaign_figures(records: Sequence[Any], out: Path, formats: Sequence[str] = FORMATS) -> list[Path]:
    """Box figures of a campaign's records: per world (and cell size), one per metric of `METRICS`,
    one box per method; written as out/box_<metric>_<world>.<format>. Returns the paths.

    Raises:
        ConfigError: no record.
    """
    from robotexp.record import RunRecord

    recs = [r if isinstance(r, RunRecord) else RunRecord.from_dict(r) for r in records]
    if not recs:
        raise ConfigError("no run to draw: the results file has no record")
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
            written += save_figure(fig, out / f"box_{key}_{world}", formats)
    return written
