"""Fuzz and time the Hokuyo SCIP 2.0 scan decoder (robotexp_drivers.lasers.hokuyo.codec.ScanDecoder).

Each stream holds 1..8 valid replies (MD/MS scans with a remaining counter and maybe a ";string",
GD/GS scans, MD acknowledgements, VV/PP/QT replies, error statuses) separated by random noise; most
streams then get random byte flips, insertions and deletions, and all are fed in random chunks.
Reports scans recovered, replies seen, bytes dropped, bad sums/lengths, any exception (there must be
none), and, for streams left intact, any scan lost or altered (there must be none: noise glued to an
echo or on lines of its own is cut off). Then times clean decoding of full URG-04LX and UTM-30LX
scans.

Run: python benchmarks/fuzz/fuzz_hokuyo.py [--streams 100000] [--seed 0]
Exit status 1 when an exception or a lost scan was found.
"""

from __future__ import annotations

import argparse
import random
import time

import numpy as np

from fuzz_streams import Tally, feed_in_chunks, mutate

from robotexp_drivers.lasers.hokuyo import codec as k
from robotexp_drivers.lasers.hokuyo import constants as C


def _scan(rng: random.Random) -> tuple[bytes, np.ndarray]:
    """A random scan reply and the ranges it must decode to."""
    encoding = rng.choice([C.CMD_MD, C.CMD_MS, C.CMD_GD, C.CMD_GS])
    n = rng.randrange(1, 120)
    cluster = rng.randrange(0, 4)
    start = rng.randrange(0, 800)
    end = start + n * max(cluster, 1) - 1 - (rng.randrange(max(cluster, 1)) if cluster > 1 else 0)
    top = 4095 if encoding in (C.CMD_MS, C.CMD_GS) else 65000
    mm = np.array([rng.randrange(20, top) if rng.random() < 0.9 else -1 for _ in range(n)], np.int64)
    ranges = np.where(mm < 0, np.inf, mm / 1000.0)
    frame = k.encode_scan(ranges, start=start, end=end, cluster=cluster, encoding=encoding,
                          remaining=rng.randrange(100), interval=rng.randrange(10),
                          timestamp_ms=rng.randrange(1 << 24),
                          string=rng.choice([None, "", "robotexp", "x" * 16]))
    return frame, ranges


def _replies(rng: random.Random) -> list[bytes]:
    """Replies that are not scans."""
    return [k.encode_reply(b"MD0044072501000", C.STATUS_OK), k.encode_reply(b"QT", C.STATUS_OK),
            k.encode_reply(b"BM", C.STATUS_BM_ALREADY_ON), k.encode_reply(b"XX", C.STATUS_UNDEFINED),
            k.encode_reply(b"MD0044080001000", C.STATUS_END_OUT_OF_RANGE),
            k.encode_reply(b"PP", C.STATUS_OK, [k.param_line("DMIN", "20"), k.param_line("AMAX", "725")]),
            k.encode_reply(b"VV", C.STATUS_OK, [k.param_line("PROT", "SCIP 2.0")])]


def _noise(rng: random.Random) -> bytes:
    out = bytearray(rng.randrange(256) for _ in range(rng.randrange(24)))
    if rng.random() < 0.3:
        out += b"\n"
    if rng.random() < 0.1:
        out += b"MD00"                                   # a false echo start
    return bytes(out)


def fuzz(streams: int, seed: int) -> int:
    """Run the fuzz loop; print the counts; return the number of problems found."""
    rng = random.Random(seed)
    scans = [_scan(rng) for _ in range(400)]
    others = _replies(rng)
    tally = Tally(("scans", "replies", "dropped_bytes", "bad_sums", "bad_lengths"))
    t0 = time.perf_counter()
    for n in range(streams):
        mutated = rng.random() < 0.8
        stream = bytearray()
        expected: list[np.ndarray] = []
        for _ in range(rng.randrange(1, 9)):
            stream += _noise(rng)
            if rng.random() < 0.75:
                frame, ranges = rng.choice(scans)
                expected.append(ranges)
            else:
                frame = rng.choice(others)
            stream += frame
        stream += _noise(rng)
        if mutated:
            mutate(rng, stream)
        dec = k.ScanDecoder(dmin_mm=20, dmax_mm=C.ENC3_MAX)
        try:
            out = feed_in_chunks(rng, dec, stream, 200)
        except Exception:  # noqa: BLE001 - the fuzzer's job is to report any exception at all
            tally.exception(f"stream {n}", stream)
            continue
        if not mutated:
            tally.compare(out, expected, np.array_equal)
        tally.add(dec)
    elapsed = time.perf_counter() - t0
    return tally.report(f"streams: {streams} in {elapsed:.1f} s ({streams / elapsed:,.0f} streams/s, seed {seed})",
                        "scans lost or altered in intact streams")


def throughput(count: int) -> None:
    """Time clean decoding of full scans in 4 KiB reads."""
    rng = np.random.default_rng(0)
    for label, n, encoding in (("URG-04LX MD, 682 values", 682, C.CMD_MD),
                               ("UTM-30LX MD, 1081 values", 1081, C.CMD_MD),
                               ("URG-04LX MS, 682 values", 682, C.CMD_MS)):
        ranges = np.round(rng.uniform(0.02, 4.0, n), 3)
        data = k.encode_scan(ranges, start=0, encoding=encoding) * count
        dec = k.ScanDecoder()
        got = 0
        t0 = time.perf_counter()
        for pos in range(0, len(data), 4096):
            got += len(dec.feed(data[pos:pos + 4096]))
        elapsed = time.perf_counter() - t0
        if got != count:
            raise SystemExit(f"throughput {label}: decoded {got} scans, expected {count}")
        print(f"throughput {label}: {got / elapsed:,.0f} scans/s ({len(data) / elapsed / 1e6:.1f} MB/s)")


def main() -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--streams", type=int, default=100_000, help="number of fuzz streams")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scans", type=int, default=5000, help="scans per throughput run")
    args = parser.parse_args()
    if args.streams < 1 or args.scans < 1:
        parser.error("--streams and --scans must be >= 1")
    problems = fuzz(args.streams, args.seed)
    throughput(args.scans)
    return 1 if problems else 0


if __name__ == "__main__":
    raise SystemExit(main())
