"""When scans and robot states happened: a read that brings several scans stamps them a scan period
apart (`ScanStamps`), a read that brings several robot states stamps them by their robot time
(`StateStamps`), an RPLidar read says how much of the next turn came after the newest complete one,
and a laser mounted on a stream robot pairs its scans with every state the robot sent, not only the
states the control loop read (Kobuki emulator on a pseudo-terminal)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from robotexp.run.laser_mount import LaserMountedRobot
from robotexp.robot import Twist
from robotexp_drivers.backend import StateStamps
from robotexp_drivers.kobuki.robot import KobukiRobot
from robotexp_drivers.lasers.base import ScanStamps
from robotexp_drivers.lasers.rplidar import RPLidarLaser
from robotexp_drivers.lasers.rplidar.codec import ScanDecoder, encode_scan


def test_scans_of_one_read_are_stamped_a_period_apart() -> None:
    s = ScanStamps(0.1)
    # first read: 3 scans, the newest ended 0.02 s before the read; the nominal period spaces them
    assert s.stamps(3, 10.0, after=0.02) == pytest.approx([9.78, 9.88, 9.98])
    # second read: 2 scans over 10.2 - 9.98 = 0.22 s: the period becomes 0.22 / 2 = 0.11
    assert s.stamps(2, 10.2) == pytest.approx([10.09, 10.2])
    assert s.period == pytest.approx(0.11)
    # third read: 4 scans 0.1 s after the last: decaying sums (0.9 * 0.22 + 0.1) / (0.9 * 2 + 4); none
    # earlier than the previous newest (10.2): spaced 0.1 / 4 apart
    assert s.stamps(4, 10.3) == pytest.approx([10.225, 10.25, 10.275, 10.3])
    assert s.period == pytest.approx((0.9 * 0.22 + 0.1) / (0.9 * 2 + 4))
    assert s.stamps(0, 11.0) == [] and s.newest == pytest.approx(10.3)


def test_states_of_one_read_are_stamped_by_their_robot_time() -> None:
    s = StateStamps()
    # first read: no rate known yet, robot seconds taken as host seconds
    assert s.stamps([0.0, 0.02, 0.04], 5.0) == pytest.approx([4.96, 4.98, 5.0])
    # second read: 0.04 robot s in 0.004 host s (an emulator at 10x): 0.1 host s per robot s
    assert s.stamps([0.06, 0.08], 5.004) == pytest.approx([5.002, 5.004])
    assert s.host_per_robot == pytest.approx(0.1)
    # a long backlog: states older than the previous read's newest are not stamped before it
    third = s.stamps([0.1, 0.2, 0.3, 0.4], 5.02)
    rate = (0.9 * 0.004 + 0.016) / (0.9 * 0.04 + 0.32)
    assert rate == pytest.approx(s.host_per_robot)
    assert third == pytest.approx([max(5.02 - (0.4 - t) * rate, 5.004) for t in (0.1, 0.2, 0.3, 0.4)])
    assert third[0] == pytest.approx(5.004) and s.stamps([], 6.0) == []


def test_rplidar_decoder_counts_the_samples_after_the_newest_turn() -> None:
    ranges = np.linspace(0.5, 5.0, 360)
    dec = ScanDecoder(360)
    turns = dec.feed(encode_scan(ranges) * 2 + encode_scan(ranges, first=0, count=20))
    # two turns completed (the second by the next turn's first node); 20 samples of the third came after
    assert len(turns) == 2 and dec.turn_samples == 360 and dec.open_samples == 20
    assert dec.feed(encode_scan(ranges, first=20, count=20)) == [] and dec.open_samples == 40


def test_a_mounted_laser_pairs_with_every_state_the_kobuki_sent(devices, wait_for) -> None:
    kobuki, lidar = devices
    with LaserMountedRobot(KobukiRobot(kobuki.address), RPLidarLaser(lidar.address)) as robot:
        assert robot.streamed
        robot.read()
        robot.command(Twist(0.2, 0.5))

        def driven() -> bool:
            times, poses = robot.history.samples()
            return len(times) >= 50 and poses[-1].distance_to(poses[0]) > 0.05

        # no read meanwhile: the states still reach the pose history (50 Kobuki frames at 50 Hz and 5 cm of
        # travel: 0.1 s at 10x on an idle machine; a loaded one may starve the emulator for seconds)
        assert wait_for(driven, 30.0)
        robot.command(Twist.ZERO)
        times, poses = robot.history.samples()
        assert len(times) >= 50 and np.all(np.diff(times) > 0)
        assert poses[-1].distance_to(poses[0]) > 0.05
        # when the robot stands still the newest state in the history is the one read() returns
        assert wait_for(lambda: robot.robot.read().velocity == Twist(0.0, 0.0), 10.0)
        time.sleep(0.1)
        assert robot.history.samples()[1][-1] == robot.robot.read().pose


def test_the_p3dx_emulator_world_moves_between_sips() -> None:
    # a laser emulator measures the emulated world whenever it likes: between two SIPs (100 ms of
    # robot time) the robot must be on its way, not parked where the last SIP put it
    from robotexp_drivers.p3dx.emulator import P3DXEmulator
    from robotexp_drivers.p3dx.robot import P3DXRobot

    with P3DXEmulator("dense", pose="1", port=0, speedup=1.0) as emu, P3DXRobot(emu.address) as robot:
        robot.command(Twist(0.3, 0.0))
        robot.wait_until(robot.read().time + 0.5)        # up to speed
        xs, sips = set(), emu.sips_sent
        end = time.monotonic() + 0.5
        while time.monotonic() < end:
            xs.add(emu.sim.true_pose.x)
            time.sleep(0.002)
        sips = emu.sips_sent - sips
        robot.command(Twist.ZERO)
    # 5 SIPs in 0.5 s; the world moves every 20 ms of robot time (a loaded machine wakes the emulator
    # less often, but more than once a cycle); parked between SIPs it would take at most sips + 1 places
    assert sips >= 2 and len(xs) >= 2 * sips, (sips, len(xs))
