"""Pacing, pause, step and stop of the live view without a browser: the `Pacer` on a
fake clock, then `ViewObserver` holding a real simulated run (robot time stands still while paused,
one tick per step, a stop from the view ends the run as STOPPED with its reason)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from robotexp.experiment import RunOutput, run_experiment
from robotexp.run.spec import RunSpec
from robotexp.run.record import EndReason
from robotexp.output.results import read_records
from robotexp.robot import Pose
from robotexp.view.feed import ViewHub
from robotexp.view.observer import STOP_REASON, Pacer, ViewObserver


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0
        self.slept: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, dt: float) -> None:
        self.slept.append(dt)
        self.now += dt


def test_pacer_keeps_robot_time_at_speed() -> None:
    clock = FakeClock()
    pacer = Pacer(10.0, clock=clock, sleep=clock.sleep)
    pacer.wait(0.0)                     # the reference
    for k in range(1, 6):
        clock.now += 0.004              # the tick's own work: 4 ms of 10 ms allowed
        pacer.wait(k * 0.1)
    assert clock.slept == pytest.approx([0.006] * 5)
    assert clock.now == pytest.approx(100.05)        # 0.5 s robot time in 0.05 s wall: 10x
    clock.now += 2.0                    # a long stall: pace from there, no burst to catch up
    clock.slept.clear()
    pacer.wait(0.6)
    pacer.wait(0.7)
    assert clock.slept == pytest.approx([0.01])
    pacer.set_speed(None)               # max: never sleeps
    clock.slept.clear()
    for k in range(8, 20):
        pacer.wait(k * 0.1)
    assert clock.slept == []
    with pytest.raises(ValueError):
        pacer.set_speed(0.0)


def test_pacer_pause_step_resume_stop_and_halt() -> None:
    pacer = Pacer(None, halt_period=0.02)
    passed: list[float] = []
    halts: list[float] = []
    holds: list[bool] = []

    def loop() -> None:
        for k in range(1000):
            pacer.wait(k * 0.1, halt=lambda: halts.append(time.monotonic()), on_hold=holds.append)
            passed.append(k)
            if pacer.stopped:
                return
            time.sleep(0.001)

    def holding(times: int) -> bool:
        """The loop is held (for the `times`-th time since it started)."""
        return holds.count(True) == times and holds[-1] is True

    # every wait below is on the loop's own signals (a loaded machine can leave the thread unscheduled
    # for long); the sleeps only give a wrong loop the time to show itself
    pacer.pause()
    t = threading.Thread(target=loop)
    t.start()
    _wait(lambda: len(halts) >= 3)       # halt at once and every halt_period while held
    assert passed == [] and holding(1)   # held at the first tick
    pacer.step()
    _wait(lambda: holding(2))            # one tick, then held again
    time.sleep(0.05)
    assert passed == [0]                 # exactly one tick
    pacer.step()
    pacer.step()
    # two ticks, held again (a third or, had the loop taken the first step between the two calls, a fourth time)
    _wait(lambda: len(passed) >= 3 and (holding(3) or holding(4)))
    time.sleep(0.05)
    assert passed == [0, 1, 2]
    pacer.resume()
    _wait(lambda: len(passed) > 10)
    assert holds[-1] is False            # not held while running
    pacer.pause()
    _wait(lambda: holds[-1] is True)
    n = len(passed)
    time.sleep(0.1)
    assert len(passed) == n
    pacer.stop()
    t.join(2)
    assert not t.is_alive() and passed[-1] == n
    assert holds[0] is True and holds.count(True) == holds.count(False)


def _run_in_thread(spec: RunSpec, observer: ViewObserver, out: Path) -> tuple[threading.Thread, list[RunOutput]]:
    result: list[RunOutput] = []
    thread = threading.Thread(target=lambda: result.append(run_experiment(spec, out, observers=[observer],
                                                                          image=False)))
    thread.start()
    return thread, result


def _wait(cond: object, timeout: float = 30.0) -> None:
    end = time.monotonic() + timeout
    while not cond():               # type: ignore[operator]
        assert time.monotonic() < end, "timed out"
        time.sleep(0.01)


def _rounded(pose: Pose) -> tuple[float, float, float]:
    return round(pose.x, 4), round(pose.y, 4), round(pose.theta, 4)


def _settled(read: Callable[[], object], timeout: float = 30.0, quiet: float = 0.3) -> object:
    """`read()` once it has kept its value for `quiet` s (a held loop: under load the loop may still be inside
    its tick, or decelerating, well after the command); fails after `timeout` s of change."""
    end = time.monotonic() + timeout
    value = read()
    while True:
        time.sleep(quiet)
        now = read()
        if now == value:
            return now
        assert time.monotonic() < end, f"still changing after {timeout} s: {value!r} -> {now!r}"
        value = now


def test_observer_pauses_steps_and_stops_a_simulated_run(tmp_path: Path) -> None:
    hub = ViewHub()
    observer = ViewObserver(hub, speed=None, frame_rate=200)
    observer.command({"cmd": "pause"})               # paused from the start
    spec = RunSpec(world="ufmg-static", method="frontier", max_time=600.0)
    thread, result = _run_in_thread(spec, observer, tmp_path)
    try:
        _wait(lambda: hub.status["state"] == "paused" and hub.meta)
        assert hub.meta["simulated"] is True and hub.meta["geo"]["cell"] > 0
        time.sleep(0.3)
        assert hub.time == 0.0                       # robot time does not pass while paused
        observer.command({"cmd": "step"})
        _wait(lambda: hub.time > 0)
        time.sleep(0.2)
        assert hub.time == pytest.approx(0.1)        # one control tick
        observer.command({"cmd": "resume"})
        # the robot turns a full circle where it starts (about 4.5 s) before it drives: wait for its path too
        _wait(lambda: hub.time > 3.0 and len(hub.path) > 2)
        observer.command({"cmd": "pause"})
        held = _settled(lambda: hub.time)            # the loop reached its hold (it may be mid-tick)
        time.sleep(0.3)
        assert hub.time == held and hub.status["state"] == "paused"
        assert hub.classes is not None and len(hub.path) > 2 and hub.curve
    finally:
        observer.command({"cmd": "stop"})
        thread.join(30)
    record = result[0].record
    assert record.end is EndReason.STOPPED and record.reason == STOP_REASON
    assert not record.completed
    assert record.robot_time_s == pytest.approx(held, abs=0.2)
    assert hub.status["state"] == "ended" and hub.status["reason"] == STOP_REASON
    written = read_records(tmp_path / "results.jsonl")
    assert [(r.end, r.reason) for r in written] == [(EndReason.STOPPED, STOP_REASON)]


def test_observer_paces_a_simulated_run(tmp_path: Path) -> None:
    hub = ViewHub()
    observer = ViewObserver(hub, speed=20.0)
    spec = RunSpec(world="ufmg-static", method="frontier", max_time=10.0)
    t0 = time.monotonic()
    thread, result = _run_in_thread(spec, observer, tmp_path)
    thread.join(60)
    wall = time.monotonic() - t0
    rec = result[0].record
    assert rec.end is EndReason.TIME_LIMIT
    assert wall >= 10.0 / 20.0 * 0.95                # not faster than asked
    assert hub.status["state"] == "ended"


def test_pause_stops_a_real_robot_until_resumed(tmp_path: Path) -> None:
    """On a robot behind a protocol (the Kobuki emulator over TCP, 30x real time) a pause commands a stop
    and the robot stands still while paused; the speed control is off (a real robot runs in real time)."""
    from robotexp.experiment import run_on_robot
    from robotexp.world.builtin import builtin_world
    from robotexp.world.poses import resolve_pose
    from robotexp_drivers.kobuki.codec import BaseControl
    from robotexp_drivers.kobuki.emulator import EmulatorLaser, KobukiEmulator
    from robotexp_drivers.kobuki.robot import KobukiRobot

    world = builtin_world("ufmg-static")
    hub = ViewHub()
    observer = ViewObserver(hub, speed=1.0)      # would crawl, were pacing applied to a real robot
    spec = RunSpec(world="ufmg-static", robot="kobuki", method="frontier", pose="path1", max_time=600.0)
    result: list[RunOutput] = []
    # the driver's watchdog at 60 s: the pause must stop the robot, not the watchdog
    with KobukiEmulator(world, pose=resolve_pose(world, "path1", 0.18)[0], speedup=30.0) as emu, \
            KobukiRobot(emu.address, laser=EmulatorLaser(emu), watchdog=60.0) as robot:
        thread = threading.Thread(target=lambda: result.append(run_on_robot(spec, robot, None, world,
                                                                            observers=[observer])))
        thread.start()
        try:
            _wait(lambda: hub.time > 5.0)         # 5 s robot time: well under 5 s wall at 30x
            assert hub.controls == ("pause", "step", "stop")
            _wait(lambda: emu.last_base_control not in (None, BaseControl(0, 0)))     # driving
            observer.command({"cmd": "pause"})
            _wait(lambda: emu.last_base_control == BaseControl(0, 0), 10.0)
            # decelerating (0.3 s wall is 9 s of robot time at 30x), then it stands still while paused
            p0 = _settled(lambda: _rounded(emu.sim.true_pose))
            time.sleep(0.3)
            p1 = emu.sim.true_pose
            assert p0 == pytest.approx((p1.x, p1.y, p1.theta), abs=1e-4)
            assert emu.last_base_control == BaseControl(0, 0)
            observer.command({"cmd": "resume"})
            _wait(lambda: emu.last_base_control != BaseControl(0, 0), 10.0)
        finally:
            observer.command({"cmd": "stop"})
            thread.join(30)
    assert result[0].record.end is EndReason.STOPPED
