"""What recording costs a simulated run: the same run with and without `--record`, and the replay.

    python benchmarks/speed/bench_record.py [WORLD] [MAX_TIME_S]

Prints the wall time of each, the ratio recorded / plain, the bag's size, and the replay's wall time
(measured in this one process, one after the other: the machine is noisy, compare ratios).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from robotexp.bag.recorder import BagRecorder
from robotexp.bag.replay import read_bag, replay_bag
from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/: perflog
from perflog import Figure, record  # noqa: E402


def main() -> None:
    world = sys.argv[1] if len(sys.argv) > 1 else "dense"
    max_time = float(sys.argv[2]) if len(sys.argv) > 2 else 300.0
    spec = RunSpec(world=world, max_time=max_time)
    run_experiment(RunSpec(world=world, max_time=5.0), None)          # numba compiles outside the timing
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "run.mcap"
        t0 = time.perf_counter()
        plain = run_experiment(spec, None)
        t1 = time.perf_counter()
        recorded = run_experiment(spec, None, observers=[BagRecorder(bag, world=world)])
        t2 = time.perf_counter()
        again = replay_bag(read_bag(bag), None)
        t3 = time.perf_counter()
        assert again.record is not None
        same = (again.record.coverage, again.record.path_length_m) == \
            (recorded.record.coverage, recorded.record.path_length_m)
        print(f"{world}, {max_time:g} s of robot time: plain {t1 - t0:.2f} s, recorded {t2 - t1:.2f} s "
              f"(x{(t2 - t1) / (t1 - t0):.2f}), bag {bag.stat().st_size / 1e6:.1f} MB, replay {t3 - t2:.2f} s; "
              f"replay reproduces coverage and path: {same}; plain run coverage {plain.record.coverage}")
        record("record", [
            Figure("recorded run's wall time / the same run without --record", (t2 - t1) / (t1 - t0), "x"),
            Figure("recording size", bag.stat().st_size / 1e6, "MB"),
            Figure("replay's wall time / the plain run's", (t3 - t2) / (t1 - t0), "x"),
            Figure("replay reproduces coverage and path length", float(same), "1 = yes"),
        ], title="Recording a run (MCAP) and replaying it", section="output",
            parameters={"world": world, "robot time": f"{max_time:g} s"})


if __name__ == "__main__":
    main()
