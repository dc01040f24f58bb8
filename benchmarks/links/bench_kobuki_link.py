"""Kobuki link benchmark: codec throughput and control-loop latency through the emulator.

1. Codec: decode a stream of emulator-like feedback frames (IDs 1, 3, 4, 5, 6, 13, 16; 81 bytes each),
   fed in 256-byte chunks, and report frames/s (the robot sends 50/s).
2. Latency: a `KobukiRobot` connected to a `KobukiEmulator` over TCP (127.0.0.1) runs a control loop
   on its robot-paced clock with a 20 ms period (one command per feedback frame); for each cycle it
   measures the time from the state frame being decoded (reader thread) to the Base Control being
   written (`KobukiRobot.frame_time` -> `command_time`). Reported as median / 95th percentile / max.

Run: python benchmarks/links/bench_kobuki_link.py [--frames 20000] [--seconds 4] [--speedup 1]
"""

from __future__ import annotations

import argparse
import statistics
import time

from robotexp.robot import Twist
from robotexp.world.builtin import builtin_world
from robotexp_drivers.kobuki.codec import (
    BasicSensorData,
    CliffSensors,
    DockingIR,
    FrameDecoder,
    GeneralPurposeInput,
    InertialSensor,
    MotorCurrent,
    RawGyro,
    encode_messages,
)
from robotexp_drivers.kobuki.emulator import KobukiEmulator
from robotexp_drivers.kobuki.robot import KobukiRobot
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/: perflog
from perflog import Figure, record  # noqa: E402


def codec_rate(n_frames: int) -> tuple[float, float]:
    """Decode `n_frames` feedback frames; return (frames/s, MB/s)."""
    frames = [encode_messages(
        BasicSensorData(20 * i % 65536, 0, 0, 0, 7 * i % 65536, 9 * i % 65536, 10, 12, 0, 0, 165, 0),
        DockingIR(0, 0, 0), InertialSensor(i % 18000, 100), CliffSensors(2000, 2000, 2000), MotorCurrent(20, 20),
        RawGyro(2 * i % 256, ((0, 0, 100), (0, 0, 101))), GeneralPurposeInput(0, 0, 0, 0, 0))
        for i in range(1000)]
    stream = b"".join(frames[i % len(frames)] for i in range(n_frames))
    dec = FrameDecoder()
    t0 = time.perf_counter()
    got = 0
    for pos in range(0, len(stream), 256):
        got += len(dec.feed(stream[pos:pos + 256]))
    dt = time.perf_counter() - t0
    assert got == n_frames, (got, n_frames)
    return got / dt, len(stream) / dt / 1e6


def loop_latency(seconds: float, speedup: float) -> tuple[list[float], int]:
    """Run a one-command-per-frame loop for `seconds` of robot time; return latencies [s] and cycles."""
    world = builtin_world("ufmg-static")
    latencies: list[float] = []
    with KobukiEmulator(world, pose=world.poses["path1"], speedup=speedup) as emu:
        with KobukiRobot(emu.address, sound=False) as robot:
            clock = robot.make_clock(0.02)
            cycles = 0
            while clock.now() < seconds:
                clock.tick()
                state = robot.read()
                robot.command(Twist(0.1 if state.time % 2 < 1 else -0.1, 0.3))
                latencies.append(robot.command_time - robot.frame_time)
                cycles += 1
    return latencies, cycles


def main() -> None:
    """Print the codec throughput and the loop latency."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=20000)
    ap.add_argument("--seconds", type=float, default=4.0, help="robot time of the latency loop [s]")
    ap.add_argument("--speedup", type=float, default=1.0, help="emulator speed-up (1 = real 50 Hz)")
    args = ap.parse_args()
    rate, mbs = codec_rate(args.frames)
    print(f"codec: {rate:,.0f} feedback frames/s decoded ({mbs:.2f} MB/s; the robot sends 50 frames/s)")
    lat, cycles = loop_latency(args.seconds, args.speedup)
    ms = sorted(x * 1000 for x in lat)
    p95 = ms[min(len(ms) - 1, int(0.95 * len(ms)))]
    print(f"loop (speedup {args.speedup:g}, {cycles} cycles of 20 ms robot time): state frame decoded -> "
          f"Base Control written: median {statistics.median(ms):.3f} ms, p95 {p95:.3f} ms, max {ms[-1]:.3f} ms")
    record("kobuki-link", [
        Figure("codec: feedback frames decoded", rate, "per s", "the robot sends 50 per s"),
        Figure("state frame -> Base Control latency, median", statistics.median(ms), "ms", f"{cycles} cycles"),
        Figure("state frame -> Base Control latency, p95", p95, "ms"),
    ], title="Kobuki link through the emulator", section="links", parameters={"speedup": args.speedup})


if __name__ == "__main__":
    main()
