"""Santos's target study: objective surfaces and GA / firefly distance to the optimum at map states.

Santos 2016, section 5 (Figs. 10-17 and 18-25): the objective surface of each form "at a given moment
of the exploration", and, on the proportional form, how far the GA and firefly (FA) targets lie from
the exhaustive optimum ("the FA gives targets closer to the cell evaluated as optimal"; "the GA
points are not of low quality, they are local optima, given the multi-modal objective"). The thesis
names neither the map states nor the number of GA / FA runs per state (each of Figs. 18-25 shows one
optimum, one FA and one GA target, in green, blue and yellow); ours are fixed here.

Map states: one run of `meta-exhaustive` per built-in world (dense, sparse) at Santos's 5 cm cell,
seed 0, the world's default start, mapped over the world plus 1 m (442 x 342 and 642 x 442 cells).
The states are the moments the coverage first reaches 20, 40, 60 and 80 % (early to late, 8 states
in all, as many as Santos's 8 tests): chosen by coverage rather than time so the two worlds are
compared at the same progress; meta-exhaustive rather than frontier because Santos's states come
from runs driven by the objective itself (its VISITED trail is the one the objective sees), and
rather than meta-ga / meta-firefly so the states do not depend on the searches studied. The run
stops once the last state is taken.

At each state the objective is built exactly as the metaheuristic plugins build it (usable
FRONTIER, OCCUPIED, the explorer's VISITED, targets on reachable cells; `state_objective`), in all
four forms with the presets of Tables 2-5. GA and FA run with seeds 0..N-1 (default 10) on each form
with the plugins' default configurations. Distances are Euclidean between the decoded cells, in
cells of 5 cm (Santos's unit).

Outputs in --out (default out/santos-targets/):
  <world>-<coverage>-map.png    the map state with the robot (Santos Figs. 10, 12, 14, 16)
  <world>-<coverage>-<form>.png the surface (Figs. 11-17, seen from above): viridis of
                                sign(f) log10(1 + |f|) over the reachable cells, from the optimum
                                (purple) to the largest value (yellow); unknown cells light grey,
                                known cells no target may use darker grey, walls black;
                                robot red, GA targets yellow, FA targets blue, optimum a green ring
                                (Santos's colours, Figs. 18-25)
  targets.csv                   one row per (state, form): the table printed
  runs.csv                      one row per search: state, form, algorithm, seed, cell, value, ...
  distances.png                 box plot of the distances per state, proportional form
  distances_by_form.png         box plot of the distances per form, all states pooled

Run: python benchmarks/studies/santos_targets.py [--seeds 10] [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt
from PIL import Image

from robotexp.errors import ConfigError
from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
from robotexp.run.loop import ExplorationRun
from robotexp.mapping.grid import OccupancyGrid
from robotexp.planning.grid_planner import dijkstra
from robotexp.planning.metaheuristics import (
    FireflyConfig,
    GAConfig,
    SearchResult,
    exhaustive,
    firefly_search,
    genetic_search,
)
from robotexp.planning.targets import nearest_passable, plan_costs, usable_frontier
from robotexp.planning.objective import FORMS, INFEASIBLE, SANTOS_CELL, Objective, params_for
from robotexp.output.figures import PAGE_WIDTH, box_figure, save_figure
from robotexp.output.render import Marker, render_field, render_map, save_png
from robotexp.robot import Pose

WORLDS = ("dense", "sparse")
LEVELS = (0.2, 0.4, 0.6, 0.8)       # coverage at which the map states are taken
NEAR = 0.01                         # a target within 1 % of |f_opt| of the optimum counts as near-optimal
CLEARANCE = 0.3                     # [m] danger zone of the plugins' A* costs (their default)
ROBOT_COLOR = (220, 40, 40)
GA_COLOR = (250, 215, 0)            # Santos: GA yellow
FA_COLOR = (30, 90, 230)            # Santos: FA blue
OPTIMUM_COLOR = (0, 200, 70)        # Santos: optimum green


@dataclass
class MapState:
    """One moment of an exploration run, with what the plugins' objective needs.

    Attributes:
        name: label, e.g. "dense-40".
        grid: the map at that moment (a copy).
        robot: (x, y) [cells] robot position, continuous (cell (r, c) covers [c, c+1) x [r, r+1)).
        visited: (rows, cols) bool VISITED cells.
        radius: [m] robot radius (targets are cells the robot can stand on).
        blacklist: (rows, cols) bool frontier cells the explorer had given up on, or None.
        coverage: share of the explorable free space mapped free.
        time: [s] robot time.
    """

    name: str
    grid: OccupancyGrid
    robot: tuple[float, float]
    visited: npt.NDArray[np.bool_]
    radius: float
    blacklist: npt.NDArray[np.bool_] | None = None
    coverage: float = math.nan
    time: float = math.nan


@dataclass
class FormStudy:
    """The objective of one form at one map state, its exhaustive optimum and the searches' targets.

    Attributes:
        form: the objective's form.
        objective: the objective (its `surface` is INFEASIBLE outside `reachable`).
        reachable: (rows, cols) bool cells a target may lie in.
        optimum: the exhaustive optimum.
        ga: one GA result per seed.
        fa: one firefly result per seed.
        ga_seconds: [s] wall time of each GA search.
        fa_seconds: [s] wall time of each firefly search.
    """

    form: str
    objective: Objective
    reachable: npt.NDArray[np.bool_]
    optimum: SearchResult
    ga: list[SearchResult] = field(default_factory=list)
    fa: list[SearchResult] = field(default_factory=list)
    ga_seconds: list[float] = field(default_factory=list)
    fa_seconds: list[float] = field(default_factory=list)

    def found(self, algorithm: str) -> list[SearchResult]:
        """The results of "ga" or "fa".

        Raises:
            ConfigError: another name.
        """
        if algorithm not in ("ga", "fa"):
            raise ConfigError(f"santos_targets: algorithm must be 'ga' or 'fa', got {algorithm!r}")
        return self.ga if algorithm == "ga" else self.fa

    def distances(self, algorithm: str) -> npt.NDArray[np.float64]:
        """(seeds,) float64 distances [cells] from the targets of "ga" or "fa" to the optimum."""
        found = self.found(algorithm)
        r0, c0 = self.optimum.cell
        return np.array([math.hypot(f.cell[0] - r0, f.cell[1] - c0) for f in found], dtype=np.float64)

    def near(self, algorithm: str, tol: float = NEAR) -> npt.NDArray[np.bool_]:
        """(seeds,) bool: targets of "ga" or "fa" worth within `tol` x |optimum| of the optimum.

        Surfaces can have several nearly equal minima far apart (a long straight frontier in the
        basic form): there a target far from the optimum cell can still be as good.
        """
        found = self.found(algorithm)
        opt = self.optimum.value
        return np.array([f.value <= opt + tol * abs(opt) for f in found], dtype=bool)

    def ratios(self, algorithm: str) -> npt.NDArray[np.float64]:
        """(seeds,) value / optimum value (1 at the optimum; below 1 for a negative optimum); NaN at 0."""
        found = self.found(algorithm)
        opt = self.optimum.value
        if opt == 0 or opt >= INFEASIBLE:
            return np.full(len(found), math.nan)
        return np.array([f.value / opt for f in found], dtype=np.float64)


def _snapshot(run: ExplorationRun, name: str, coverage: float) -> MapState:
    """The map state of `run` now: grid copy, robot cell position, VISITED as the explorer keeps it."""
    st = run.state
    assert st is not None
    grid = run.grid.copy()
    geo = grid.geo
    explorer = run.explorer
    own = getattr(explorer, "visited", None)
    if isinstance(own, np.ndarray) and own.shape == grid.shape:
        visited = own.copy()                    # the metaheuristic plugins' own VISITED list
    else:
        visited = np.zeros(grid.shape, dtype=bool)
        for r, c in run.metrics.visited:
            if geo.contains(r, c):
                visited[r, c] = True
    black = getattr(explorer, "blacklist", None)
    blacklist = black.copy() if isinstance(black, np.ndarray) and black.shape == grid.shape else None
    robot = ((st.pose.x - geo.origin_x) / geo.cell, (st.pose.y - geo.origin_y) / geo.cell)
    return MapState(name, grid, robot, visited, float(run.robot.radius), blacklist, coverage, run.robot_time)


def collect_states(world: str, levels: Sequence[float] = LEVELS, *, method: str = "meta-exhaustive",
                   seed: int = 0) -> list[MapState]:
    """Map states of one run of `method` on `world` at 5 cm cells, when coverage first reaches each level.

    A coverage sample that passes several levels at once gives one state. The run is stopped once
    the last level is reached (or ends by itself; levels never reached give no state).

    Args:
        world: a world name.
        levels: coverage shares in (0, 1].
        method: the explorer driving the run.
        seed: the run's seed.

    Returns:
        The states, in time order, named "<world>-<coverage in %>".
    """
    pending = sorted(levels)
    states: list[MapState] = []
    latest: list[float | None] = [None]

    def on_sample(t: float, cov: float | None) -> None:
        latest[0] = cov

    def on_run(run: ExplorationRun) -> None:
        cov = latest[0]
        if cov is None or not pending or cov < pending[0] or run.state is None:
            return
        while pending and cov >= pending[0]:
            pending.pop(0)
        states.append(_snapshot(run, f"{world}-{round(100 * cov):02d}", cov))
        if not pending:
            run.request_stop("all map states taken")

    spec = RunSpec(world=world, method=method, cell=SANTOS_CELL, seed=seed)
    run_experiment(spec, None, image=False, on_sample=on_sample, on_run=on_run)
    return states


def state_objective(state: MapState, form: str) -> tuple[Objective, npt.NDArray[np.bool_]]:
    """The objective of `form` at `state` as the metaheuristic plugins build it, and the reachable cells.

    Reachable: Dijkstra over the frontier plugin's costs (robot radius, CLEARANCE) from the robot's
    cell, or from the nearest passable cell within 0.5 m when the robot's own is not passable.
    FRONTIER: `usable_frontier` within 3 sigma_f (+1 cell) of a reachable cell, minus the blacklist.
    """
    grid = state.grid
    geo = grid.geo
    params = params_for(form)
    cost = plan_costs(grid, state.radius, CLEARANCE)
    passable = np.isfinite(cost)
    r, c = int(math.floor(state.robot[1])), int(math.floor(state.robot[0]))
    start = None
    if geo.contains(r, c):
        start = (r, c) if passable[r, c] else nearest_passable(passable, r, c, int(math.ceil(0.5 / geo.cell)))
    reachable = np.isfinite(dijkstra(cost, start)[0]) if start is not None else np.zeros(grid.shape, dtype=bool)
    reach = 3.0 * params.sigma_f * SANTOS_CELL / geo.cell + 1.0
    frontier = usable_frontier(grid, reachable, reach, state.blacklist)
    obj = Objective(params, frontier, grid.occupied(), state.visited, state.robot, reachable, cell=geo.cell)
    return obj, reachable


def study_state(state: MapState, forms: Sequence[str] = FORMS, seeds: int = 10, *,
                ga: GAConfig | None = None, fa: FireflyConfig | None = None) -> list[FormStudy]:
    """Build each form's objective at `state`, take its exhaustive optimum and run GA and FA per seed.

    Seed k seeds both searches with `numpy.random.default_rng(k)`, k = 0..seeds-1.

    Args:
        state: the map state.
        forms: objective forms to study.
        seeds: GA and FA runs per form (0: the optimum only).
        ga: GA configuration (None: the plugins' default).
        fa: firefly configuration (None: the plugins' default).

    Returns:
        One `FormStudy` per form, in the order given.
    """
    out = []
    for form in forms:
        obj, reachable = state_objective(state, form)
        study = FormStudy(form, obj, reachable, exhaustive(obj.surface))
        for k in range(seeds):
            t = time.perf_counter()
            study.ga.append(genetic_search(obj.surface, np.random.default_rng(k), ga))
            study.ga_seconds.append(time.perf_counter() - t)
            t = time.perf_counter()
            study.fa.append(firefly_search(obj.surface, np.random.default_rng(k), fa))
            study.fa_seconds.append(time.perf_counter() - t)
        out.append(study)
    return out


def symlog(values: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """sign(f) log10(1 + |f|): the colour scale of the surface images.

    The surfaces span orders of magnitude (thousands beside a wall next to the robot in the
    proportional form, hundreds at a frontier, nearly 0 far from everything): a linear colour map
    would show one colour wherever a target could be. This one keeps the sign (0 stays 0) and
    compresses both tails.
    """
    return np.sign(values) * np.log10(1.0 + np.abs(values))


def surface_image(state: MapState, study: FormStudy, *, scale: int | None = None,
                  max_size: int = 1400) -> Image.Image:
    """The surface of `study` at `state` with the robot, the GA and FA targets and the optimum marked.

    Markers, drawn in this order: robot (red disc), GA targets (yellow discs of radius 6 px), FA
    targets (blue discs of radius 3.5 px: a GA and an FA target in one cell show as a blue dot in a
    yellow disc), all at their cell centres, and the optimum as a green ring of radius 9 px around
    its cell centre, on top.
    """
    geo = state.grid.geo

    def at(cell: tuple[int, int]) -> tuple[float, float]:
        return geo.center_of(cell[0], cell[1])

    rx, ry = geo.origin_x + state.robot[0] * geo.cell, geo.origin_y + state.robot[1] * geo.cell
    markers = [Marker(rx, ry, ROBOT_COLOR, 5.0, outline=(0, 0, 0))]
    markers += [Marker(*at(f.cell), GA_COLOR, 6.0, outline=(0, 0, 0)) for f in study.ga]
    markers += [Marker(*at(f.cell), FA_COLOR, 3.5, outline=(0, 0, 0)) for f in study.fa]
    if study.optimum.value < INFEASIBLE:
        markers.append(Marker(*at(study.optimum.cell), OPTIMUM_COLOR, 9.0, ring=True))
    field = symlog(np.where(study.reachable, study.objective.surface, 0.0))
    vals = field[study.reachable]
    lo, hi = (float(vals.min()), float(vals.max())) if vals.size else (0.0, 1.0)
    hi = hi if hi > lo else lo + 1.0
    title = (f"{state.name} {study.form}: sign(f) log10(1+|f|) {lo:.2f} (purple) .. {hi:.2f} (yellow); "
             f"optimum green ring, GA yellow, FA blue, robot red")
    return render_field(field, geo, mask=study.reachable, states=state.grid.states(), limits=(lo, hi),
                        markers=markers, scale=scale, title=title, max_size=max_size)


def summary(state: MapState, study: FormStudy) -> dict[str, object]:
    """One table row: optimum; per algorithm the distances [cells], shares at / near the optimum, ratio, time."""
    row: dict[str, object] = {"state": state.name, "coverage": round(state.coverage, 3), "form": study.form,
                              "opt_row": study.optimum.cell[0], "opt_col": study.optimum.cell[1],
                              "opt_value": study.optimum.value}
    for alg in ("ga", "fa"):
        d = study.distances(alg)
        q = study.ratios(alg)
        secs = study.ga_seconds if alg == "ga" else study.fa_seconds
        evals = [f.evaluations for f in (study.ga if alg == "ga" else study.fa)]
        ok = d.size > 0
        row |= {f"{alg}_d_mean": float(d.mean()) if ok else math.nan,
                f"{alg}_d_median": float(np.median(d)) if ok else math.nan,
                f"{alg}_d_max": float(d.max()) if ok else math.nan,
                f"{alg}_at_opt": float(np.mean(d == 0)) if ok else math.nan,
                f"{alg}_near_opt": float(np.mean(study.near(alg))) if ok else math.nan,
                f"{alg}_ratio_median": float(np.nanmedian(q)) if ok and np.isfinite(q).any() else math.nan,
                f"{alg}_ms": 1000 * float(np.mean(secs)) if ok else math.nan,
                f"{alg}_evals": float(np.mean(evals)) if ok else math.nan}
    return row


def _print_table(rows: list[dict[str, object]]) -> None:
    print("\n| state | form | f_opt | GA d mean / med / max [cells] | GA at / near opt | GA f/f_opt | "
          "FA d mean / med / max [cells] | FA at / near opt | FA f/f_opt | GA ms | FA ms |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['state']} | {r['form']} | {r['opt_value']:.4g} | "
              f"{r['ga_d_mean']:.1f} / {r['ga_d_median']:.1f} / {r['ga_d_max']:.1f} | "
              f"{r['ga_at_opt']:.0%} / {r['ga_near_opt']:.0%} | {r['ga_ratio_median']:.3f} | "
              f"{r['fa_d_mean']:.1f} / {r['fa_d_median']:.1f} / {r['fa_d_max']:.1f} | "
              f"{r['fa_at_opt']:.0%} / {r['fa_near_opt']:.0%} | {r['fa_ratio_median']:.3f} | "
              f"{r['ga_ms']:.0f} | {r['fa_ms']:.0f} |")


def _print_pooled(runs: list[dict[str, object]], forms: Sequence[str]) -> None:
    """Per form and algorithm, over every state and seed: distances, shares at / near the optimum."""
    print(f"\npooled over states and seeds (near: within {NEAR:.0%} of |f_opt|; f >= 0: the search found no "
          "frontier's attraction at all):")
    print("| form | algorithm | runs | d mean [cells] | d median | d <= 5 cells | at opt | near opt | f >= 0 | "
          "evaluations | ms |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for form in forms:
        for alg in ("ga", "fa"):
            sel = [r for r in runs if r["form"] == form and r["algorithm"] == alg]
            if not sel:
                continue
            d = np.array([r["distance_cells"] for r in sel], dtype=np.float64)
            near = np.mean([bool(r["near"]) for r in sel])
            print(f"| {form} | {alg.upper()} | {len(sel)} | {d.mean():.1f} | {np.median(d):.1f} | "
                  f"{np.mean(d <= 5):.0%} | {np.mean(d == 0):.0%} | {near:.0%} | "
                  f"{np.mean([float(r['value']) >= 0 for r in sel]):.0%} | "
                  f"{np.mean([r['evaluations'] for r in sel]):.0f} | {np.mean([r['ms'] for r in sel]):.1f} |")


def _write_csv(path: Path, rows: list[dict[str, object]]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def main() -> None:
    """Collect the map states, study them, write the images, CSVs and box plots, print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", nargs="+", default=list(WORLDS))
    ap.add_argument("--levels", nargs="+", type=float, default=list(LEVELS), help="coverage of the states")
    ap.add_argument("--forms", nargs="+", default=list(FORMS), choices=FORMS)
    ap.add_argument("--seeds", type=int, default=10, help="GA and FA runs per state and form")
    ap.add_argument("--method", default="meta-exhaustive", help="explorer of the runs giving the states")
    ap.add_argument("--out", type=Path, default=Path("out/santos-targets"))
    ap.add_argument("--quick", action="store_true", help="levels 0.3 and 0.6, 3 seeds, proportional form only")
    args = ap.parse_args()
    if args.quick:
        args.levels, args.seeds, args.forms = [0.3, 0.6], 3, ["proportional"]
    t0 = time.perf_counter()
    states = [s for w in args.worlds for s in collect_states(w, args.levels, method=args.method)]
    print(f"{len(states)} map states from {args.method} runs in {time.perf_counter() - t0:.0f} s: "
          + ", ".join(f"{s.name} ({s.grid.shape[1]} x {s.grid.shape[0]} cells, t {s.time:.0f} s)" for s in states))
    rows: list[dict[str, object]] = []
    runs: list[dict[str, object]] = []
    dist: dict[tuple[str, str, str], npt.NDArray[np.float64]] = {}
    for st in states:
        geo = st.grid.geo
        pose = Pose(geo.origin_x + st.robot[0] * geo.cell, geo.origin_y + st.robot[1] * geo.cell)
        save_png(render_map(st.grid.states(), geo, end=pose, title=f"{st.name}: map and robot"),
                 args.out / f"{st.name}-map.png")
        for study in study_state(st, args.forms, args.seeds):
            save_png(surface_image(st, study), args.out / f"{st.name}-{study.form}.png")
            rows.append(summary(st, study))
            for alg in ("ga", "fa"):
                dist[(st.name, study.form, alg)] = study.distances(alg)
                found = study.ga if alg == "ga" else study.fa
                secs = study.ga_seconds if alg == "ga" else study.fa_seconds
                for k, (f, d, near, s) in enumerate(zip(found, study.distances(alg), study.near(alg), secs,
                                                        strict=True)):
                    runs.append({"state": st.name, "form": study.form, "algorithm": alg, "seed": k,
                                 "row": f.cell[0], "col": f.cell[1], "value": f.value,
                                 "opt_value": study.optimum.value, "distance_cells": float(d), "near": int(near),
                                 "evaluations": f.evaluations, "ms": 1000 * s})
    _print_table(rows)
    _print_pooled(runs, args.forms)
    _write_csv(args.out / "targets.csv", rows)
    if runs:
        _write_csv(args.out / "runs.csv", runs)
        form = "proportional" if "proportional" in args.forms else args.forms[0]
        groups = [(f"{st.name} {alg.upper()}", dist[(st.name, form, alg)]) for st in states for alg in ("ga", "fa")]
        save_figure(box_figure(groups, ylabel="distance to the optimum [5 cm cells]",
                               title=f"GA and FA targets vs. the exhaustive optimum, {form} form, {args.seeds} seeds",
                               width=max(PAGE_WIDTH, 0.8 * len(groups))), args.out / "distances", ("png",))
        pooled = [(f"{f} {alg.upper()}", np.concatenate([dist[(st.name, f, alg)] for st in states]))
                  for f in args.forms for alg in ("ga", "fa")]
        save_figure(box_figure(pooled, ylabel="distance to the optimum [5 cm cells]",
                               title=f"distance to the optimum per form, {len(states)} states x {args.seeds} seeds",
                               width=max(PAGE_WIDTH, 1.0 * len(pooled))), args.out / "distances_by_form", ("png",))
    print(f"\nwrote {len(states) * (len(args.forms) + 1)} images, targets.csv, runs.csv and the box plots to "
          f"{args.out} in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
