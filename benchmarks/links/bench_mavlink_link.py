"""MAVLink driver: codec throughput and control-loop latency through the emulator (UDP, 127.0.0.1).

Latency: from the moment the backend decoded a LOCAL_POSITION_NED to the moment the control loop's
velocity target left (robot.state_time -> robot.command_time), over 200 paced ticks.
"""

from __future__ import annotations

import statistics
import time

from robotexp.robot import Twist
from robotexp.world.builtin import builtin_world
from robotexp_drivers.mavlink.codec import MavlinkCodec
from robotexp_drivers.mavlink.emulator import MavlinkEmulator
from robotexp_drivers.mavlink.robot import MavlinkRobot
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/: perflog
from perflog import Figure, record  # noqa: E402


def codec_throughput(n: int = 20_000) -> list[Figure]:
    """Print decoded packets/s for position, attitude and obstacle-distance packets."""
    figures: list[Figure] = []
    tx = MavlinkCodec(1, 1)
    for name, msg in (("LOCAL_POSITION_NED", tx.mav.local_position_ned_encode(1, 1, 2, 0, 0.1, 0.2, 0)),
                      ("ATTITUDE", tx.mav.attitude_encode(1, 0, 0, 0.5, 0, 0, 0.1)),
                      ("OBSTACLE_DISTANCE", tx.mav.obstacle_distance_encode(1, 0, [300] * 72, 5, 10, 300, 5.0, 0, 12))):
        data = b"".join(tx.encode(msg) for _ in range(n))
        rx = MavlinkCodec(255, 190)
        t0 = time.perf_counter()
        got = rx.feed(data)
        dt = time.perf_counter() - t0
        print(f"codec: {name:20s} {len(got) / dt:10.0f} packets/s ({len(data) / len(got):.0f} bytes each)")
        figures.append(Figure(f"codec: {name} decoded", len(got) / dt, "per s"))
    return figures


def loop_latency(ticks: int = 200) -> list[Figure]:
    """Print the state-to-command latency of a paced control loop against the emulator."""
    lat = []
    with MavlinkEmulator(builtin_world("ufmg-static"), speedup=1.0) as emu:
        with MavlinkRobot(emu.address) as robot:
            clock = robot.make_clock(0.05)
            for _ in range(ticks):
                clock.tick()
                robot.read()
                robot.command(Twist(0.0, 0.1))
                lat.append(robot.command_time - robot.state_time)
    lat_ms = sorted(x * 1000 for x in lat)
    print(f"loop: state packet -> velocity target: median {statistics.median(lat_ms):.3f} ms, "
          f"p95 {lat_ms[int(0.95 * len(lat_ms))]:.3f} ms, max {lat_ms[-1]:.3f} ms over {ticks} ticks")
    return [Figure("state packet -> velocity target latency, median", statistics.median(lat_ms), "ms",
                   f"{ticks} ticks"),
            Figure("state packet -> velocity target latency, p95", lat_ms[int(0.95 * len(lat_ms))], "ms")]


if __name__ == "__main__":
    record("mavlink-link", codec_throughput() + loop_latency(),
           title="MAVLink rover link (UDP) through the emulator", section="links")
