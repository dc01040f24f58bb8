"""Per laser: the decode rate of its codec and the latency from a scan received to the map updated.

For every laser registered in `robotexp.lasers` that has an emulator of the same name in
`robotexp.laser_emulators`:

- decode rate: a stream of `--scans` scans made by the driver package's `codec.encode_scan` (ranges a
  simulated robot measures in `--world`) fed to `codec.ScanDecoder().feed` in 4 KiB reads: scans/s
  and MB/s;
- latency: the emulator serves the laser on a pseudo-terminal from a simulated robot standing in the
  world (`robotexp.sim.mounted_source`), the driver reads it, and each scan goes into an
  `OccupancyGrid` of the default cell over the world (as `ExplorationRun` does, with the laser's own
  range): the time from the scan's stamp (when the driver had it complete) to the grid updated,
  median and 95th percentile over `--latency-scans` scans, and how many scans the loop missed.

Run: python benchmarks/links/bench_lasers.py [--world ufmg-static] [--scans 2000] [--latency-scans 40]
Prints one line per laser; exit status 1 when a laser could not be measured.
"""

from __future__ import annotations

import argparse
import time
from importlib import import_module
from types import ModuleType

import numpy as np

from robotexp.run.spec import DEFAULT_CELL, MAP_MARGIN
from robotexp.world.poses import resolve_pose
from robotexp.laser import LASER_EMULATORS, LASERS, Laser
from robotexp.mapping.geometry import GridGeometry
from robotexp.mapping.grid import OccupancyGrid
from robotexp.registry import available, load
from robotexp.sim import SimRobot, mounted_source, preset
from robotexp.world.builtin import builtin_world


def _codec(driver: type) -> ModuleType:
    """The codec module next to a driver class (its package's `codec`)."""
    module = driver.__module__
    for name in (module + ".codec", module.rpartition(".")[0] + ".codec"):
        try:
            return import_module(name)
        except ImportError:
            continue
    raise ImportError(f"no codec module next to {module}")


def decode_rate(codec: ModuleType, ranges: np.ndarray, scans: int) -> tuple[float, float, int]:
    """(scans/s, MB/s, scans decoded) of `codec.ScanDecoder().feed` over `scans` encoded scans."""
    frame = codec.encode_scan(ranges)
    data = frame * scans
    dec = codec.ScanDecoder()
    got = 0
    t0 = time.perf_counter()
    for pos in range(0, len(data), 4096):
        got += len(dec.feed(data[pos:pos + 4096]))
    elapsed = time.perf_counter() - t0
    return got / elapsed, len(data) / elapsed / 1e6, got


def latency(laser: Laser, grid: OccupancyGrid, pose: object, count: int) -> tuple[list[float], int]:
    """Stamp-to-grid latencies [s] of `count` scans, and the scans missed between them."""
    grid.update(pose, laser.wait_scan(-1, 3.0).scan)      # compile / warm the kernels before timing
    s = laser.wait_scan(-1, 3.0)                            # the newest scan: time from here on
    out: list[float] = []
    missed = 0
    for _ in range(count):
        nxt = laser.wait_scan(s.seq, 3.0)
        missed += nxt.seq - s.seq - 1
        s = nxt
        grid.update(pose, s.scan)
        out.append(time.monotonic() - s.stamp)
    return out, missed


def bench(name: str, world_name: str, scans: int, latency_scans: int) -> str:
    """One laser's line."""
    driver = load(LASERS, name, Laser)
    emulator_cls = load(LASER_EMULATORS, name, object)
    codec = _codec(driver)
    world = builtin_world(world_name)
    robot = preset("kobuki")
    start, _ = resolve_pose(world, None, robot.radius)
    assert world.bounds is not None
    geo = GridGeometry.covering(*world.bounds, cell=DEFAULT_CELL, margin=MAP_MARGIN)
    with SimRobot(world, robot=robot, pose=start, sonar=False) as sim:
        source = mounted_source(sim)
        source(np.linspace(-1.0, 1.0, 8), 4.0)              # compile the ray caster before the laser times out
        emulator = emulator_cls(source, pty=True)
        try:
            emulator.start()
            laser = driver(emulator.address)
            try:
                g = laser.geometry
                ranges = source(g.angles(), g.range_max)
                rate, mbs, got = decode_rate(codec, ranges, scans)
                grid = OccupancyGrid(geo)
                lat, missed = latency(laser, grid, sim.true_pose, latency_scans)
            finally:
                laser.close()
        finally:
            emulator.close()
    ms = np.array(lat) * 1000.0
    return (f"{name}: decode {rate:,.0f} scans/s ({mbs:.1f} MB/s, {got} of {scans} scans); scan stamp -> grid "
            f"updated median {np.median(ms):.2f} ms, p95 {np.percentile(ms, 95):.2f} ms over {len(lat)} scans, "
            f"{missed} missed ({g.beams} beams, {g.range_max:g} m, {1 / g.period:.1f} Hz, {world_name}, "
            f"cell {DEFAULT_CELL:g} m)")


def main() -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="ufmg-static", help="builtin world the emulated laser looks at")
    parser.add_argument("--scans", type=int, default=2000, help="scans in the decode-rate stream")
    parser.add_argument("--latency-scans", type=int, default=40, help="scans timed from stamp to grid")
    args = parser.parse_args()
    if args.scans < 2 or args.latency_scans < 1:
        parser.error("--scans must be >= 2 and --latency-scans >= 1")
    names = sorted(set(available(LASERS)) & set(available(LASER_EMULATORS)))
    failed = 0
    for name in names:
        try:
            print(bench(name, args.world, args.scans, args.latency_scans), flush=True)
        except Exception as exc:  # noqa: BLE001 - one laser's failure must not hide the others' figures
            failed += 1
            print(f"{name}: not measured: {type(exc).__name__}: {exc}", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
