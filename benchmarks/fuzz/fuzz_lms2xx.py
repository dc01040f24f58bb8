"""Fuzz and time the SICK LMS2xx decoders (robotexp_drivers.lasers.lms2xx.codec).

Each stream holds 1..8 valid telegrams (continuous-output scans of 181/361/401 values in mm or cm, and
the replies a driver waits for: A0, BB, F4/F7, B1, BA, 90, 91, 92; or host requests) separated by random
noise with standalone ACK/NAK bytes; most streams then get random byte flips, insertions and deletions,
and all are fed in random chunks, then flushed. Reports telegrams and scans recovered, bytes dropped,
bad CRCs/headers, any exception (there must be none), and, for streams left intact with STX-free noise,
any telegram or scan lost (there must be none). Then times clean decoding of the continuous output.

Run: python benchmarks/fuzz/fuzz_lms2xx.py [--streams 100000] [--seed 0]
Exit status 1 when an exception or a lost telegram was found.
"""

from __future__ import annotations

import argparse
import random
import time

import numpy as np

from robotexp_drivers.lasers.lms2xx import codec as k
from robotexp_drivers.lasers.lms2xx import constants as c
from fuzz_streams import Tally, mutate


def _scan(rng: random.Random, beams: int, units: str) -> bytes:
    top = 8.0 if units == "mm" else 80.0
    r = np.array([rng.uniform(0, top) if rng.random() < 0.9 else np.inf for _ in range(beams)])
    return k.encode_scan(r, units=units)


def _reply_frames(rng: random.Random) -> list[bytes]:
    """A pool of valid LMS -> host telegrams."""
    pool = [_scan(rng, beams, units) for beams in (181, 361, 401) for units in ("mm", "cm") for _ in range(6)]
    cfg = k.LMSConfig.default()
    pool += [k.reply_mode(0), k.reply_mode(1, address=1), k.reply_variant(True, 180, 50),
             k.reply_variant(False, 100, 25), k.reply_config(cfg), k.reply_configured(True, cfg),
             k.reply_status(k.LMSStatus("V02.10 ", 0x24, 0, 0, 180, 100, 38400, 0, 1)), k.reply_type(),
             k.reply_power_on(), k.reply_reset_ack(), k.reply_not_acknowledged()]
    return pool


def _request_frames(rng: random.Random) -> list[bytes]:
    """A pool of valid host -> LMS requests."""
    pool = [k.req_reset(), k.req_status(), k.req_type(), k.req_config(), k.req_values(), k.req_stop(),
            k.req_continuous(), k.req_installation(), k.req_configure(k.LMSConfig.default())]
    pool += [k.req_baud(b) for b in c.BAUD_CODES] + [k.req_variant(a, r) for a, r in sorted(c.VALID_VARIANTS)]
    return pool


def _noise(rng: random.Random, stx_free: bool) -> bytes:
    out = bytearray(rng.randrange(256) for _ in range(rng.randrange(24)))
    if rng.random() < 0.3:
        out += bytes((c.ACK,)) if rng.random() < 0.7 else bytes((c.NAK,))
    if rng.random() < 0.2:
        out += bytes((c.STX, 0x80 | rng.randrange(2), rng.randrange(256)))   # a false start
    if stx_free:
        out = out.replace(bytes((c.STX,)), b"\x03")
    return bytes(out)


def _key(obj: object) -> object:
    return obj.tobytes() if isinstance(obj, np.ndarray) else obj


def fuzz(streams: int, seed: int) -> int:
    """Run the fuzz loop; print the counts; return the number of problems found."""
    rng = random.Random(seed)
    pools = {"replies": _reply_frames(rng), "requests": _request_frames(rng)}
    tally = Tally(("telegrams", "scans", "dropped_bytes", "bad_crcs", "bad_headers", "truncated", "bad_scans"))
    t0 = time.perf_counter()
    for n in range(streams):
        kind = "replies" if n % 3 else "requests"
        mutated = rng.random() < 0.8
        frames = [rng.choice(pools[kind]) for _ in range(rng.randrange(1, 9))]
        stream = bytearray()
        for f in frames:
            stream += _noise(rng, stx_free=not mutated) + f
        stream += _noise(rng, stx_free=not mutated)
        if mutated:
            mutate(rng, stream)
        tel = k.TelegramDecoder(replies=kind == "replies")
        scans = k.ScanDecoder()
        out_t: list[k.Telegram] = []
        out_s: list[np.ndarray] = []
        try:
            pos = 0
            while pos < len(stream):
                step = rng.randrange(1, 256)
                chunk = bytes(stream[pos:pos + step])
                out_t += tel.feed(chunk)
                if kind == "replies":
                    out_s += scans.feed(chunk)
                pos += step
            out_t += tel.flush()
            if kind == "replies":
                out_s += scans.flush()
        except Exception:  # noqa: BLE001 - the fuzzer's job is to report any exception at all
            tally.exception(f"stream {n}", stream)
            continue
        if not mutated:
            # STX-free noise around intact telegrams: every telegram (and scan) must come out, in order
            tally.compare(out_t, [t for f in frames for t in k.TelegramDecoder(replies=kind == "replies").feed(f)])
            if kind == "replies":
                tally.compare([_key(s) for s in out_s], [_key(s) for f in frames for s in k.ScanDecoder().feed(f)])
        tally.totals["telegrams"] += len(out_t)
        tally.totals["scans"] += len(out_s)
        tally.add(tel, ("dropped_bytes", "bad_crcs", "bad_headers", "truncated"))
        tally.add(scans, ("bad_scans",))
    elapsed = time.perf_counter() - t0
    return tally.report(f"streams: {streams} in {elapsed:.1f} s (seed {seed})",
                        "telegrams/scans lost from intact streams")


def throughput(count: int, seed: int) -> None:
    """Time clean decoding of the continuous output (0xB0 scans back to back) in 4 KiB reads."""
    rng = random.Random(seed)
    for beams in (181, 361, 401):
        frames = [_scan(rng, beams, "mm") for _ in range(8)]
        data = b"".join(frames[i % len(frames)] for i in range(count))
        dec = k.ScanDecoder(beams=beams)
        t0 = time.perf_counter()
        got = 0
        for pos in range(0, len(data), 4096):
            got += len(dec.feed(data[pos:pos + 4096]))
        elapsed = time.perf_counter() - t0
        if got != count:
            raise SystemExit(f"throughput run {beams} beams: decoded {got} scans, expected {count}")
        line = 38400 / (c.BITS_PER_BYTE * len(frames[0]))
        print(f"throughput {beams} values/scan: {got / elapsed:,.0f} scans/s ({len(data) / elapsed / 1e6:.1f} MB/s;"
              f" {got / elapsed / line:,.0f}x what 38400 baud carries, {got / elapsed / 75:,.0f}x the 75 Hz mirror)")


def main() -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--streams", type=int, default=100_000, help="number of fuzz streams")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scans", type=int, default=20_000, help="scans per throughput run")
    args = parser.parse_args()
    if args.streams < 0 or args.scans < 1:
        parser.error("--streams must be >= 0 and --scans >= 1")
    problems = fuzz(args.streams, args.seed)
    throughput(args.scans, args.seed)
    return 1 if problems else 0


if __name__ == "__main__":
    raise SystemExit(main())
