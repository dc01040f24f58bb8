"""Fuzz the MAVLink codec: random and mutated streams must never raise, and valid frames survive noise.

Usage: python benchmarks/fuzz/fuzz_mavlink.py [N] [SEED]   (default 100000 streams)
"""

from __future__ import annotations

import random
import sys
import time

from robotexp_drivers.mavlink.codec import MavlinkCodec


def main(n: int = 100_000, seed: int = 0) -> int:
    """Run `n` streams; return 1 when a valid frame in noise was lost."""
    rng = random.Random(seed)
    tx = MavlinkCodec(1, 1)
    good = [tx.encode(tx.mav.heartbeat_encode(10, 3, 0x81, 15, 4, 3)),
            tx.encode(tx.mav.attitude_encode(42, 0, 0, 0.5, 0, 0, 0.1)),
            tx.encode(tx.mav.obstacle_distance_encode(7, 0, [300] * 72, 5, 10, 300, 5.0, 0.0, 12))]
    rx = MavlinkCodec(255, 190)
    lost = 0
    t0 = time.perf_counter()
    for i in range(n):
        noise = bytes(rng.getrandbits(8) for _ in range(rng.randrange(64)))
        if i % 3 == 0:
            noise = bytes([rng.choice((0xFD, 0xFE))]) + noise
        frame = good[i % 3]
        if i % 2:     # a mutated copy first: bit flips, truncation
            bad = bytearray(frame)
            bad[rng.randrange(len(bad))] ^= 1 << rng.randrange(8)
            noise += bytes(bad[: rng.randrange(1, len(bad) + 1)])
        got = rx.feed(noise + frame + bytes(300))
        lost += not any(bytes(m.get_msgbuf()) == frame for m in got)
    dt = time.perf_counter() - t0
    print(f"{n} streams in {dt:.1f} s: {rx.frames} frames, {rx.bad_frames} bad frames, {rx.unknown} unknown, "
          f"{rx.dropped_bytes} bytes dropped, valid frames lost: {lost}")
    return 1 if lost else 0


if __name__ == "__main__":
    sys.exit(main(*(int(a) for a in sys.argv[1:3])))
