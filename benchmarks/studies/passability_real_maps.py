"""Real maps before and after a change to the planners: one `robotexp explore` per map, method and robot,
run from each of two checkouts on the same core, and the table of both.

Each run: `python -m robotexp.cli explore --world MAP --method M --robot R --max-time T --out DIR` in the
checkout's folder (its code), pinned with `taskset -c CORE`. Success: coverage >= 0.95 of the explorable
space, no collision, ended by the explorer (`completed`: its "explored", not stopped by the run's check).
Rows already in the output folder are kept (run it again to resume); `--report` prints the table of what
is there.

    python benchmarks/studies/passability_real_maps.py --before /work/main --after . --out /tmp/pass \
        --maps strands_kth,ipa_lab_c --methods frontier,bvp --robots p3dx,kobuki --max-time 1800
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

MAPS = "/work/shared/maps"


def run_one(checkout: Path, python: str, world: str, method: str, robot: str, max_time: float, out: Path,
            core: int) -> dict[str, object]:
    """One run (skipped when its results.jsonl exists); its record."""
    rec = out / "results.jsonl"
    if not rec.exists():
        out.mkdir(parents=True, exist_ok=True)
        cmd = ["taskset", "-c", str(core), "nice", "-n", "5", python, "-m", "robotexp.cli", "explore",
               "--world", world, "--method", method, "--robot", robot, "--max-time", str(max_time),
               "--out", str(out), "--image-format", "png"]
        subprocess.run(cmd, cwd=checkout, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
    if not rec.exists():
        return {"reason": "no record"}
    return json.loads(rec.read_text().strip().splitlines()[-1])


def success(r: dict[str, object]) -> bool:
    cov = r.get("coverage")
    return (isinstance(cov, float) and cov >= 0.95 and r.get("collisions") == 0
            and r.get("completed") is True)


def cell(r: dict[str, object]) -> str:
    cov = r.get("coverage")
    c = f"{100 * cov:5.1f}" if isinstance(cov, (int, float)) else "  -  "
    return (f"{c} % {r.get('collisions', '-')!s:>2} col {float(r.get('robot_time_s', 0) or 0):6.0f} s "
            f"{str(r.get('reason', '-')).split(':')[0][:22]:<22} {'OK' if success(r) else '--'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, required=True, help="checkout whose code is the 'before'")
    ap.add_argument("--after", type=Path, required=True, help="checkout whose code is the 'after'")
    ap.add_argument("--python-before", default=sys.executable)
    ap.add_argument("--python-after", default=sys.executable)
    ap.add_argument("--maps", default="strands_kth,ipa_lab_c,stage_hospital,ipa_freiburg79,aws_small_house,eb_room")
    ap.add_argument("--methods", default="frontier,bvp")
    ap.add_argument("--robots", default="p3dx,kobuki")
    ap.add_argument("--max-time", type=float, default=1800.0)
    ap.add_argument("--core", type=int, default=1)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--only", choices=("before", "after"), help="run only this side")
    ap.add_argument("--report", action="store_true", help="run nothing: the table of what is recorded")
    args = ap.parse_args()
    sides = {"before": (args.before, args.python_before), "after": (args.after, args.python_after)}
    rows = []
    for name in args.maps.split(","):
        world = name if os.path.sep in name else next(
            str(p) for p in (Path(MAPS) / f"{name}.yaml", Path(MAPS) / f"{name}.map") if p.exists())
        for method in args.methods.split(","):
            for robot in args.robots.split(","):
                got = {}
                for side, (checkout, python) in sides.items():
                    out = args.out / side / f"{name}-{method}-{robot}"
                    if args.report or (args.only and args.only != side):
                        rec = out / "results.jsonl"
                        got[side] = (json.loads(rec.read_text().strip().splitlines()[-1]) if rec.exists()
                                     else {"reason": "not run"})
                    else:
                        got[side] = run_one(checkout.resolve(), python, world, method, robot, args.max_time,
                                            out.resolve(), args.core)
                rows.append((name, method, robot, got))
                print(f"{name:<16} {method:<9} {robot:<7} | {cell(got['before'])} | {cell(got['after'])}", flush=True)
    n = {s: sum(success(g[s]) for *_, g in rows) for s in sides}
    print(f"successes: before {n['before']}/{len(rows)}, after {n['after']}/{len(rows)}")


if __name__ == "__main__":
    main()
