"""Cost of the images a run writes at its end (robotexp.output.figures, matplotlib) against the raster frame path.

Run: python benchmarks/speed/bench_figures.py [--world dense] [--method frontier] [--max-time 600] [--repeats 5]
Target: the map image of a 600 s dense run in about 1 s or less.

One run is made (no images), then, in this process: the first map figure (it imports matplotlib and loads
its fonts, as the first run of a process does), then --repeats times each of: the map figure written as PNG
(made and saved), the coverage figure as PNG, the map figure as SVG and as PDF, and one raster frame
(`robotexp.output.render.render_map`, what --frames, video and the live view draw) encoded as PNG. Medians are
printed, with the ratio of the map figure to the raster frame measured in this run.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="dense")
    ap.add_argument("--method", default="frontier")
    ap.add_argument("--max-time", type=float, default=600.0, help="robot time of the run [s]")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()

    from robotexp.run.spec import RunSpec
    from robotexp.experiment import run_experiment

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        t0 = time.perf_counter()
        res = run_experiment(RunSpec(world=args.world, method=args.method, max_time=args.max_time), out,
                             image=False)
        run = res.run
        geo = run.grid.geo
        print(f"run: {args.world} {args.method}, {run.robot_time:.0f} s robot time, {len(run.metrics.path)} path "
              f"points, grid {geo.cols} x {geo.rows} cells of {geo.cell * 1000:g} mm "
              f"(made in {time.perf_counter() - t0:.1f} s)")

        from robotexp.output.figures import run_coverage_figure, run_map_figure, save_figure
        from robotexp.output.render import save_png
        from robotexp.output.results import map_image

        t = time.perf_counter()
        save_figure(run_map_figure(run), out / "first", ("png",))
        first = time.perf_counter() - t

        def timed(fn: object) -> float:
            times = []
            for _ in range(args.repeats):
                t = time.perf_counter()
                fn()  # type: ignore[operator]
                times.append(time.perf_counter() - t)
            return statistics.median(times)

        png = timed(lambda: save_figure(run_map_figure(run), out / "map", ("png",)))
        cov = timed(lambda: save_figure(run_coverage_figure(run), out / "cov", ("png",)))
        svg = timed(lambda: save_figure(run_map_figure(run), out / "map", ("svg",)))
        pdf = timed(lambda: save_figure(run_map_figure(run), out / "map", ("pdf",)))
        raster = timed(lambda: save_png(map_image(run, "frame"), out / "frame.png"))
        print(f"first map figure in this process (imports matplotlib): {first:.3f} s")
        print(f"map figure PNG: {png:.3f} s   coverage figure PNG: {cov:.3f} s   both: {png + cov:.3f} s")
        print(f"map figure SVG: {svg:.3f} s   PDF: {pdf:.3f} s")
        print(f"raster frame PNG (render_map): {raster:.3f} s   map figure / raster frame: {png / raster:.1f}x")


if __name__ == "__main__":
    main()
