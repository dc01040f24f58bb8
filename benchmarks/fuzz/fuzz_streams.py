"""What the fuzz scripts share: random mutations of a byte stream and feeding it in chunks."""

from __future__ import annotations

import random
import traceback
from collections.abc import Callable
from typing import Any
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # benchmarks/: perflog
from perflog import Figure, record  # noqa: E402


def mutate(rng: random.Random, stream: bytearray) -> None:
    """1..5 random byte flips, insertions (1..8 bytes) or deletions (1..4 bytes), in place."""
    for _ in range(rng.randrange(1, 6)):
        if not stream:
            return
        pos, kind = rng.randrange(len(stream)), rng.randrange(3)
        if kind == 0:
            stream[pos] ^= rng.randrange(1, 256)
        elif kind == 1:
            stream[pos:pos] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 9)))
        else:
            del stream[pos:pos + rng.randrange(1, 5)]


def feed_in_chunks(rng: random.Random, decoder: Any, stream: bytes | bytearray, longest: int) -> list[Any]:
    """Everything `decoder.feed` returns for `stream` fed in random chunks of 1..`longest` bytes."""
    out: list[Any] = []
    pos = 0
    while pos < len(stream):
        step = rng.randrange(1, longest + 1)
        out += decoder.feed(bytes(stream[pos:pos + step]))
        pos += step
    return out


class Tally:
    """What one fuzz loop counts: the decoders' counters, the exceptions raised and the items lost from
    intact streams; `report` prints them and returns the number of problems (exceptions + lost)."""

    def __init__(self, keys: tuple[str, ...] | list[str]) -> None:
        self.totals: dict[str, int] = dict.fromkeys(keys, 0)
        self.exceptions: list[str] = []
        self.lost = 0

    def exception(self, label: str, stream: bytes | bytearray) -> None:
        """Note the exception being handled, with the stream that raised it."""
        self.exceptions.append(f"{label}: {bytes(stream).hex()}\n{traceback.format_exc()}")

    def compare(self, out: list[Any], expected: list[Any], same: Callable[[Any, Any], bool] | None = None) -> None:
        """Count what an intact stream lost: `out` must be `expected`, item by item (`same`, else ==)."""
        if same is None:
            equal = out == expected
        else:
            equal = len(out) == len(expected) and all(same(a, b) for a, b in zip(out, expected, strict=False))
        if not equal:
            self.lost += max(1, len(expected) - len(out))

    def add(self, decoder: Any, keys: tuple[str, ...] | None = None) -> None:
        """Add the decoder's counters named `keys` (all totals when None)."""
        for key in keys if keys is not None else tuple(self.totals):
            self.totals[key] += getattr(decoder, key)

    def report(self, header: str, lost_label: str, part: str = "") -> int:
        """Print the counts under `header`, write them as the script's figures (`part`: a second set of
        the same script); return exceptions + lost."""
        print(header)
        for key, value in self.totals.items():
            print(f"  {key}: {value}")
        print(f"  {lost_label}: {self.lost}")
        print(f"  exceptions: {len(self.exceptions)}")
        for text in self.exceptions[:3]:
            print(text)
        main = sys.modules["__main__"].__doc__ or Path(sys.argv[0]).stem
        record(Path(sys.argv[0]).stem.replace("_", "-") + (f"-{part}" if part else ""), [
            *(Figure(key, float(value), "") for key, value in self.totals.items()),
            Figure(lost_label, float(self.lost), "", "must be 0"),
            Figure("exceptions raised", float(len(self.exceptions)), "", "must be 0"),
        ], title=main.strip().splitlines()[0].rstrip(".") + (f" ({part})" if part else ""), section="fuzzing",
            parameters={"arguments": " ".join(sys.argv[1:]) or "defaults"})
        return len(self.exceptions) + self.lost
