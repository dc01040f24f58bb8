"""Scripted exploration vs. the same exploration from run_experiment: wall time of the exploration.

Both sides run the same RunSpec (world, method, pose, speed, seed) and the same number of times,
alternating; the figure is the ratio of the median `wall_time_s` (the control loop, as written in
results.jsonl) of the Lua runs to that of the direct runs, plus the ratio of whole-call times
(Lua runtime start, script, world set-up included). Target: loop ratio within 1.05.

    python benchmarks/speed/bench_lua.py [--world ufmg-static] [--repeat 3] [--max-time 120]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment
from robotexp.lua import run_script
import sys

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/: perflog
from perflog import Figure, record  # noqa: E402

SCRIPT = """
exploration.setWorld("{world}")
exploration.setMethod(ExplorationMethod.FRONTIER)
exploration.setMaxTime({max_ms})
robot.setMaxSpeed(300)
robot.setMaxLaserRange(3000)
exploration.start()
exploration.wait()
"""


def main() -> None:
    """Run the comparison and print the ratios."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="ufmg-static")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--max-time", type=float, default=120.0, help="robot-time limit [s]")
    args = ap.parse_args()
    spec = RunSpec(world=args.world, method="frontier", max_time=args.max_time)
    loops: dict[str, list[float]] = {"lua": [], "direct": []}
    calls: dict[str, list[float]] = {"lua": [], "direct": []}
    with tempfile.TemporaryDirectory() as tmp:
        script = Path(tmp) / "bench.lua"
        script.write_text(SCRIPT.format(world=args.world, max_ms=args.max_time * 1000))
        run_experiment(spec, None, image=False)           # warm-up: numba compile, world caches
        for i in range(args.repeat):
            t0 = time.perf_counter()
            result = run_script(script, out=Path(tmp) / f"lua{i}")
            calls["lua"].append(time.perf_counter() - t0)
            loops["lua"].append(result.records[0]["wall_time_s"])
            t0 = time.perf_counter()
            direct = run_experiment(spec, Path(tmp) / f"direct{i}", image=False)
            calls["direct"].append(time.perf_counter() - t0)
            loops["direct"].append(direct.record["wall_time_s"])
            assert result.records[0]["path_length_m"] == direct.record["path_length_m"], "runs differ"
    for label, data in (("exploration loop", loops), ("whole call", calls)):
        lua_s, direct_s = statistics.median(data["lua"]), statistics.median(data["direct"])
        print(f"{label:17s} lua {lua_s:7.3f} s  direct {direct_s:7.3f} s  ratio {lua_s / direct_s:.3f}")
    record("lua", [
        Figure(f"{label}: Lua script / the same run from Python", statistics.median(data["lua"])
               / statistics.median(data["direct"]), "x", f"median of {args.repeat}")
        for label, data in (("exploration loop", loops), ("whole call", calls))
    ], title="A run from a Lua script against the same run from Python",
        parameters={"world": args.world, "robot time": f"{args.max_time:g} s"})


if __name__ == "__main__":
    main()
