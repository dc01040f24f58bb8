"""P3-DX link benchmark: codec throughput and control-loop latency through the emulator.

Run: python benchmarks/links/bench_p3dx_link.py
Prints packets/s decoded (SIPs with 16 sonar readings, and 0x61 laser packets) and the latency
from the moment the driver has a complete state (SIP + scan) to the moment its velocity command
has been written, over TCP on 127.0.0.1 with the emulator at 10x speed.
"""

from __future__ import annotations

import statistics
import time

from robotexp.robot import Twist
from robotexp.sim import LaserConfig
from robotexp_drivers.p3dx import codec as k
from robotexp_drivers.p3dx.emulator import P3DXEmulator
from robotexp_drivers.p3dx.robot import P3DXRobot
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/: perflog
from perflog import Figure, record  # noqa: E402


def codec_throughput(n: int = 20000) -> tuple[float, float]:
    """Packets per second decoded: (SIPs, laser packets)."""
    sip = k.encode_packet(k.StandardSip(xpos=1000, ypos=2000, thpos=300, sonar=tuple((i, 1000 + i) for i in range(16)),
                                        grip_state=0, analog_port=0, analog=0, digin=0, digout=0, battery_x10=130,
                                        charge_state=0, rot_vel_x10=0, fault_flags=0, lat_vel=0, temperature=-127,
                                        state_of_charge=0))
    laser = b"".join(k.encode_laser_scan(list(range(1000, 1181))))
    out = []
    for stream, count in ((sip * n, n), (laser * (n // 6), (n // 6) * 6)):
        dec = k.PacketDecoder(max_count=255)
        t0 = time.perf_counter()
        for i in range(0, len(stream), 4096):
            dec.feed(stream[i:i + 4096])
        out.append(count / (time.perf_counter() - t0))
    return out[0], out[1]


def control_latency(cycles: int = 300) -> list[float]:
    """Seconds from a complete state in the driver to its velocity command written."""
    lat: list[float] = []
    with P3DXEmulator("ufmg-static", port=0, speedup=10.0, laser=LaserConfig(range_max=3.0)) as emu:
        with P3DXRobot(emu.address, laser_range=3.0) as robot:
            published: list[float] = []
            original = robot._publish

            def stamp(state: object) -> None:
                published.append(time.perf_counter())
                original(state)  # type: ignore[arg-type]

            robot._publish = stamp  # type: ignore[method-assign]
            clock = robot.make_clock(0.1)
            for _ in range(cycles):
                clock.tick()
                robot.read()
                robot.command(Twist(0.0, 0.1))
                lat.append(time.perf_counter() - published[-1])
    return lat


def main() -> None:
    """Print the measurements."""
    sips, lasers = codec_throughput()
    print(f"codec: {sips:,.0f} SIPs/s decoded (16 sonar), {lasers:,.0f} laser packets/s (32 readings)")
    lat = sorted(control_latency())
    print(f"state -> command latency over {len(lat)} cycles: median {statistics.median(lat) * 1e3:.2f} ms, "
          f"p95 {lat[int(0.95 * len(lat))] * 1e3:.2f} ms, max {lat[-1] * 1e3:.2f} ms")
    record("p3dx-link", [
        Figure("codec: SIPs decoded (16 sonar)", sips, "per s"),
        Figure("codec: laser packets decoded (32 readings)", lasers, "per s"),
        Figure("state -> command latency, median", statistics.median(lat) * 1e3, "ms", f"{len(lat)} cycles"),
        Figure("state -> command latency, p95", lat[int(0.95 * len(lat))] * 1e3, "ms"),
    ], title="P3-DX link (ARIA protocol) through the emulator", section="links")


if __name__ == "__main__":
    main()
