"""TeamClock: a tick waits for every robot's own time to move on by a period."""

from __future__ import annotations

import pytest

from robotexp.clock import PacedClock, TeamClock


def test_a_team_tick_waits_for_each_robot_in_turn_on_its_own_time() -> None:
    asked: list[tuple[str, float]] = []

    def robot(name: str, lag: float):       # a robot whose stream reaches each time asked `lag` s late
        def wait_until(t: float) -> float:
            asked.append((name, t))
            return t + lag
        return wait_until
    clock = TeamClock([PacedClock(0.1, robot("a", 0.0), start=5.0), PacedClock(0.1, robot("b", 0.02), start=40.0)])
    assert clock.period == 0.1
    clock.tick()
    clock.tick()
    # robot b's second period runs from where its stream was (40.12), not from where it was asked to be
    assert asked == [("a", 5.1), ("b", 40.1), ("a", pytest.approx(5.2)), ("b", pytest.approx(40.22))]
    assert clock.now() == pytest.approx(0.2)
    with pytest.raises(ValueError):
        TeamClock([])
