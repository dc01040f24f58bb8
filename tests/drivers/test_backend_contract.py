"""The backend contract (robotexp.testing.backend_contract) for every built-in backend against its emulator.

Each check runs on a fresh emulator of ufmg-static sped up 10x, through real sockets: TCP for p3dx
and kobuki, UDP for mavlink (as `robotexp emulate` serves them by default).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import pytest

from robotexp.world.poses import resolve_pose
from robotexp.robot import Twist
from robotexp.testing.backend_contract import CHECKS, BackendContractError, BackendHarness, HarnessFactory
from robotexp.world.model import World
from robotexp_drivers.kobuki.codec import twist_from_base_control
from robotexp_drivers.kobuki.emulator import KobukiEmulator
from robotexp_drivers.kobuki.robot import KOBUKI_RADIUS, KobukiRobot
from robotexp_drivers.mavlink.emulator import MavlinkEmulator
from robotexp_drivers.mavlink.robot import ROVER_RADIUS, MavlinkRobot
from robotexp_drivers.p3dx.emulator import P3DXEmulator
from robotexp_drivers.p3dx.robot import P3DXRobot

SPEEDUP = 10.0


def p3dx(world: World) -> HarnessFactory:
    @contextmanager
    def make() -> Iterator[BackendHarness]:
        with P3DXEmulator(world, pose="path1", port=0, speedup=SPEEDUP) as emu:
            def received() -> Twist | None:
                v_mm, w_deg = emu.commanded
                return Twist(v_mm / 1000, math.radians(w_deg))
            yield BackendHarness(
                name="p3dx", emulator=emu, connect=lambda **kw: P3DXRobot(emu.address, laser=False, **kw),
                received=received, stall=emu.stall, vanish=emu.vanish, garbage=emu.inject, timeout=1.0,
                v_resolution=0.0011, w_resolution=math.radians(1.01))     # VEL in mm/s, RVEL in deg/s
    return make


def kobuki(world: World) -> HarnessFactory:
    @contextmanager
    def make() -> Iterator[BackendHarness]:
        start = resolve_pose(world, "path1", KOBUKI_RADIUS)[0]
        with KobukiEmulator(world, pose=start, speedup=SPEEDUP) as emu:
            def received() -> Twist | None:
                m = emu.last_base_control
                return None if m is None else Twist(*twist_from_base_control(m.speed_mm_s, m.radius_mm))
            yield BackendHarness(
                name="kobuki", emulator=emu,
                connect=lambda **kw: KobukiRobot(emu.address, version_timeout=0.05, sound=False, **kw),
                received=received, stall=emu.pause_stream, vanish=emu.drop_client, garbage=emu.send_raw,
                corrupt=emu.corrupt_frames, timeout=1.0,
                v_resolution=0.0011, w_resolution=0.01)     # speed in mm/s, radius in mm
    return make


def mavlink(world: World) -> HarnessFactory:
    @contextmanager
    def make() -> Iterator[BackendHarness]:
        start = resolve_pose(world, "path1", ROVER_RADIUS)[0]
        with MavlinkEmulator(world, pose=start, speedup=SPEEDUP) as emu:
            yield BackendHarness(
                name="mavlink", emulator=emu, connect=lambda **kw: MavlinkRobot(emu.address, **kw),
                received=lambda: emu.last_twist, stall=emu.pause_stream, vanish=emu.close, garbage=emu.send_raw,
                corrupt=emu.corrupt_frames, timeout=1.0,
                v_resolution=1e-6, w_resolution=1e-6)       # float32 m/s and rad/s
    return make


BACKENDS: dict[str, Callable[[World], HarnessFactory]] = {"p3dx": p3dx, "kobuki": kobuki, "mavlink": mavlink}


@pytest.mark.parametrize("check", CHECKS, ids=lambda c: c.__name__.removeprefix("check_"))
@pytest.mark.parametrize("backend", list(BACKENDS))
def test_backend_keeps_the_contract(backend: str, check: Callable[[HarnessFactory], None], world: World) -> None:
    check(BACKENDS[backend](world))


def test_a_backend_that_breaks_the_contract_is_named() -> None:
    """The kit fails a pair whose emulator never hears the stop: the message names backend and check."""
    from robotexp.testing.backend_contract import check_stop_on_close
    from robotexp.world.builtin import builtin_world

    world = builtin_world("ufmg-static")
    real = kobuki(world)

    @contextmanager
    def deaf_to_stops() -> Iterator[BackendHarness]:
        with real() as h:
            heard: list[Twist | None] = []
            really = h.received

            def received() -> Twist | None:     # an emulator that drops every zero-speed command
                now = really()
                if now is not None and now != Twist.ZERO:
                    heard.append(now)
                return heard[-1] if heard else now
            h.received = received
            yield h

    with pytest.raises(BackendContractError, match=r"backend 'kobuki', stop on close: after close\(\), the last "
                                                   r"command the emulator heard is Twist\(v=0\.2"):
        check_stop_on_close(deaf_to_stops)
