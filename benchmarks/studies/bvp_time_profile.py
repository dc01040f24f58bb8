"""Where a bvp run's robot time goes: how fast the robot drives and why, with a given number of sweeps.

BVP's speed law (eqs. 3.4-3.5) scales the top speed by the heading error ((180 - |varphi|) / 180) and by
the nearest return (rho, d / r_max within r_max of the robot's edge); the heading follows the descent
of a potential relaxed by `sweeps` Gauss-Seidel sweeps a second. A field that has not converged turns
under the robot (its goals change faster than the sweeps carry the change across the map), so the
robot zigzags and slows. For each `--sweeps` value this runs bvp on the world and prints the record
(coverage, robot time, path, end) and the share of robot time at each commanded speed, the mean of
the two factors of eq. 3.5 and the share of steps with a heading error above 45 degrees.

    python benchmarks/studies/bvp_time_profile.py [--world generated:office:0] [--sweeps 30,150] [--max-time 3600]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any


def profile(world: str, sweeps: int, max_time: float) -> str:
    """Run bvp on `world` with `sweeps` and describe where its robot time went."""
    import numpy as np

    import robotexp_plugins.bvp as bvp
    from robotexp.run.spec import RunSpec
    from robotexp.experiment import run_experiment
    from robotexp.run.observers import RunObserver

    factors: list[tuple[float, float]] = []
    law = bvp.speed_law

    def recording_law(v_prev: float, varphi: float, d: float, **kw: float) -> float:
        rho = max(d, 0.0) / kw["r_max"] if d <= kw["r_max"] else 1.0
        factors.append((abs(math.degrees(bvp.wrap_angle(varphi))), rho))
        return law(v_prev, varphi, d, **kw)

    class Steps(RunObserver):
        def __init__(self) -> None:
            self.rows: list[tuple[float, float]] = []

        def on_step(self, run: Any, step: Any) -> None:
            self.rows.append((step.time, float(getattr(step.decision, "v", math.nan))))

    steps = Steps()
    bvp.speed_law = recording_law       # type: ignore[assignment]
    try:
        t0 = time.process_time()
        out = run_experiment(RunSpec(world=world, method="bvp", max_time=max_time, params={"sweeps": sweeps}), None,
                             observers=[steps], image=False)
        cpu = time.process_time() - t0
    finally:
        bvp.speed_law = law             # type: ignore[assignment]
    r = out.record
    s = np.array(steps.rows)
    dt, v = np.diff(s[:, 0]), s[:-1, 1]
    lines = [f"{world} bvp sweeps={sweeps}: coverage {r.coverage}, {r.robot_time_s:.0f} s, {r.path_length_m:.1f} m, "
             f"mean speed {r.path_length_m / max(r.robot_time_s, 1e-9):.3f} m/s, {cpu:.1f} s CPU; {r.reason}"]
    shares = []
    for lo, hi in ((-math.inf, 0.02), (0.02, 0.1), (0.1, 0.2), (0.2, 0.29), (0.29, math.inf)):
        m = (v > lo) & (v <= hi)
        shares.append(f"({lo:g}, {hi:g}] {dt[m].sum() / dt.sum():.2f}")
    lines.append("  share of robot time at commanded speed [m/s]: " + ", ".join(shares))
    if factors:
        f = np.array(factors)
        lines.append(f"  eq. 3.5 factors: heading (180 - |varphi|) / 180 mean {((180 - f[:, 0]) / 180).mean():.3f}, "
                     f"|varphi| > 45 deg in {(f[:, 0] > 45).mean():.2f} of steps; rho mean {f[:, 1].mean():.3f}")
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="generated:office:0")
    ap.add_argument("--sweeps", default="30,150", help="comma-separated sweeps per update (the thesis: 30)")
    ap.add_argument("--max-time", type=float, default=3600.0, help="robot-time limit per run [s]")
    args = ap.parse_args()
    try:
        values = [int(v) for v in args.sweeps.split(",")]
    except ValueError:
        print(f"bvp_time_profile: --sweeps must be integers, got {args.sweeps!r}", file=sys.stderr)
        return 2
    for sweeps in values:
        print(profile(args.world, sweeps, args.max_time), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
