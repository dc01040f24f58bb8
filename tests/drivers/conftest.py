"""Fixtures shared by the driver tests: the ufmg-static world, emulators on it, run specs, waiting."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

import pytest

from robotexp.run.spec import RunSpec
from robotexp.world.poses import resolve_pose
from robotexp.robot import Pose
from robotexp.world.builtin import builtin_world
from robotexp.world.model import World
from robotexp_drivers.kobuki.emulator import KobukiEmulator
from robotexp_drivers.kobuki.robot import KOBUKI_RADIUS
from robotexp_drivers.mavlink.emulator import MavlinkEmulator
from robotexp_drivers.mavlink.robot import ROVER_RADIUS

WaitFor = Callable[..., bool]


def _wait_for(cond: Callable[[], bool], timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.002)
    return cond()


@pytest.fixture
def wait_for() -> WaitFor:
    """`wait_for(cond, timeout=10.0)`: poll `cond` until it holds (True) or `timeout` s pass (its last value).
    The default is generous on purpose: a loaded machine can starve an emulator's thread for seconds, and a
    condition met early costs nothing; a test that bounds a delay passes its own `timeout`."""
    return _wait_for


@pytest.fixture
def run_spec() -> Callable[[str, float], RunSpec]:
    """`run_spec(robot, max_time)`: frontier exploration of ufmg-static from path1 at 0.3 m/s."""
    def make(robot: str, max_time: float) -> RunSpec:
        return RunSpec(world="ufmg-static", robot=robot, method="frontier", pose="path1", speed=0.3,
                       max_time=max_time)
    return make


@pytest.fixture(scope="module")
def world() -> World:
    return builtin_world("ufmg-static")


@pytest.fixture
def start(world: World) -> Pose:
    """Where a Kobuki starts in ufmg-static (pose path1)."""
    return resolve_pose(world, "path1", KOBUKI_RADIUS)[0]


@pytest.fixture
def emulator(world: World, start: Pose) -> Iterator[KobukiEmulator]:
    """A Kobuki emulator of ufmg-static at path1, 30x real time, serving on TCP."""
    with KobukiEmulator(world, pose=start, speedup=30.0) as emu:
        yield emu


@pytest.fixture
def emu(world: World) -> Iterator[MavlinkEmulator]:
    """A MAVLink rover emulator of ufmg-static at path1, 10x real time, serving on UDP, with OBSTACLE_DISTANCE."""
    with MavlinkEmulator(world, pose=resolve_pose(world, "path1", ROVER_RADIUS)[0], speedup=10.0,
                         obstacle_distance=True) as e:
        yield e
