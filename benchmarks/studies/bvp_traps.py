"""bvp on large real floors with and without relaxing the field anew at a stale peak (`trap_time`).

When goals vanish (a pocket or a room resolved) the harmonic field relaxes from above, and the cells they
pulled stay a peak of q = 1 - p until the sweeps wear it down below the pull of the goals left; on a
large floor that pull is tiny and the robot circles on the peak for minutes. `trap_time` (default 5 s)
relaxes the field anew from below when a peak has held the robot that long; `trap_time=0` is the field of
the thesis (with the stall watch's flush only). For each map and robot preset this runs bvp both ways
(default start, seed 0) and prints the record (coverage of the reachable space, end, robot time, path),
the number of flushes started by a peak, and the process's CPU time (user + system) per second of robot
time over the run (after a 5 s warm-up run that compiles the kernels).

    python benchmarks/studies/bvp_traps.py MAP.yaml [MAP ...] [--robots p3dx,kobuki] [--max-time 14400]
        [--record]

The maps are any ROS .yaml or MobileSim .map files (the project's real-map corpus lives outside the
repository); `--record` writes benchmarks/results/bvp-traps.json.
"""

from __future__ import annotations

import argparse
import resource
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from perflog import Figure, record  # noqa: E402


def _cpu() -> float:
    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_utime + u.ru_stime


def one(path: str, robot: str, trap_time: float | None, max_time: float) -> dict[str, Any]:
    """One bvp run on the map `path` (trap_time None: the default); its record, CPU time and flush counts."""
    from robotexp.experiment import run_experiment
    from robotexp.run.spec import RunSpec

    params = {} if trap_time is None else {"trap_time": trap_time}
    runs: list[Any] = []
    cpu0 = _cpu()
    rec = run_experiment(RunSpec(world=str(Path(path).resolve()), method="bvp", robot=robot, params=params,
                                 max_time=max_time), None, image=False, on_run=runs.append).record
    cpu = _cpu() - cpu0
    ex = runs[-1].explorer
    return {"coverage": float(rec["coverage"]), "end": str(rec["end"]), "reason": str(rec["reason"]),
            "robot_time_s": float(rec["robot_time_s"]), "path_length_m": float(rec["path_length_m"]),
            "collisions": int(rec["collisions"]), "cpu_s": cpu, "traps": ex.traps, "flushes": ex.flushes}


def main() -> None:
    """Run each map and robot both ways, print, and with --record write the figures."""
    from robotexp.experiment import run_experiment
    from robotexp.run.spec import RunSpec

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("maps", nargs="+")
    ap.add_argument("--robots", default="p3dx,kobuki")
    ap.add_argument("--max-time", type=float, default=14400.0, help="[s] robot time per run")
    ap.add_argument("--record", action="store_true", help="write benchmarks/results/bvp-traps.json")
    args = ap.parse_args()
    run_experiment(RunSpec(world="dense", method="bvp", max_time=5.0), None, image=False)     # compile
    figures: list[Figure] = []
    for path in args.maps:
        name = Path(path).stem
        for robot in [r for r in args.robots.split(",") if r]:
            for label, trap_time in (("trap_time=0", 0.0), ("default", None)):
                got = one(path, robot, trap_time, args.max_time)
                ms = 1e3 * got["cpu_s"] / got["robot_time_s"]
                print(f"{name} {robot} {label}: coverage {got['coverage']:.4f}, {got['end']} at "
                      f"{got['robot_time_s']:.0f} s, path {got['path_length_m']:.0f} m, collisions "
                      f"{got['collisions']}, flushes {got['flushes']} ({got['traps']} at a peak), "
                      f"{ms:.2f} ms CPU per robot-s ({got['reason']})", flush=True)
                what = f"{name}, {robot}, bvp {label}"
                note = (f"{got['end']} at {got['robot_time_s']:.0f} s, {got['flushes']} flushes "
                        f"({got['traps']} at a peak)")
                figures += [Figure(f"{what}: coverage", round(got["coverage"], 4), "", note),
                            Figure(f"{what}: CPU per robot-second", round(ms, 2), "ms", note)]
    if args.record:
        record("bvp-traps", figures, section="studies",
               title="bvp on large real floors: the field relaxed anew at a stale peak (trap_time) or not")


if __name__ == "__main__":
    main()
