"""Fuzz and time the RPLidar decoders (robotexp_drivers.lasers.rplidar.codec ScanDecoder, RequestDecoder).

Each stream holds 1..6 turns of 36 nodes (a 10-deg binning keeps 100,000 streams quick; the node
format is the same at 360) separated by noise, then the first node of one more turn (which completes
the last); most streams then get random byte flips, insertions and deletions, and all are fed in
random chunks. Every other stream also goes through the request decoder with valid requests among
the noise. Reports turns recovered, nodes, bytes dropped, short turns, any exception (there must be
none), and, for streams left intact whose noise cannot pass for a node (bytes whose two low bits are
equal), any turn lost or altered (there must be none). The SCAN protocol has no checksum: in
mutated streams noise that passes the node checks lands in the turn it falls into, which is why the
decoder drops turns of too few nodes and keeps the nearest echo per beam. Then times clean decoding
of full 360-node turns. A quarter as many EXPRESS_SCAN streams (1..60 capsules of an A1's 720-sample
turn, noise between them that cannot pass for a capsule's sync nibble when intact) go through the
express decoder likewise: no exception, every turn of an intact stream exactly the turn sent.

Run: python benchmarks/fuzz/fuzz_rplidar.py [--streams 100000] [--seed 0]
Exit status 1 when an exception or a lost turn was found.
"""

from __future__ import annotations

import argparse
import random
import time

import numpy as np

from fuzz_streams import Tally, feed_in_chunks, mutate

from robotexp_drivers.lasers.rplidar import codec as k
from robotexp_drivers.lasers.rplidar import constants as C

BEAMS = 36


def _turn(rng: random.Random) -> tuple[bytes, np.ndarray]:
    """A random turn and the ranges it must decode to."""
    q2 = np.array([rng.randrange(600, 48000) if rng.random() < 0.9 else 0 for _ in range(BEAMS)], np.float64)
    ranges = np.where(q2 > 0, q2 / 4000.0, np.inf)
    return k.encode_scan(ranges, quality=rng.randrange(1, 64)), ranges


def _requests(rng: random.Random) -> list[bytes]:
    return [k.request(c) for c in (C.CMD_STOP, C.CMD_RESET, C.CMD_SCAN, C.CMD_FORCE_SCAN, C.CMD_GET_INFO,
                                   C.CMD_GET_HEALTH, C.CMD_GET_SAMPLERATE)] + [
        k.request(C.CMD_SET_MOTOR_PWM, rng.randrange(1024).to_bytes(2, "little")) for _ in range(8)] + [
        k.request(C.CMD_EXPRESS_SCAN, bytes(5))]


_NODE_FREE = bytes(b for b in range(256) if not (b ^ (b >> 1)) & 1 and b != C.SYNC_BYTE)


def _noise(rng: random.Random, node_free: bool) -> bytes:
    n = rng.randrange(24)
    if node_free:
        return bytes(rng.choice(_NODE_FREE) for _ in range(n))
    return bytes(rng.randrange(256) for _ in range(n))


EXPRESS_SAMPLES = 720          # an A1 turn in express mode: a capsule spans 16 deg
_CAPSULE_FREE = bytes(b for b in range(256) if b >> 4 != C.EXPRESS_SYNC_1)


def _express_stream(rng: random.Random, mutated: bool) -> tuple[bytearray, np.ndarray, int]:
    """Capsules of 1..60 (a turn is 22.5) with noise between them; the per-beam ranges every turn
    holds, and how many turns an intact stream must give."""
    n = EXPRESS_SAMPLES
    mm = np.array([rng.randrange(150, 16383) if rng.random() < 0.9 else 0 for _ in range(n)], np.int64)
    count = rng.randrange(1, 61)
    stream = bytearray()
    for i in range(count):
        idx = np.arange(i * 32, i * 32 + 32) % n
        noise = bytes(rng.randrange(256) for _ in range(rng.randrange(8))) if mutated else \
            bytes(rng.choice(_CAPSULE_FREE) for _ in range(rng.randrange(8)))
        stream += noise + k.encode_capsule(int(idx[0] * C.ANGLE_Q6_TURN // n), i == 0, mm[idx])
    beam_of_sample = k.beam_index(k.node_angles_cw(n), n)
    ranges = np.full(n, np.nan)
    ranges[beam_of_sample] = np.where(mm > 0, mm / 1000.0, np.inf)
    placed = 32 * (count - 1)                          # the last capsule waits for a next one
    return stream, ranges, max(0, (placed - 1) // n - 1)


def fuzz_express(streams: int, rng: random.Random) -> int:
    """Capsule streams through ExpressDecoder; print the counts; return the problems found."""
    tally = Tally(("scans", "capsules", "dropped_bytes", "gaps", "short_turns"))
    t0 = time.perf_counter()
    for n in range(streams):
        mutated = rng.random() < 0.8
        stream, ranges, want = _express_stream(rng, mutated)
        if mutated:
            mutate(rng, stream)
        dec = k.ExpressDecoder(EXPRESS_SAMPLES)
        try:
            out = feed_in_chunks(rng, dec, stream, 400)
        except Exception:  # noqa: BLE001 - the fuzzer's job is to report any exception at all
            tally.exception(f"express stream {n}", stream)
            continue
        if not mutated:
            tally.compare(out, [ranges] * want, np.array_equal)
        tally.add(dec)
    elapsed = time.perf_counter() - t0
    return tally.report(f"express streams: {streams} in {elapsed:.1f} s",
                        "express turns lost or altered in intact streams", part="express")


def fuzz(streams: int, seed: int) -> int:
    """Run the fuzz loop; print the counts; return the number of problems found."""
    rng = random.Random(seed)
    turns = [_turn(rng) for _ in range(300)]
    requests = _requests(rng)
    tally = Tally(("scans", "nodes", "dropped_bytes", "short_turns", "request decoder requests",
                   "request decoder dropped_bytes", "request decoder bad_checksums"))
    t0 = time.perf_counter()
    for n in range(streams):
        mutated = rng.random() < 0.8
        stream = bytearray()
        expected: list[np.ndarray] = []
        for _ in range(rng.randrange(1, 7)):
            frame, ranges = rng.choice(turns)
            stream += _noise(rng, node_free=not mutated) + frame
            expected.append(ranges)
        stream += _noise(rng, node_free=not mutated) + k.encode_node(True, 10, 0, 4000)
        if mutated:
            mutate(rng, stream)
        dec = k.ScanDecoder(BEAMS)
        try:
            out = feed_in_chunks(rng, dec, stream, 120)
            if n % 2:
                reqs = bytearray()
                for _ in range(rng.randrange(1, 6)):
                    reqs += _noise(rng, node_free=False) + rng.choice(requests)
                if rng.random() < 0.8:
                    mutate(rng, reqs)
                rdec = k.RequestDecoder()
                tally.totals["request decoder requests"] += len(feed_in_chunks(rng, rdec, reqs, 120))
                tally.totals["request decoder dropped_bytes"] += rdec.dropped_bytes
                tally.totals["request decoder bad_checksums"] += rdec.bad_checksums
        except Exception:  # noqa: BLE001 - the fuzzer's job is to report any exception at all
            tally.exception(f"stream {n}", stream)
            continue
        if not mutated:
            tally.compare(out, expected, np.array_equal)
        tally.add(dec, ("scans", "nodes", "dropped_bytes", "short_turns"))
    elapsed = time.perf_counter() - t0
    return tally.report(f"streams: {streams} in {elapsed:.1f} s ({streams / elapsed:,.0f} streams/s, seed {seed})",
                        "turns lost or altered in intact streams")


def throughput(count: int) -> None:
    """Time clean decoding of full 360-node turns in 4 KiB reads."""
    rng = np.random.default_rng(0)
    ranges = np.round(rng.uniform(0.15, 12.0, 360) * 4000) / 4000
    data = k.encode_scan(ranges) * (count + 1)
    dec = k.ScanDecoder(360)
    got = 0
    t0 = time.perf_counter()
    for pos in range(0, len(data), 4096):
        got += len(dec.feed(data[pos:pos + 4096]))
    elapsed = time.perf_counter() - t0
    if got != count:
        raise SystemExit(f"throughput: decoded {got} turns, expected {count}")
    print(f"throughput A1 turns, 360 nodes: {got / elapsed:,.0f} turns/s, {dec.nodes / elapsed:,.0f} nodes/s "
          f"({len(data) / elapsed / 1e6:.1f} MB/s; an A1 sends 1,968 nodes/s)")


def main() -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--streams", type=int, default=100_000, help="number of fuzz streams")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--turns", type=int, default=2000, help="turns per throughput run")
    args = parser.parse_args()
    if args.streams < 1 or args.turns < 1:
        parser.error("--streams and --turns must be >= 1")
    problems = fuzz(args.streams, args.seed)
    problems += fuzz_express(max(1, args.streams // 4), random.Random(args.seed + 1))
    throughput(args.turns)
    return 1 if problems else 0


if __name__ == "__main__":
    raise SystemExit(main())
