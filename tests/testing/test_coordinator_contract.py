"""check_coordinator on every installed coordinator, and on coordinators that break each rule."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytest

from robotexp import Candidates, Coordinator, PluginError, check_coordinator
from robotexp.registry import COORDINATORS, available, load


@pytest.mark.parametrize("name", sorted(available(COORDINATORS)))
def test_every_installed_coordinator_keeps_the_contract(name):
    cls = load(COORDINATORS, name, Coordinator)
    report = check_coordinator(cls, name=name)
    assert report.rounds == 40
    assert (report.assigned > 0) == cls.assigns_targets


class Nearest(Coordinator):
    def assign(self, candidates: Candidates, kept: Sequence[int | None]) -> list[int | None]:
        out = list(kept)
        for i, k in enumerate(kept):
            if k is None and len(candidates) and np.isfinite(candidates.cost[i]).any():
                out[i] = int(np.argmin(candidates.cost[i]))
        return out


class ForgetsKept(Nearest):
    def assign(self, candidates, kept):
        return super().assign(candidates, [None] * len(kept))


class Blind(Coordinator):
    def assign(self, candidates, kept):
        return [k if k is not None else (0 if len(candidates) else None) for k in kept]


class Lazy(Coordinator):
    def assign(self, candidates, kept):
        return list(kept)


class Positional(Nearest):
    def __init__(self, beta: float = 1.0) -> None:
        self.beta = beta


class OutOfBounds(Nearest):
    parameter_bounds = {"beta": (0.0, 1.0)}

    def __init__(self, *, beta: float = 2.0) -> None:
        self.beta = beta


class Scribbles(Nearest):
    def assign(self, candidates, kept):
        candidates.cost[:] = 0.0
        return super().assign(candidates, kept)


def test_a_nearest_target_coordinator_passes():
    assert check_coordinator(Nearest).assigned > 0


@pytest.mark.parametrize(("cls", "message"), [
    (ForgetsKept, "keeps target"),
    (Blind, "cannot reach"),
    (Lazy, "was given none"),
    (Positional, "keyword-only"),
    (OutOfBounds, "outside its bounds"),
    (Scribbles, "changed the candidates"),
    (int, "not a subclass"),
])
def test_each_rule_broken_is_named(cls, message):
    with pytest.raises(PluginError, match=message):
        check_coordinator(cls)


class Shuffled(Nearest):
    def assign(self, candidates, kept):
        out = super().assign(candidates, kept)
        reachable = [i for i, k in enumerate(out) if kept[i] is None and k is not None]
        for i in reachable:
            choices = np.flatnonzero(np.isfinite(candidates.cost[i]))
            out[i] = int(np.random.default_rng().choice(choices))      # not the context's generator
        return out


def test_randomness_outside_the_context_generator_is_caught():
    with pytest.raises(PluginError, match="same seed"):
        check_coordinator(Shuffled)
