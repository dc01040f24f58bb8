"""`check_explorer`: every installed explorer and the example plugin keep the contract; plugins that
break one rule each are refused with a message that names the plugin and the rule."""

from __future__ import annotations

import datetime
import importlib.util
import math
import random
import time
from pathlib import Path
from time import perf_counter as tick        # an alias: the check must see through it

import pytest

from robotexp.testing.explorer_contract import check_explorer, make_room
from robotexp.errors import PluginError
from robotexp.explorer import Done, Explorer
from robotexp.registry import EXPLORERS, available, load
from robotexp.robot import RobotState, Twist

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "plugin" / "robotexp_wallfollow.py"
BUILTIN = ["bvp", "frontier", "meta-exhaustive", "meta-firefly", "meta-ga", "srt-ball", "srt-laser", "srt-star",
           "waypoints"]


def test_every_builtin_explorer_is_installed() -> None:
    assert set(BUILTIN) <= set(available(EXPLORERS))


@pytest.mark.parametrize("name", BUILTIN)
def test_builtin_explorers_pass(name: str) -> None:
    report = check_explorer(load(EXPLORERS, name, Explorer), name=name)
    # the trial really ran: steps at 10 Hz until Done or the 20 s of robot time
    assert report.steps >= 1
    assert report.robot_time <= 20.0 + 1e-9
    assert report.done is not None or report.steps == 200


def test_example_plugin_passes_through_the_public_export() -> None:
    import robotexp

    spec = importlib.util.spec_from_file_location("robotexp_wallfollow_check", EXAMPLE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert robotexp.check_explorer is check_explorer          # what a plugin's own tests call
    report = robotexp.check_explorer(module.WallFollowExplorer, name="wall-follow")
    assert report.parameters == {"duration": 120.0, "wall_distance": 0.6, "speed": None, "home_radius": 0.5}
    assert report.steps == 200 and report.done is None         # it drives for 120 s; the check stops at 20 s


def test_make_room_is_a_closed_room_with_a_crate() -> None:
    world = make_room()
    assert world.boxes.shape == (5, 5)
    assert world.poses["start"].x == 1.0 and world.bounds == (-0.1, -0.1, 5.1, 4.1)


# -- plugins that break one rule each ------------------------------------------------------------------
class Spin(Explorer):
    """Turns in place: keeps every rule (the base the broken ones start from)."""

    def __init__(self, *, rate: float = 0.5, laps: int | None = None) -> None:
        self.rate, self.laps = rate, laps

    def step(self, state: RobotState, grid: object) -> Twist | Done:
        return Done("enough") if state.time >= 2.95 else Twist(0.0, self.rate)


class ReturnsNone(Spin):
    def step(self, state: RobotState, grid: object) -> Twist | Done:
        if state.time > 0.45:
            return None          # type: ignore[return-value]
        return Twist(0.1, 0.0)


class Unannotated(Spin):
    def __init__(self, *, rate=0.5) -> None:     # type: ignore[no-untyped-def]
        super().__init__(rate=rate)


class Positional(Spin):
    def __init__(self, rate: float = 0.5) -> None:
        super().__init__(rate=rate)


class NoDefault(Spin):
    def __init__(self, *, rate: float) -> None:
        super().__init__(rate=rate)


class DictParameter(Spin):
    def __init__(self, *, table: dict[str, float] | None = None) -> None:
        super().__init__()


class WrongDefault(Spin):
    def __init__(self, *, laps: int = 2.5) -> None:       # type: ignore[assignment]
        super().__init__()


class ReadsWallClock(Spin):
    def step(self, state: RobotState, grid: object) -> Twist | Done:
        self.started = getattr(self, "started", time.time())
        return Twist(0.0, 0.1 if time.time() - self.started < 1 else 0.0)


class ReadsAliasedClock(Spin):
    def step(self, state: RobotState, grid: object) -> Twist | Done:
        return Twist(0.0, 0.2 if tick() > 0 else 0.0)


class ReadsDatetime(Spin):
    def reset(self, ctx: object) -> None:
        super().reset(ctx)        # type: ignore[arg-type]
        self.day = datetime.datetime.now().day


class Sleeps(Spin):
    def step(self, state: RobotState, grid: object) -> Twist | Done:
        time.sleep(0)
        return Twist(0.0, 0.1)


class GlobalRandom(Spin):
    def step(self, state: RobotState, grid: object) -> Twist | Done:
        return Twist(0.0, random.uniform(-0.5, 0.5))


class RaisesInStep(Spin):
    def step(self, state: RobotState, grid: object) -> Twist | Done:
        raise KeyError("pose")


class NanTwist(Spin):
    def step(self, state: RobotState, grid: object) -> Twist | Done:
        return Twist(math.nan, 0.0)


class BadGridModel(Spin):
    grid_model = "bayes"        # type: ignore[assignment]


class BadNeedsRange(Spin):
    needs_range = "laser"       # type: ignore[assignment]


class Drawn(Spin):
    """Draws a node and the target it turns towards (keeps every rule)."""

    def markers(self) -> dict[str, dict[str, object]]:
        return {"points": {"node": [1.0, 1.0]}, "lines": {"edge": [1.0, 1.0, 2.0, 1.5]},
                "circles": {"reach": [1.0, 1.0, 0.5]}, "polygons": {"room": [[0, 0, 1, 0, 1, 1]]}}


class MarkersNotADict(Spin):
    def markers(self) -> dict[str, dict[str, object]]:
        return [1.0, 2.0]       # type: ignore[return-value]


class MarkersOddPoints(Spin):
    def markers(self) -> dict[str, dict[str, object]]:
        return {"points": {"target": [1.0, 2.0, 3.0]}}


class MarkersUnknownKind(Spin):
    def markers(self) -> dict[str, dict[str, object]]:
        return {"arrows": {"way": [0.0, 0.0, 1.0, 1.0]}}


class MarkersNan(Spin):
    def markers(self) -> dict[str, dict[str, object]]:
        return {"circles": {"reach": [0.0, 0.0, math.nan]}}


class MarkersTwoPointPolygon(Spin):
    def markers(self) -> dict[str, dict[str, object]]:
        return {"polygons": {"region": [[0.0, 0.0, 1.0, 1.0]]}}


class MarkersChangeDecisions(Spin):
    """Draws a random target: drawing takes from the run's generator, so the steps after it change."""

    def step(self, state: RobotState, grid: object) -> Twist | Done:
        return Twist(0.0, float(self.ctx.rng.uniform(0.1, 0.5)))

    def markers(self) -> dict[str, dict[str, object]]:
        return {"points": {"target": [float(self.ctx.rng.uniform(0, 5)), 1.0]}}


def test_a_plugin_that_keeps_the_rules_passes() -> None:
    report = check_explorer(Spin, name="spin")
    assert report.parameters == {"rate": 0.5, "laps": None}
    assert report.done == "enough" and report.steps == 31      # robot time 0.0, 0.1, .., 3.0 s
    assert Spin().markers() == {}                               # the contract's default: nothing drawn
    assert check_explorer(Drawn, name="drawn").done == "enough"


@pytest.mark.parametrize(("cls", "expected"), [
    (ReturnsNone, "step returned None (NoneType) at step 6 (robot time 0.5 s); it must return a "
                  "robotexp.robot.Twist or a robotexp.explorer.Done"),
    (Unannotated, "Unannotated.__init__ parameter 'rate' has no type annotation"),
    (Positional, "Positional.__init__ parameter 'rate' must be keyword-only"),
    (NoDefault, "NoDefault.__init__ parameter 'rate' has no default"),
    (DictParameter, "annotated dict[str, float] | None, which the CLI cannot parse"),
    (WrongDefault, "WrongDefault.__init__ parameter 'laps' defaults to 2.5, which is not a <class 'int'>"),
    (ReadsWallClock, "reads the clock or sleeps (time.time() at "),
    (ReadsAliasedClock, "reads the clock or sleeps (time.perf_counter() at "),
    (ReadsDatetime, "reads the clock or sleeps (datetime.datetime.now() at "),
    (Sleeps, "reads the clock or sleeps (time.sleep() at "),
    (GlobalRandom, "with the same seed, step 1 (robot time 0.0 s) returned"),
    (RaisesInStep, "step() raised KeyError: 'pose'"),
    (NanTwist, "step returned Twist(v=nan, w=0.0) at step 1"),
    (BadGridModel, "grid_model must be 'logodds' or 'himm', got 'bayes'"),
    (BadNeedsRange, "needs_range must be True or False, got 'laser'"),
    (MarkersNotADict, "markers() must return a dict, got list"),
    (MarkersOddPoints, "markers()['points']['target'] holds 3 numbers, not a multiple of 2"),
    (MarkersUnknownKind, "markers() kind 'arrows' is none of points, circles, lines, polygons"),
    (MarkersNan, "markers()['circles']['reach'] holds nan; only finite numbers [m]"),
    (MarkersTwoPointPolygon, "markers()['polygons']['region'][0] has 2 points; an outline needs 3 or more"),
    (MarkersChangeDecisions, "with the same seed, step 2 (robot time 0.1 s) returned"),
])
def test_broken_plugins_are_refused_by_name_and_rule(cls: type, expected: str) -> None:
    with pytest.raises(PluginError) as info:
        check_explorer(cls, name="broken")
    message = str(info.value)
    assert message.startswith(f"explorer 'broken' ({__name__}:{cls.__qualname__}): ")
    assert expected in message


def test_clock_reads_name_the_file_and_line() -> None:
    with pytest.raises(PluginError, match=r"time\.time\(\) at .*test_explorer_contract\.py:\d+ in step"):
        check_explorer(ReadsWallClock)


def test_not_an_explorer_is_refused() -> None:
    with pytest.raises(PluginError, match="is not a subclass of robotexp.explorer.Explorer"):
        check_explorer(dict)


def test_the_previous_profile_hook_is_restored() -> None:
    import sys
    before = sys.getprofile()
    check_explorer(Spin)
    with pytest.raises(PluginError):
        check_explorer(ReadsWallClock)
    assert sys.getprofile() is before
