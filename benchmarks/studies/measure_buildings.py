"""What real buildings are like, measured on their maps, beside the generated `building` worlds.

For every map of the folders and files given (ROS map_server `.yaml`; an ARIA `.map` is rasterised on
5 cm cells unless a `.yaml` of the same name lies beside it) this measures, with
robotexp.world.measure.measure_grid: door widths (the narrowest passages between regions), corridor
widths, room areas (regions between doors, corridors left out), clutter (obstacles standing free in
free space: pieces per 100 m2 and their areas; specks of at most 0.01 m2 counted apart), wall thickness,
corners of the wall face per metre (0 for straight drawn walls), one-cell gaps in walls, the share of
unknown space in the building's box, unknown pockets, and the length of free boundary open onto the
outside. It prints one row per map and the pooled distributions (door widths, corridor widths, room
areas and clutter areas pooled over the maps' doors, corridors, rooms and pieces; the other measures one
value per map), then writes:

- `benchmarks/results/buildings.json` (perflog: command, commit, machine): the 10th, 50th and 90th
  percentiles of each distribution, of the corpus and of the generated worlds;
- `benchmarks/results/buildings/distributions.json`: every map's row and the 0, 5, ..., 100th
  percentiles of each distribution (the generator's parameters in robotexp/world/building.py come from it);
- `--figure PNG`: histograms of the corpus beside the generated worlds (the share of the items, or of the
  maps, in each bin; values beyond the axis are counted in its end bins).

    python benchmarks/studies/measure_buildings.py ../shared/maps --leave-out 'eb_*,stdr_*,turtlebot3_*,nav2_tb3_*' \
        --generated building:0-19 --figure docs/figures/buildings.png

`--leave-out GLOBS` measures and prints those maps but leaves them out of the pooled distributions
(designed arenas and toy worlds rather than buildings); `--generated KIND:A-B` measures
`generated:KIND:SEED` for those seeds; `--no-record` writes nothing.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perflog import Figure, command, commit, record, results_dir  # noqa: E402

POOLED = ("door_widths", "corridor_widths", "room_areas", "clutter_areas")
PER_MAP = ("clutter_per_100m2", "specks_per_100m2", "wall_thickness", "corners_per_m", "wall_gaps_per_10m",
           "unknown_share_box", "pockets_per_100m2", "open_length")
UNITS = {"door_widths": "m", "corridor_widths": "m", "room_areas": "m2", "clutter_areas": "m2",
         "clutter_per_100m2": "/100 m2", "specks_per_100m2": "/100 m2", "wall_thickness": "m", "corners_per_m": "/m",
         "wall_gaps_per_10m": "/10 m", "unknown_share_box": "", "pockets_per_100m2": "/100 m2", "open_length": "m"}


def map_files(paths: list[str]) -> list[Path]:
    """The maps of the folders and files given: `.yaml`, and `.map` without a `.yaml` beside it."""
    out: list[Path] = []
    for p in map(Path, paths):
        files = sorted(p.iterdir()) if p.is_dir() else [p]
        for f in files:
            if f.suffix.lower() in (".yaml", ".yml") or (f.suffix.lower() == ".map"
                                                         and not f.with_suffix(".yaml").exists()):
                out.append(f)
    return out


def load_grid(path: Path) -> tuple[np.ndarray, float]:
    from robotexp.mapping.geometry import GridGeometry
    from robotexp.world.groundtruth import occupancy
    from robotexp.world.mobilesim import load_mobilesim
    from robotexp.world.rosmap import load_ros_grid

    if path.suffix.lower() == ".map":
        world = load_mobilesim(path)
        assert world.bounds is not None
        geo = GridGeometry.covering(*world.bounds, cell=0.05, margin=0.5)
        return np.where(occupancy(world, geo), 100, 0).astype(np.int8), geo.cell
    values, geo = load_ros_grid(path)
    return values, geo.cell


def row(name: str, values: np.ndarray, cell: float) -> dict:
    from robotexp.world.measure import measure_grid

    m = measure_grid(values, cell)
    return {"map": name, "cell": cell, "free_area": m.free_area, "door_widths": m.door_widths,
            "corridor_widths": m.corridor_widths, "room_areas": m.room_areas,
            "clutter_areas": [a for a in m.clutter_areas if a > 0.01 + 1e-12],
            "clutter_per_100m2": m.clutter_per_100m2, "specks_per_100m2": m.specks_per_100m2,
            "wall_thickness": m.wall_thickness, "corners_per_m": m.corners_per_m,
            "wall_gaps_per_10m": m.wall_gaps_per_10m, "unknown_share_box": m.unknown_share_box,
            "pockets_per_100m2": 100.0 * m.pockets / max(m.free_area, 1e-9), "open_length": m.open_length}


def print_row(r: dict) -> None:
    def med(xs: list[float]) -> str:
        return f"{np.median(xs):6.2f}" if xs else "     -"
    print(f"{r['map']:28s} {r['free_area']:7.0f} {len(r['door_widths']):5d} {med(r['door_widths'])} "
          f"{len(r['corridor_widths']):4d} {med(r['corridor_widths'])} {len(r['room_areas']):4d} "
          f"{med(r['room_areas'])} "
          f"{r['clutter_per_100m2']:6.1f} {r['specks_per_100m2']:6.1f} {r['wall_thickness']:5.2f} "
          f"{r['corners_per_m']:5.2f} {r['wall_gaps_per_10m']:5.2f} {r['unknown_share_box']:5.2f} "
          f"{r['pockets_per_100m2']:5.2f} {r['open_length']:7.1f}", flush=True)


HEADER = (f"{'map':28s} {'free m2':>7} {'doors':>5} {'med m':>6} {'corr':>4} {'med m':>6} {'rooms':>4} "
          f"{'med m2':>6} {'clut':>6} {'speck':>6} {'wall':>5} {'corn':>5} {'gaps':>5} {'unkn':>5} "
          f"{'pock':>5} {'open m':>7}")


def pooled(rows: list[dict]) -> dict[str, list[float]]:
    out: dict[str, list[float]] = {k: [x for r in rows for x in r[k]] for k in POOLED}
    out.update({k: [float(r[k]) for r in rows] for k in PER_MAP})
    return out


def quantiles(dist: dict[str, list[float]]) -> dict[str, list[float] | None]:
    q = np.linspace(0, 100, 21)
    return {k: [round(float(v), 4) for v in np.percentile(xs, q)] if xs else None for k, xs in dist.items()}


def figure(path: Path, corpus: dict[str, list[float]], generated: dict[str, list[float]] | None, label: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [("door_widths", "door width [m]", np.arange(0.3, 4.05, 0.1), False),
              ("corridor_widths", "corridor width [m]", np.arange(0.3, 3.65, 0.15), False),
              ("room_areas", "room area [m2]", np.geomspace(1, 1000, 25), True),
              ("clutter_per_100m2", "clutter pieces per 100 m2 (per map)", np.arange(0, 42, 3), False),
              ("corners_per_m", "wall-face corners per m (per map)", np.arange(0, 13, 1), False),
              ("unknown_share_box", "unknown share of the building box (per map)", np.arange(0, 0.65, 0.05), False)]
    fig, axes = plt.subplots(2, 3, figsize=(13, 7))
    for ax, (key, title, bins, logx) in zip(axes.ravel(), panels, strict=True):
        for dist, name, colour in ((corpus, "real maps", "tab:blue"), (generated, label, "tab:orange")):
            if dist is None or not dist[key]:
                continue
            xs = np.clip(dist[key], bins[0], bins[-1])       # the ends of the axis hold what lies beyond
            ax.hist(xs, bins=bins, weights=np.full(len(xs), 1.0 / len(xs)), alpha=0.55, label=name, color=colour)
        ax.set_xlabel(title)
        if logx:
            ax.set_xscale("log")
    axes[0, 0].set_ylabel("share of the doors, corridors, rooms")
    axes[1, 0].set_ylabel("share of the maps")
    axes[0, 0].legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    print(f"figure written to {path}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("maps", nargs="+", help="folders of maps and map files")
    ap.add_argument("--leave-out", default="", help="comma-separated globs of map names not pooled")
    ap.add_argument("--generated", default="", help="KIND:A-B, generated worlds to measure beside the maps")
    ap.add_argument("--figure", type=Path, default=None, help="PNG of the histograms")
    ap.add_argument("--no-record", action="store_true", help="print only")
    args = ap.parse_args()
    globs = [g for g in args.leave_out.split(",") if g]
    files = map_files(args.maps)
    if not files:
        print(f"measure_buildings: no .yaml or .map file in {' '.join(args.maps)}; give folders of maps",
              file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    print(HEADER)
    rows, left_out = [], []
    for f in files:
        r = row(f.stem, *load_grid(f))
        print_row(r)
        (left_out if any(fnmatch.fnmatch(f.stem, g) for g in globs) else rows).append(r)
    gen_rows: list[dict] = []
    if args.generated:
        from robotexp.world.generate import generate_grid

        kind, _, seeds = args.generated.partition(":")
        a, _, b = seeds.partition("-")
        for seed in range(int(a), int(b or a) + 1):
            values, geo = generate_grid(kind, seed)
            r = row(f"generated:{kind}:{seed}", values, geo.cell)
            print_row(r)
            gen_rows.append(r)
    corpus = pooled(rows)
    generated = pooled(gen_rows) if gen_rows else None
    print(f"\npooled over {len(rows)} maps (left out: {', '.join(r['map'] for r in left_out) or 'none'})"
          + (f", {len(gen_rows)} generated" if gen_rows else ""))
    figures = []
    for key in (*POOLED, *PER_MAP):
        for who, dist in (("real maps", corpus), (f"generated {args.generated}", generated)):
            if dist is None or not dist[key]:
                continue
            p10, p50, p90 = np.percentile(dist[key], [10, 50, 90])
            print(f"{who:24s} {key:20s} n {len(dist[key]):5d}  p10 {p10:8.3f}  median {p50:8.3f}  p90 {p90:8.3f} "
                  f"{UNITS[key]}")
            for name, v in (("p10", p10), ("median", p50), ("p90", p90)):
                figures.append(Figure(f"{who}: {key.replace('_', ' ')} {name}", round(float(v), 3), UNITS[key]))
    print(f"{time.perf_counter() - t0:.1f} s")
    if args.no_record:
        return 0
    tree = commit()            # before anything is written: the figure and the results are tracked files
    record("buildings", figures, title="Real buildings measured, and the generated building worlds", section="studies",
           parameters={"maps pooled": len(rows), "maps left out": len(left_out), "generated": args.generated or "none"})
    out = results_dir() / "buildings" / "distributions.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    doc = {"command": command(), "commit": tree, "maps": [r["map"] for r in rows],
           "left_out": [r["map"] for r in left_out], "percentiles": list(range(0, 101, 5)),
           "corpus": quantiles(corpus), "generated": quantiles(generated) if generated else None,
           "rows": rows + left_out, "generated_rows": gen_rows}
    # one line per distribution and per map: a readable diff when measured again
    lines = []
    for key, value in doc.items():
        if isinstance(value, dict):
            inner = [f'  {json.dumps(k)}: {json.dumps(v)}' for k, v in value.items()]
            lines.append(f'{json.dumps(key)}: {{\n' + ",\n".join(inner) + "\n }")
        elif key in ("rows", "generated_rows"):
            lines.append(f'{json.dumps(key)}: [\n' + ",\n".join(f"  {json.dumps(r)}" for r in value) + "\n ]")
        else:
            lines.append(f"{json.dumps(key)}: {json.dumps(value)}")
    out.write_text("{\n " + ",\n ".join(lines) + "\n}\n")
    print(f"distributions written to {out}")
    if args.figure is not None:
        figure(args.figure, corpus, generated, f"generated {args.generated}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
