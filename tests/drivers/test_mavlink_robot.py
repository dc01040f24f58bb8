"""MavlinkRobot against the emulator on real UDP/TCP sockets: connect, units, faults, watchdog."""

from __future__ import annotations

import math
import random
import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from robotexp.errors import ConnectionLost
from robotexp.run.spec import RunSpec
from robotexp.world.poses import resolve_pose
from robotexp.experiment import run_on_robot
from robotexp.robot import Twist
from robotexp.world.model import World
from robotexp_drivers.mavlink import constants as C
from robotexp_drivers.mavlink.emulator import MavlinkEmulator
from robotexp_drivers.mavlink.robot import MavlinkRobot

WaitFor = Callable[..., bool]                # the `wait_for` fixture (conftest.py)


def test_connect_guided_armed_pose_and_commands(emu: MavlinkEmulator, wait_for: WaitFor) -> None:
    with MavlinkRobot(emu.address) as robot:
        assert emu.mode == C.ROVER_MODE_GUIDED and emu.armed
        assert robot.describe()["mode"] == "GUIDED"
        s = robot.read()
        true = emu.sim.read().pose
        assert math.isclose(s.pose.x, true.x, abs_tol=1e-5) and math.isclose(s.pose.y, true.y, abs_tol=1e-5)
        assert s.laser is not None and s.laser.angles.size == 72
        clock = robot.make_clock(0.1)
        for _ in range(10):
            robot.command(Twist(0.3, 0.5))
            clock.tick()
        assert emu.last_twist is not None and math.isclose(emu.last_twist.v, 0.3, rel_tol=1e-6)
        s = robot.read()
        assert math.isclose(s.velocity.w, 0.5, rel_tol=1e-3) and math.isclose(s.velocity.v, 0.3, rel_tol=1e-3)
        assert s.battery == 12.6
    assert wait_for(lambda: emu.mode == C.ROVER_MODE_HOLD)
    assert emu.last_twist == Twist.ZERO


def test_tcp_and_pty_transports(world: World) -> None:
    for kw in ({"tcp": True}, {"pty": True}):
        with MavlinkEmulator(world, speedup=10.0, **kw) as e:   # type: ignore[arg-type]
            with MavlinkRobot(e.address) as robot:
                assert robot.read().pose.distance_to(e.sim.read().pose) < 1e-5


def test_watchdog_stops_the_vehicle(emu: MavlinkEmulator, wait_for: WaitFor, cpu_wait: Any) -> None:
    with MavlinkRobot(emu.address) as robot:
        mark, t0 = cpu_wait.total(), time.perf_counter()
        robot.command(Twist(0.3, 0.0))
        assert wait_for(lambda: robot.watchdog_stops == 1, 30.0)
        # within 1.5 s, plus what a loaded machine kept the threads waiting for a CPU meanwhile
        assert time.perf_counter() - t0 < 1.5 + cpu_wait.since(mark)
        # the stop is sent when the count goes up; the emulator has it a moment later
        assert wait_for(lambda: emu.last_twist == Twist.ZERO)


def test_vehicle_vanishing_mid_run_raises_within_a_second_and_writes_partial_result(
        tmp_path: os.PathLike[str], world: World, cpu_wait: Any) -> None:
    e = MavlinkEmulator(world, pose=resolve_pose(world, "path1", 0.25)[0], speedup=10.0, obstacle_distance=True).start()
    spec = RunSpec(world="ufmg-static", method="frontier", pose="path1", speed=0.3, max_time=300)
    with MavlinkRobot(e.address) as robot:
        t_gone: list[float] = []
        waited: list[float] = []

        def on_sample(t: float, cov: float | None) -> None:
            if t >= 3.0 and not t_gone:
                e.close()
                t_gone.append(time.perf_counter())
                waited.append(cpu_wait.total())

        out = run_on_robot(spec, robot, tmp_path, world, on_sample=on_sample)
        detected = time.perf_counter() - t_gone[0]
        with pytest.raises(ConnectionLost):
            robot.read()
    # 1 s silence + one control period, plus what a loaded machine kept the threads waiting for a CPU meanwhile
    assert detected < 1.3 + cpu_wait.since(waited[0])
    assert out.record["completed"] is False
    assert (tmp_path / "results.jsonl").read_text().count("\n") == 1


def test_stalled_link_raises_and_the_last_command_is_a_stop(emu: MavlinkEmulator, wait_for: WaitFor,
                                                            cpu_wait: Any) -> None:
    with MavlinkRobot(emu.address) as robot:
        robot.command(Twist(0.2, 0.0))
        emu.pause_stream()
        t0, mark = time.perf_counter(), cpu_wait.total()
        with pytest.raises(ConnectionLost):
            clock = robot.make_clock(0.1)
            while True:
                robot.command(Twist(0.2, 0.0))
                clock.tick()
        assert time.perf_counter() - t0 < 1.2 + cpu_wait.since(mark)      # (a loaded machine: plus its CPU wait)
        assert wait_for(lambda: emu.last_twist == Twist.ZERO)


def test_garbage_burst_and_wrong_checksums_are_survived(emu: MavlinkEmulator, wait_for: WaitFor) -> None:
    with MavlinkRobot(emu.address) as robot:
        clock = robot.make_clock(0.1)
        # seeded garbage without frame-start bytes (0xFD, 0xFE): every byte of it must be dropped,
        # after a false MAVLink 2 start announcing a 255-byte payload
        rng = random.Random(7)
        garbage = bytes(rng.choice([b for b in range(256) if b not in (0xFD, 0xFE)]) for _ in range(2000))
        emu.send_raw(bytes([0xFD, 0xFF]) + garbage)
        emu.corrupt_frames(20)
        for _ in range(20):
            robot.command(Twist(0.2, 0.0))
            clock.tick()
        extra = robot.read().extra
        assert extra["bad_frames"] >= 20 and extra["dropped_bytes"] >= 2000
        assert emu.last_twist is not None and math.isclose(emu.last_twist.v, 0.2, rel_tol=1e-6)
    assert wait_for(lambda: emu.last_twist == Twist.ZERO)


def test_no_vehicle_is_connection_lost() -> None:
    with pytest.raises(ConnectionLost, match="no vehicle HEARTBEAT"):
        MavlinkRobot("udp:127.0.0.1:0", connect_timeout=0.3)


def _echo_errors(world: World, states: list[Any]) -> np.ndarray:
    """[m] distance from each echo of `states` (placed from the state's pose) to the world's walls."""
    from robotexp.mapping.geometry import GridGeometry
    from robotexp.world.groundtruth import occupancy
    from robotexp.planning.grid_planner import distance_transform

    geo = GridGeometry.covering(*world.bounds, cell=0.01, margin=0.5)
    dist = distance_transform(occupancy(world, geo)) * geo.cell
    out = []
    for s in states:
        scan, p = s.laser, s.pose
        hit = np.isfinite(scan.ranges) & (scan.ranges < scan.range_max)
        bx = scan.offset_x + scan.ranges[hit] * np.cos(scan.angles[hit])
        by = scan.ranges[hit] * np.sin(scan.angles[hit])
        c, sn = math.cos(p.theta), math.sin(p.theta)
        cells = geo.cells_of(np.column_stack([p.x + c * bx - sn * by, p.y + sn * bx + c * by]))
        out.append(dist[cells[:, 0], cells[:, 1]])
    return np.concatenate(out)


def _laser_states(world: World, seconds: float, twist: Twist | None) -> list[Any]:
    """The states with a scan, one per robot time, that a MavlinkRobot reads for `seconds` of wall time
    from the emulator (OBSTACLE_DISTANCE, 5x real time) at path1, commanding `twist` (None: none)."""
    start = resolve_pose(world, "path1", 0.25)[0]
    states: list[Any] = []
    with MavlinkEmulator(world, pose=start, speedup=5.0, obstacle_distance=True) as e:
        with MavlinkRobot(e.address) as robot:
            deadline = time.perf_counter() + seconds
            while time.perf_counter() < deadline:
                if twist is not None:
                    robot.command(twist)
                s = robot.read()
                if s.laser is not None and (not states or s.time != states[-1].time):
                    states.append(s)
                time.sleep(0.002)
    return states


@pytest.mark.parametrize("paired", [True, False])
def test_a_scan_is_placed_from_the_pose_at_its_stamp(world: World, paired: bool,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """OBSTACLE_DISTANCE comes at 10 Hz, poses at 20 Hz: while the rover turns at 90 deg/s, half the
    states carry a scan a pose old (4.5 deg). Placed from the pose at its stamp, every echo lies on a
    wall (whole cm, 1 cm raster); placed from the newest pose (a stamp on another clock than the
    vehicle's boot clock), echoes at a few metres miss the walls by decimetres. Each scan keeps its
    stamp in every state that carries it (the run loop maps it once)."""
    import robotexp_drivers.mavlink.robot as mr

    if not paired:
        monkeypatch.setattr(mr, "PAIR_SPAN", -1.0)
    states = [s for s in _laser_states(world, 1.5, Twist(0.0, math.radians(90)))
              if abs(s.velocity.w) > math.radians(80)]
    stamps = [s.laser.stamp for s in states]
    assert len(states) >= 20
    assert len(set(stamps)) < len(stamps)                 # scans repeated in several states ...
    assert len(set(stamps)) >= len(stamps) // 3           # ... each one two states or so
    err = _echo_errors(world, states)
    if paired:
        assert np.percentile(err, 95) < 0.03, np.percentile(err, [50, 95])
    else:
        assert np.percentile(err, 95) > 0.08, np.percentile(err, [50, 95])


def test_a_sender_that_leaves_time_usec_zero_still_gets_every_scan_mapped(world: World,
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """OBSTACLE_DISTANCE's time_usec may be 0 (a companion computer that does not stamp): such scans
    cannot be placed from the pose at their time, but each still gets a stamp of its own, so the run
    loop maps every scan once instead of the first one for ever."""
    orig = MavlinkEmulator._obstacle_distance

    def unstamped(self: MavlinkEmulator, t: float, scan: object) -> Any:
        msg = orig(self, t, scan)
        msg.time_usec = 0
        return msg

    monkeypatch.setattr(MavlinkEmulator, "_obstacle_distance", unstamped)
    stamps: list[float] = []
    for s in _laser_states(world, 1.0, None):
        if not stamps or s.laser.stamp != stamps[-1]:
            assert s.laser.stamp is not None
            stamps.append(s.laser.stamp)
    assert len(stamps) >= 20 and stamps == sorted(set(stamps))     # a new stamp for every scan
