"""Does an explorer's cost grow with the explored area on a real map? CPU per robot-second along one run.

One run per map and method (default start, seed 0, the robot preset given) with an observer that notes,
at every coverage sample, the process's CPU time (user + system, `resource.getrusage`) and the known
free area of the robot's map. The run is cut into stretches of `--stretch` seconds of robot time; each
stretch's CPU per robot-second is printed beside the free area known at its end. An explorer whose cost
per robot-second stays flat while the known area grows tenfold does no whole-map work per step; one whose
cost follows the area does. The figure quoted is the ratio of the last stretch's CPU per robot-second to
the first one past `--settle` [m2] of known area (the first seconds, when the map is tiny, cost less for
every explorer). The machine is shared, so CPU time, not wall time.

With `--before CHECKOUT` (another tree of the project, e.g. an export of main) each run is made twice, in a
child process of each tree pinned to `--core`, the two alternating, and both trees' ratios are printed and
recorded: a change's effect on the growth measured on one machine in one go. The child imports the tree's
`robotexp` and its `plugins` (as robotexp_plugins) and `drivers`, whatever the environment installed.

Run: python benchmarks/speed/bench_area_cost.py MAP.yaml [MAP ...] [--methods frontier,bvp]
     [--robot kobuki] [--max-time 7200] [--stretch 600] [--before CHECKOUT [--core 1]] [--record]
The maps are any ROS .yaml or MobileSim .map files (the project's real-map corpus lives outside the
repository); `--record` writes benchmarks/results/area-cost.json.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np

from robotexp.experiment import run_experiment
from robotexp.run.observers import RunObserver
from robotexp.run.spec import RunSpec

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perflog import Figure, record  # noqa: E402


class AreaClock(RunObserver):
    """(robot time [s], CPU [s], known free area [m2]) at every coverage sample of the run."""

    def __init__(self) -> None:
        self.rows: list[tuple[float, float, float]] = []

    @staticmethod
    def _cpu() -> float:
        u = resource.getrusage(resource.RUSAGE_SELF)
        return u.ru_utime + u.ru_stime

    def on_start(self, run) -> None:  # type: ignore[no-untyped-def]
        self.rows = [(0.0, self._cpu(), 0.0)]

    def on_sample(self, run, time: float, coverage: float | None) -> None:  # type: ignore[no-untyped-def]
        free = float(np.count_nonzero(run.grid.free())) * run.grid.geo.cell ** 2
        self.rows.append((time, self._cpu(), free))


def stretches(rows: list[tuple[float, float, float]], stretch: float) -> list[tuple[float, float, float]]:
    """(robot time at the end [s], CPU per robot-second [ms], known free area at the end [m2]) per stretch."""
    out = []
    t0, c0, _ = rows[0]
    for t, c, area in rows[1:]:
        if t - t0 >= stretch:
            out.append((t, 1e3 * (c - c0) / (t - t0), area))
            t0, c0 = t, c
    return out


# A run in another tree: its robotexp, plugins and drivers come first, this file's `measure` measures.
CHILD = """
import importlib.util, json, sys
tree, here = sys.argv[1], sys.argv[2]
sys.path[:0] = [tree, here]
for name, folder in (("robotexp_plugins", "plugins"), ("robotexp_drivers", "drivers")):
    spec = importlib.util.spec_from_file_location(name, f"{tree}/{folder}/__init__.py",
                                                  submodule_search_locations=[f"{tree}/{folder}"])
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
import robotexp
assert robotexp.__file__.startswith(tree), robotexp.__file__
import bench_area_cost
print(json.dumps(bench_area_cost.measure(sys.argv[3], sys.argv[4], sys.argv[5], float(sys.argv[6]))))
"""


def measure(path: str, method: str, robot: str, max_time: float) -> dict[str, object]:
    """One run of `method` on the map `path` (after a 5 s warm-up run on `dense`): its rows and record."""
    run_experiment(RunSpec(world="dense", method=method, max_time=5.0, robot=robot), None, image=False)
    clock = AreaClock()
    out = run_experiment(RunSpec(world=str(Path(path).resolve()), method=method, max_time=max_time, robot=robot),
                         None, observers=[clock], image=False)
    r = out.record
    return {"rows": clock.rows, "coverage": float(r["coverage"]), "robot_time_s": float(r["robot_time_s"]),
            "reason": str(r["reason"]), "path_length_m": float(r["path_length_m"])}


def in_tree(tree: Path, core: int, path: str, method: str, robot: str, max_time: float) -> dict[str, object]:
    """`measure` in a child process of `tree`, pinned to `core`."""
    cmd = ["taskset", "-c", str(core), sys.executable, "-c", CHILD, str(tree), str(Path(__file__).resolve().parent),
           str(Path(path).resolve()), method, robot, str(max_time)]
    done = subprocess.run(cmd, cwd=tree, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def report(name: str, label: str, got: dict[str, object], args: argparse.Namespace) -> Figure | None:
    """Print one run's stretches; its growth figure (None with fewer than two stretches past --settle)."""
    rows = stretches([tuple(x) for x in got["rows"]], args.stretch)  # type: ignore[attr-defined]
    print(f"{name} {label}: coverage {got['coverage']:.4f}, path {got['path_length_m']:.1f} m, robot time "
          f"{got['robot_time_s']:.0f} s, {got['reason']}", flush=True)
    for t, ms, area in rows:
        print(f"  to {t:6.0f} s: {ms:7.2f} ms CPU per robot-s, {area:7.0f} m2 known free", flush=True)
    counted = [s for s in rows if s[2] >= args.settle]
    if len(counted) < 2:
        return None
    first, last = counted[0], counted[-1]
    ratio = last[1] / first[1]
    print(f"  last / first stretch past {args.settle:g} m2: {ratio:.2f} ({first[1]:.2f} -> {last[1]:.2f} ms while "
          f"the known area grew {first[2]:.0f} -> {last[2]:.0f} m2)", flush=True)
    return Figure(f"{name}, {label}: CPU per robot-second, last / first {args.stretch:g} s stretch", round(ratio, 2),
                  "x", f"{first[1]:.2f} -> {last[1]:.2f} ms, known free area {first[2]:.0f} -> {last[2]:.0f} m2")


def main() -> None:
    """Print each stretch of each run; with --record, write the growth ratios."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="+")
    ap.add_argument("--methods", default="frontier,bvp,srt-laser,meta-ga,meta-firefly")
    ap.add_argument("--robot", default="kobuki")
    ap.add_argument("--max-time", type=float, default=7200.0, help="[s] robot time per run")
    ap.add_argument("--stretch", type=float, default=600.0, help="[s] robot time per stretch")
    ap.add_argument("--settle", type=float, default=100.0, help="[m2] known area before the first stretch counted")
    ap.add_argument("--before", type=Path, help="another tree of the project, run beside this one")
    ap.add_argument("--core", type=int, default=1, help="with --before: the core both trees' runs are pinned to")
    ap.add_argument("--record", action="store_true", help="write benchmarks/results/area-cost.json")
    args = ap.parse_args()
    methods = [m for m in args.methods.split(",") if m]
    if args.before is not None and not (args.before / "robotexp" / "__init__.py").is_file():
        sys.exit(f"bench_area_cost: --before {args.before} holds no robotexp package; give a tree of the project")
    here = Path(__file__).resolve().parents[2]
    figures: list[Figure] = []
    for path in args.maps:
        name = Path(path).stem
        for k, method in enumerate(methods):
            if args.before is None:
                sides = [("", None)]
            else:       # alternate which tree runs first
                sides = [(" before", args.before.resolve()), ("", here)]
                sides = sides if k % 2 == 0 else sides[::-1]
            for suffix, tree in sides:
                got = measure(path, method, args.robot, args.max_time) if tree is None \
                    else in_tree(tree, args.core, path, method, args.robot, args.max_time)
                fig = report(name, f"{method} ({args.robot}){suffix}", got, args)
                if fig is not None:
                    figures.append(fig)
    if args.record and figures:
        parameters = {} if args.before is None else {"before": str(args.before)}
        record("area-cost", sorted(figures, key=lambda f: f.label), section="speed",
               title="CPU per robot-second as the explored area grows, along runs on real maps",
               parameters=parameters)


if __name__ == "__main__":
    main()
