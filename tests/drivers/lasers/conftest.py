"""Fixtures shared by the laser tests: a Kobuki emulator with an RPLidar emulator on pseudo-terminals."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from robotexp.robot import Pose
from robotexp.sim import mounted_source
from robotexp.world.model import World
from robotexp_drivers.kobuki.emulator import KobukiEmulator
from robotexp_drivers.lasers.rplidar.emulator import RPLidarEmulator


@pytest.fixture
def devices(world: World, start: Pose) -> Iterator[tuple[KobukiEmulator, RPLidarEmulator]]:
    """A Kobuki emulator of ufmg-static at path1 and an RPLidar emulator measuring from its robot,
    each on a pseudo-terminal, 10x real time."""
    with KobukiEmulator(world, pose=start, speedup=10.0, pty=True) as kobuki, \
            RPLidarEmulator(mounted_source(kobuki.sim, lock=kobuki.lock), pty=True, speedup=10.0) as lidar:
        yield kobuki, lidar
