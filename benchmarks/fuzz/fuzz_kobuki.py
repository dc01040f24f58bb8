"""Fuzz the Kobuki frame decoder and measure its throughput.

Runs `--streams` seeded streams, a third each of: random bytes; valid feedback frames embedded in
random noise (0xAA 0x55 included); valid frames with one frame mutated (bytes overwritten, inserted
or deleted). Reports frames recovered, frames lost, frames forged (accepted but never sent:
corrupted bytes that pass the XOR and the sub-payload tiling), bytes dropped, exceptions (there
must be none), and the decode rate of a clean 50 Hz-style stream in frames/s.

    python benchmarks/fuzz/fuzz_kobuki.py --streams 100000 --seed 1
"""

from __future__ import annotations

import argparse
import random
import time
import traceback

from robotexp_drivers.kobuki import constants as K
from robotexp_drivers.kobuki.codec import (
    BasicSensorData,
    CliffSensors,
    DockingIR,
    Frame,
    FrameDecoder,
    GeneralPurposeInput,
    InertialSensor,
    Message,
    MotorCurrent,
    RawGyro,
    UnknownSubpayload,
    encode_messages,
)


def random_stream_frame(rng: random.Random) -> Frame:
    """One default-stream feedback frame (IDs 1, 3, 4, 5, 6, 13, 16) with random field values."""
    u8, u16, i16 = (lambda: rng.randrange(256)), (lambda: rng.randrange(65536)), \
        (lambda: rng.randrange(-32768, 32768))
    return [
        BasicSensorData(u16(), u8() & 7, u8() & 3, u8() & 7, u16(), u16(), rng.randrange(-128, 128),
                        rng.randrange(-128, 128), u8() & 7, rng.choice((0, 2, 6, 18, 22)),
                        rng.randrange(130, 168), u8() & 3),
        DockingIR(u8() & 0x3F, u8() & 0x3F, u8() & 0x3F),
        InertialSensor(i16(), i16(), 0, 0, 0),
        CliffSensors(u16() & 0xFFF, u16() & 0xFFF, u16() & 0xFFF),
        MotorCurrent(u8(), u8()),
        RawGyro(u8(), tuple((i16(), i16(), i16()) for _ in range(rng.randint(2, 3)))),
        GeneralPurposeInput(u16() & 0xF, u16() & 0xFFF, u16() & 0xFFF, u16() & 0xFFF, u16() & 0xFFF),
    ]


def random_frame(rng: random.Random) -> Frame:
    """A default-stream frame, or a short frame with an unknown sub-payload."""
    if rng.random() < 0.8:
        return random_stream_frame(rng)
    extra: list[Message] = [UnknownSubpayload(rng.choice((2, 7, 30, 200)), rng.randbytes(rng.randint(1, 30)))]
    return extra + random_stream_frame(rng)[:rng.randint(0, 2)]


def mutate(rng: random.Random, frame: bytes) -> bytes:
    """Overwrite, insert or delete 1-4 bytes of `frame`."""
    out = bytearray(frame)
    for _ in range(rng.randint(1, 4)):
        kind, i = rng.randrange(3), rng.randrange(len(out) + 1)
        if kind == 0 and i < len(out):
            out[i] = rng.randrange(256)
        elif kind == 1:
            out.insert(i, rng.randrange(256))
        elif kind == 2 and i < len(out):
            del out[i]
    return bytes(out)


def feed_in_chunks(rng: random.Random, decoder: FrameDecoder, data: bytes) -> list[Frame]:
    """Feed `data` in random chunks of 1..128 bytes."""
    out: list[Frame] = []
    pos = 0
    while pos < len(data):
        size = rng.randint(1, 128)
        out += decoder.feed(data[pos:pos + size])
        pos += size
    return out


def is_subsequence(needles: list[Frame], haystack: list[Frame]) -> bool:
    """True when `needles` appear in `haystack` in order."""
    it = iter(haystack)
    return all(any(n == h for h in it) for n in needles)


def main() -> None:
    """Parse the arguments, fuzz, and print the report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--streams", type=int, default=100_000, help="number of fuzzed streams")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rng = random.Random(args.seed)

    stats = {name: 0 for name in ("sent", "recovered", "lost", "lost_in_noise", "forged", "dropped",
                                  "bad_checksums", "bad_lengths", "exceptions", "later_sent", "later_lost",
                                  "mutated_streams_with_forgery")}
    first_exceptions: list[str] = []
    t0 = time.perf_counter()
    fed_bytes = 0
    for s in range(args.streams):
        mode = s % 3
        frames = [random_frame(rng) for _ in range(rng.randint(1, 6))]
        encoded = [encode_messages(*f) for f in frames]
        k = rng.randrange(len(frames))
        if mode == 0:
            data, expected = rng.randbytes(rng.randint(0, 600)), []
        elif mode == 1:
            noise = [rng.randbytes(rng.randint(0, 40)) for _ in range(len(frames) + 1)]
            data = noise[0] + b"".join(e + noise[i + 1] for i, e in enumerate(encoded)) \
                + bytes(K.MAX_FRAME_LEN)  # the stream goes on: a false length cannot hold frames back
            expected = frames
        else:
            data = b"".join(encoded[:k]) + mutate(rng, encoded[k]) + b"".join(encoded[k + 1:]) \
                + bytes(K.MAX_FRAME_LEN)
            expected = frames[:k] + frames[k + 1:]
        decoder = FrameDecoder()
        fed_bytes += len(data)
        try:
            out = feed_in_chunks(rng, decoder, data)
        except Exception:  # noqa: BLE001 - a fuzzer records every escape, that is its purpose
            stats["exceptions"] += 1
            if len(first_exceptions) < 5:
                first_exceptions.append(f"stream {s}: {data.hex()}\n{traceback.format_exc()}")
            continue
        forged = [f for f in out if f not in frames]
        stats["sent"] += len(expected)
        stats["recovered"] += sum(1 for f in expected if f in out)
        lost = sum(1 for f in expected if f not in out)
        stats["lost"] += lost
        stats["lost_in_noise"] += lost if mode == 1 else 0
        stats["forged"] += len(forged)
        stats["dropped"] += decoder.dropped_bytes
        stats["bad_checksums"] += decoder.bad_checksums
        stats["bad_lengths"] += decoder.bad_lengths
        if mode == 2:
            later = frames[k + 1:]
            stats["later_sent"] += len(later)
            if not is_subsequence(later, out[k:]):
                stats["later_lost"] += 1
                if not forged:
                    stats["exceptions"] += 1
                    first_exceptions.append(f"stream {s}: later frame lost without a forged frame")
            stats["mutated_streams_with_forgery"] += bool(forged)
    fuzz_time = time.perf_counter() - t0

    # Throughput on a clean stream of default feedback frames fed in 64-byte reads.
    clean = b"".join(encode_messages(*random_stream_frame(rng)) for _ in range(20_000))
    decoder = FrameDecoder()
    t0 = time.perf_counter()
    n = sum(len(decoder.feed(clean[i:i + 64])) for i in range(0, len(clean), 64))
    rate = n / (time.perf_counter() - t0)

    print(f"streams fuzzed        {args.streams} ({fed_bytes} bytes, {fuzz_time:.1f} s, seed {args.seed})")
    print(f"frames sent           {stats['sent']}")
    print(f"frames recovered      {stats['recovered']}")
    print(f"frames lost           {stats['lost']} ({stats['lost_in_noise']} of them in noise streams, "
          f"the rest in mutated streams)")
    print(f"later frames lost     in {stats['later_lost']} of {args.streams // 3} mutated streams "
          f"({stats['later_sent']} later frames sent)")
    print(f"frames forged         {stats['forged']} ({stats['mutated_streams_with_forgery']} in mutated "
          f"streams; corrupted bytes that pass XOR + tiling)")
    print(f"bytes dropped         {stats['dropped']}")
    print(f"bad checksums         {stats['bad_checksums']}")
    print(f"bad lengths           {stats['bad_lengths']}")
    print(f"exceptions found      {stats['exceptions']}")
    for text in first_exceptions:
        print(text)
    print(f"clean decode rate     {rate:,.0f} frames/s ({n} frames of {len(clean) // n} bytes, "
          f"64-byte reads)")


if __name__ == "__main__":
    main()
