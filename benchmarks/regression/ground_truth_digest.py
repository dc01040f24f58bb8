"""Digest of the ground truth (reachable and explorable cells) of many worlds, to compare two trees.

For every built-in world at each of its named poses, every map given (files or folders of .yaml/.map)
and generated office, warehouse and cave worlds (--seeds), from the run's default start and at the
default 10 cm cell: the counts of reachable and explorable cells and a hash of each grid, as JSON
lines. Run it under each tree's robotexp and compare:

    python benchmarks/regression/ground_truth_digest.py MAPS_DIR --seeds 0-49 > new.jsonl
    python benchmarks/regression/ground_truth_digest.py --compare old.jsonl new.jsonl

Coverage's denominator is the explorable cells: where their hash is equal, every coverage is.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path


def _worlds(maps: list[str], seeds: range) -> list[tuple[str, str | None]]:
    from robotexp.world.builtin import builtin_names
    from robotexp.world.loader import load_world

    out: list[tuple[str, str | None]] = []
    for name in builtin_names():
        poses = list(load_world(name).poses)
        out += [(name, p) for p in poses] if poses else [(name, None)]
    for m in maps:
        path = Path(m)
        files = sorted([*path.glob("*.yaml"), *path.glob("*.map")]) if path.is_dir() else [path]
        out += [(str(f), None) for f in files]
    out += [(f"generated:{kind}:{s}", None) for kind in ("office", "warehouse", "cave") for s in seeds]
    return out


def digest(maps: list[str], seeds: range) -> None:
    from robotexp.run.spec import RunSpec, plan_run
    from robotexp.world.loader import load_world

    for world, pose in _worlds(maps, seeds):
        t0 = time.perf_counter()
        plan = plan_run(RunSpec(world=world, method="frontier", pose=pose), load_world(world), 0.25)
        t = plan.truth
        print(json.dumps({"world": world, "pose": pose,
                          "reachable": int(t.reachable.sum()), "explorable": int(t.explorable.sum()),
                          "reachable_hash": hashlib.sha1(t.reachable.tobytes()).hexdigest()[:16],
                          "explorable_hash": hashlib.sha1(t.explorable.tobytes()).hexdigest()[:16],
                          "seconds": round(time.perf_counter() - t0, 3)}), flush=True)


def compare(a: str, b: str) -> None:
    def load(p: str) -> dict[tuple[str, str | None], dict[str, object]]:
        return {(r["world"], r["pose"]): r for r in map(json.loads, Path(p).read_text().splitlines())}

    old, new = load(a), load(b)
    same = 0
    for key in old.keys() & new.keys():
        o, n = old[key], new[key]
        if o["explorable_hash"] == n["explorable_hash"] and o["reachable_hash"] == n["reachable_hash"]:
            same += 1
            continue
        print(f"{key[0]} {key[1] or ''}: reachable {o['reachable']} -> {n['reachable']}, "
              f"explorable {o['explorable']} -> {n['explorable']}"
              + (" (explorable cells the same)" if o["explorable_hash"] == n["explorable_hash"] else ""))
    print(f"{same} of {len(old.keys() & new.keys())} worlds identical; only in one file: "
          f"{len(old.keys() ^ new.keys())}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("maps", nargs="*", help="map files or folders")
    ap.add_argument("--seeds", default="0-49", help="generated worlds' seeds A-B (default 0-49)")
    ap.add_argument("--compare", nargs=2, metavar=("OLD", "NEW"), help="compare two digests")
    args = ap.parse_args()
    if args.compare:
        compare(*args.compare)
        return
    a, _, b = args.seeds.partition("-")
    digest(args.maps, range(int(a), int(b or a) + 1))


if __name__ == "__main__":
    sys.exit(main())
