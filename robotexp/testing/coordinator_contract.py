"""`check_coordinator`: does a coordinator plugin keep the contract of `robotexp.coordinator.Coordinator`?

A plugin author calls it from a test (``robotexp.check_coordinator(MyCoordinator)``); robotexp's own tests
call it for every installed coordinator. It checks, in this order, and raises `PluginError` naming the
plugin and the first rule broken:

1. the class subclasses `Coordinator` and `assigns_targets` and `reassigns` are bools;
2. every `__init__` parameter is keyword-only with a default, every name in `parameter_bounds` is one of
   them and its default lies within its bounds, and the class builds with the defaults alone;
3. on `cases` seeded random rounds (2 to 6 robots, 0 to 12 targets, some unreachable from some robots,
   some robots keeping a target, some told the target they are on their way to (`Candidates.held`)),
   `assign` returns a list with one entry per robot, each None or the
   index of a target; a robot that keeps a target keeps it; no robot gets a target it cannot reach; a
   coordinator that assigns targets gives every robot without one that can reach some target a target;
   the candidates it was given are unchanged;
4. with the same seed it decides the same: a second instance repeats every round.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass, replace

import numpy as np

from robotexp.coordinator import Candidates, Coordinator, TeamContext
from robotexp.errors import PluginError, RobotexpError

__all__ = ["check_coordinator", "CoordinatorReport", "random_candidates"]

LASER_RANGE = 3.0       # [m] the sensor range the check's teams have


@dataclass(frozen=True)
class CoordinatorReport:
    """What `check_coordinator` saw: the rounds played and the targets given out."""

    rounds: int
    assigned: int           # targets given to robots without one


def random_candidates(rng: np.random.Generator, robots: int, targets: int) -> Candidates:
    """A coordination round on a 20 x 20 m square: `targets` frontier targets and `robots` robots at random,
    each robot's cost the straight distance times 1..1.5, a fifth of the pairs unreachable."""
    points = rng.uniform(0.0, 20.0, (targets, 2))
    positions = rng.uniform(0.0, 20.0, (robots, 2))
    straight = np.hypot(positions[:, None, 0] - points[None, :, 0], positions[:, None, 1] - points[None, :, 1])
    cost = straight * rng.uniform(1.0, 1.5, straight.shape)
    cost[rng.random(cost.shape) < 0.2] = np.inf
    cells = tuple(np.array([[int(p[1] * 10), int(p[0] * 10)]], np.int64) for p in points)
    return Candidates(points=points, cells=cells, cost=cost, positions=positions)


def check_coordinator(cls: type, *, name: str | None = None, cases: int = 40, seed: int = 0) -> CoordinatorReport:
    """Check coordinator class `cls` (see the module); `name` labels it in errors (its registered name).

    Raises:
        PluginError: the first rule broken, naming the plugin.
    """
    label = f"coordinator {name or getattr(cls, '__name__', repr(cls))!r}"
    if not (isinstance(cls, type) and issubclass(cls, Coordinator)):
        raise PluginError(f"{label}: {cls!r} is not a subclass of robotexp.Coordinator")
    for flag in ("assigns_targets", "reassigns"):
        if not isinstance(getattr(cls, flag), bool):
            raise PluginError(f"{label}: {flag} must be a bool, got {getattr(cls, flag)!r}")
    _check_parameters(cls, label)
    first, second = _build(cls, label), _build(cls, label)
    for c in (first, second):
        c.reset(TeamContext(size=6, laser_range=LASER_RANGE, radius=(0.25,) * 6, rng=np.random.default_rng(seed)))
    rng = np.random.default_rng(seed)
    assigned = 0
    for case in range(cases):
        n, k = int(rng.integers(2, 7)), int(rng.integers(0, 13))
        cand = random_candidates(rng, n, k)
        kept: list[int | None] = [None] * n
        held: list[int | None] = [None] * n
        for i in range(n):
            reachable = np.flatnonzero(np.isfinite(cand.cost[i]))
            if len(reachable) and rng.random() < 0.3:
                kept[i] = held[i] = int(rng.choice(reachable))
            elif len(reachable) and rng.random() < 0.3:
                held[i] = int(rng.choice(reachable))
        if rng.random() < 0.5:
            cand = replace(cand, held=tuple(held))
        before = (cand.points.copy(), cand.cost.copy(), [c.copy() for c in cand.cells])
        out = _assign(first, cand, kept, label, case)
        _check_round(cls, cand, kept, out, label, case)
        if not (np.array_equal(before[0], cand.points) and np.array_equal(before[1], cand.cost)
                and all(np.array_equal(a, b) for a, b in zip(before[2], cand.cells, strict=True))):
            raise PluginError(f"{label}: assign changed the candidates it was given (round {case})")
        again = _assign(second, cand, kept, label, case)
        if again != out:
            raise PluginError(f"{label}: a second instance with the same seed assigned {again} instead of {out} "
                              f"(round {case}): randomness must come from TeamContext.rng")
        assigned += sum(1 for i, t in enumerate(out) if kept[i] is None and t is not None)
    return CoordinatorReport(rounds=cases, assigned=assigned)


def _check_parameters(cls: type[Coordinator], label: str) -> None:
    bounds = {}
    for klass in reversed(cls.__mro__):
        bounds.update(vars(klass).get("parameter_bounds", {}))
    params = {}
    for p in list(inspect.signature(cls.__init__).parameters.values())[1:]:
        if p.kind in (p.VAR_KEYWORD, p.VAR_POSITIONAL):
            continue
        if p.kind is not p.KEYWORD_ONLY or p.default is p.empty:
            raise PluginError(f"{label}: parameter {p.name!r} must be keyword-only with a default")
        params[p.name] = p.default
    for key, (lo, hi) in bounds.items():
        if key not in params:
            raise PluginError(f"{label}: parameter_bounds names {key!r}, which is not a parameter")
        value = params[key]
        if isinstance(value, (int, float)) and not isinstance(value, bool) and (
                (lo is not None and value < lo) or (hi is not None and value > hi)):
            raise PluginError(f"{label}: the default {key}={value} lies outside its bounds {lo}..{hi}")


def _build(cls: type[Coordinator], label: str) -> Coordinator:
    try:
        return cls()
    except RobotexpError as exc:
        raise PluginError(f"{label}: does not build with its defaults: {exc}") from exc


def _assign(c: Coordinator, cand: Candidates, kept: list[int | None], label: str, case: int) -> list[int | None]:
    try:
        out = c.assign(cand, list(kept))
    except Exception as exc:
        raise PluginError(f"{label}: assign raised {type(exc).__name__}: {exc} (round {case})") from exc
    if not isinstance(out, list) or len(out) != cand.robots:
        raise PluginError(f"{label}: assign must return a list of {cand.robots} entries, got {out!r} (round {case})")
    return out


def _check_round(cls: type[Coordinator], cand: Candidates, kept: list[int | None], out: list[int | None],
                 label: str, case: int) -> None:
    for i, t in enumerate(out):
        if t is not None and (isinstance(t, bool) or not isinstance(t, (int, np.integer)) or not 0 <= t < len(cand)):
            raise PluginError(f"{label}: robot {i}'s target {t!r} is not None nor a candidate index (round {case})")
        if kept[i] is not None and t != kept[i]:
            raise PluginError(f"{label}: robot {i} keeps target {kept[i]} but was given {t!r} (round {case})")
        if t is not None and not math.isfinite(cand.cost[i, t]):
            raise PluginError(f"{label}: robot {i} was given target {t}, which it cannot reach (round {case})")
        if (cls.assigns_targets and kept[i] is None and t is None and len(cand)
                and np.isfinite(cand.cost[i]).any()):
            raise PluginError(f"{label}: robot {i} has no target and can reach one, but was given none "
                              f"(round {case})")
