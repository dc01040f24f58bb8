"""What the fuzz scripts share: random mutations of a byte stream and feeding it in chunks."""

from __future__ import annotations

import random
from typing import Any


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
