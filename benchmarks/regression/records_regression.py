"""Records regression: run a list of (world, method, pose, speed) through the public entry point and
write every record to a JSONL file; or compare two such files key by key, wall times aside.

A restructure of the run loop must leave every record as it was: same path lengths, coverage,
milestones and curves to the last digit. Record a baseline before the change and compare after:

    python benchmarks/regression/records_regression.py record /tmp/before.jsonl            # minutes of CPU
    python benchmarks/regression/records_regression.py record /tmp/after.jsonl
    python benchmarks/regression/records_regression.py compare /tmp/before.jsonl /tmp/after.jsonl

`record` takes `--only world:method` (repeatable) to run a subset, and `--max-time S` to cut every
run short (a quick check). Besides the record, each line holds the SHA-256 of the run's coverage
curve and true-path CSV files (`curve_sha256`, `path_sha256`), so a change anywhere along the run
shows, not only at its end. `compare` prints one line per difference and exits 1 when there is one.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from robotexp.run.spec import RunSpec
from robotexp.experiment import run_experiment

# every built-in explorer on dense and sparse from the default pose at the default speed; srt-ball
# only in sparse (it stops at once in dense); waypoints where the world has waypoint lists
CASES: list[tuple[str, str, str | None, float]] = [
    (world, method, None, 0.3)
    for world in ("dense", "sparse")
    for method in ("frontier", "bvp", "srt-ball", "srt-star", "srt-laser", "meta-ga", "meta-firefly",
                   "meta-exhaustive")
    if not (world == "dense" and method == "srt-ball")
] + [("ufmg-static", "waypoints", None, 0.3), ("ufmg-static", "frontier", None, 0.3)]

# fields that measure the machine, not the run
IGNORED = {"wall_time_s", "case_wall_s"}


def _sha(path: Path) -> str | None:
    return hashlib.sha256(path.read_bytes()).hexdigest() if path.exists() else None


def record(out: Path, only: list[str], max_time: float | None) -> None:
    """Run the cases (or those named in `only`, as world:method) and append their records to `out`."""
    cases = [c for c in CASES if not only or f"{c[0]}:{c[1]}" in only]
    if not cases:
        sys.exit(f"records_regression: no case matches {only}; cases: "
                 + ", ".join(f"{w}:{m}" for w, m, _, _ in CASES))
    out.parent.mkdir(parents=True, exist_ok=True)
    for world, method, pose, speed in cases:
        spec = RunSpec(world=world, method=method, pose=pose, speed=speed)
        if max_time is not None:
            spec.max_time = max_time
        t0 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            result = run_experiment(spec, Path(tmp), image=False)
            rec: dict[str, Any] = dict(result.record)
            name = rec["run"]
            rec["curve_sha256"] = _sha(Path(tmp) / f"{name}.coverage.csv")
            rec["path_sha256"] = _sha(Path(tmp) / f"{name}.path.csv")
        rec["case_wall_s"] = round(time.perf_counter() - t0, 1)
        with open(out, "a", encoding="utf-8") as f:
            f.write(json.dumps(rec) + "\n")
        print(f"{world} {method}: {rec['path_length_m']} m, coverage {rec['coverage']}, {rec['reason']} "
              f"({rec['case_wall_s']} s)", flush=True)


def _key(rec: dict[str, Any]) -> str:
    return f"{rec['world']}:{rec['method']}:{rec.get('pose')}:{rec['max_speed_m_s']}"


def compare(a: Path, b: Path, ignore: frozenset[str] = frozenset()) -> int:
    """Print every difference between the records of `a` and `b` (matched by world, method, pose,
    speed), wall times and the keys in `ignore` aside; return the number of differences."""
    def load(p: Path) -> dict[str, dict[str, Any]]:
        return {_key(r): r for r in (json.loads(line) for line in p.read_text().splitlines() if line.strip())}
    ra, rb = load(a), load(b)
    diffs = 0
    for key in sorted(set(ra) | set(rb)):
        if key not in ra or key not in rb:
            print(f"{key}: only in {a if key in ra else b}")
            diffs += 1
            continue
        x, y = ra[key], rb[key]
        for k in sorted(set(x) | set(y)):
            if k in IGNORED or k in ignore:
                continue
            if x.get(k, "<missing>") != y.get(k, "<missing>"):
                print(f"{key}: {k}: {x.get(k, '<missing>')!r} != {y.get(k, '<missing>')!r}")
                diffs += 1
    print(f"{len(set(ra) & set(rb))} runs compared, {diffs} difference(s)")
    return diffs


def main() -> None:
    """Command line: `record OUT.jsonl [--only world:method ...] [--max-time S]` or
    `compare A B [--ignore KEY ...]`."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="mode", required=True)
    r = sub.add_parser("record", help="run the cases and write their records")
    r.add_argument("out", type=Path)
    r.add_argument("--only", action="append", default=[], help="world:method (repeatable)")
    r.add_argument("--max-time", type=float, default=None, help="[s] robot time per run")
    c = sub.add_parser("compare", help="compare two record files, wall times aside")
    c.add_argument("a", type=Path)
    c.add_argument("b", type=Path)
    c.add_argument("--ignore", action="append", default=[],
                   help="a key not to compare (repeatable), e.g. one a later change added to every record")
    args = ap.parse_args()
    if args.mode == "record":
        record(args.out, args.only, args.max_time)
    else:
        sys.exit(1 if compare(args.a, args.b, frozenset(args.ignore)) else 0)


if __name__ == "__main__":
    main()
