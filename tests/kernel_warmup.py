"""Compile the package's numba kernels into numba's cache before the test processes start (tests/conftest.py).

numba compiles a kernel at its first call and keeps it in its cache (`cache=True`, beside the source). On a
fresh clone the cache is empty: each test process would compile the kernels its tests meet first, the two
processes often the same ones at once, and a test that holds the machine alone (a real-time one) would compile
with the other process waiting. Run before them, in two processes splitting the work, these calls fill the cache
once; the tests load from it. A kernel a test calls with other argument types still compiles there.

    python tests/kernel_warmup.py PART      (PART: 0 or 1; `PARTS` of them)
"""

from __future__ import annotations

import sys
from collections.abc import Callable

PARTS = 2


def _localization() -> None:
    from robotexp.localization import covariance, kernels

    kernels.warm()
    covariance.warm()


def _planning() -> None:
    from robotexp.planning import grid_planner

    grid_planner.warm()


def _runs(*methods: str, localize: str = "none", odometry: str = "none") -> Callable[[], None]:
    def run() -> None:
        from robotexp.experiment import run_experiment
        from robotexp.run.spec import RunSpec

        for method in methods:
            spec = RunSpec(world="dense", method=method, max_time=5.0, localize=localize, odometry=odometry)
            run_experiment(spec, None, image=False)
    return run


def _team() -> None:
    from robotexp.experiment import run_team
    from robotexp.run.spec import RunSpec
    from robotexp.run.team import TeamSpec

    for coordinator in ("burgard", "minpos"):
        run_team(RunSpec(world="dense", method="frontier", max_time=5.0),
                 TeamSpec(robots=("p3dx", "p3dx"), coordinator=coordinator), None, image=False)
    run_team(RunSpec(world="dense", method="frontier", max_time=5.0),
             TeamSpec(robots=("p3dx", "p3dx"), coordinator="none", comm_range=3.0), None, image=False)


# two parts of about the same compile time on a 2-core machine
WORK: tuple[tuple[Callable[[], None], ...], ...] = (
    (_localization, _runs("frontier", localize="scan-match", odometry="p3dx"), _team),
    (_planning, _runs("frontier", "bvp", "meta-ga", "meta-firefly", "srt-laser", "srt-ball", "srt-star")),
)


def main(part: int) -> None:
    for job in WORK[part]:
        job()


if __name__ == "__main__":
    main(int(sys.argv[1]))
