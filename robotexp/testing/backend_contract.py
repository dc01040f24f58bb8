"""The contract every robot backend keeps against its emulator, as plain functions a test suite calls.

A backend author describes the pair once, in a `BackendHarness` (how to connect the backend to a
running emulator, what velocity the emulator last decoded, how to make the emulator stall, vanish
or send garbage), and hands a factory of it to each check, or to `check_backend` for all of them:

```python
@contextmanager
def my_pair() -> Iterator[BackendHarness]:
    with MyEmulator(world, speedup=10.0) as emu:
        yield BackendHarness(name="mine", connect=lambda **kw: MyRobot(emu.address, **kw), ...)

@pytest.mark.parametrize("check", CHECKS, ids=lambda c: c.__name__)
def test_contract(check):
    check(my_pair)
```

The checks, each on a fresh pair (docs/backend-contract.md says why each one matters):

- `check_handshake`: connecting yields an open robot whose state is finite and whose robot time
  advances tick by tick; after `close()` it is closed, `read()` raises RobotError, a second
  `close()` is harmless;
- `check_velocity`: commands (forward, turning in place, backwards while turning, and one beyond
  the robot's limits, which arrives clamped) reach the emulator in SI within the protocol's
  resolution, and the robot's reported speed follows;
- `check_stop_on_close`: closing a moving robot leaves a stop as the last command the emulator heard;
- `check_watchdog`: a control loop that stops calling `command()` gets the robot stopped by the
  backend itself (its `watchdog_stops` counts it, where it keeps one);
- `check_peer_vanishing`: the emulator going away ends the next reads with ConnectionLost within
  the silence timeout plus `slack`; the backend then refuses motion, `close()` is quiet, and an
  emulator that outlives its client has its robot stopped;
- `check_garbage`: random bytes (and frames with wrong checksums, where the harness can make them)
  in the stream are survived: no error, robot time goes on, the pose never jumps, commands still
  arrive, and the final stop too;
- `check_stall`: an emulator that keeps the connection but stops sending ends the reads with
  ConnectionLost within the silence timeout plus `slack`, and the backend's last command is a stop.

Every failure is a `BackendContractError` (an AssertionError, so pytest shows it as a test failure)
naming the backend and the check. Waits are bounded; the whole contract takes a few seconds of wall
time per backend with an emulator sped up ~10x.
"""

from __future__ import annotations

import math
import random
import time
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import Any

from robotexp.errors import ConnectionLost, RobotError
from robotexp.robot import Robot, RobotState, Twist

__all__ = ["BackendHarness", "BackendContractError", "HarnessFactory", "CHECKS", "check_backend",
           "check_handshake", "check_velocity", "check_stop_on_close", "check_watchdog", "check_peer_vanishing",
           "check_garbage", "check_stall"]

PERIOD = 0.1            # [s] robot time per control tick in the checks


@dataclass
class BackendHarness:
    """One backend connected to its running emulator, as the checks see the pair.

    Attributes:
        name: the backend's name (messages).
        connect: opens the backend on the emulator, e.g. ``lambda **kw: MyRobot(emu.address, **kw)``;
            called with no keyword, or with ``watchdog=`` [s] alone (`check_watchdog`).
        received: the last velocity command the emulator decoded from the backend, in SI (None
            before any): what the protocol carried, not what the emulated robot does.
        stall: make the emulator stop sending while it keeps the connection and reads commands.
        vanish: make the emulator go away (close its socket or its device; it may stop serving).
        garbage: send these bytes to the backend before the emulator's next frame.
        emulator: the emulator object, whose `sim` (a `robotexp.sim.SimRobot`), when it has one
            and it is still open after `vanish`, must have been stopped.
        corrupt: send the next n frames with wrong checksums (None: the emulator cannot).
        timeout: [s] the backend's silence timeout (as it is constructed by `connect`).
        v_resolution: [m/s] what the protocol's speed units round to (plus float noise).
        w_resolution: [rad/s] the same for turn rates.
    """

    name: str
    connect: Callable[..., Robot]
    received: Callable[[], Twist | None]
    stall: Callable[[], None]
    vanish: Callable[[], None]
    garbage: Callable[[bytes], None]
    emulator: Any = None
    corrupt: Callable[[int], None] | None = None
    timeout: float = 1.0
    v_resolution: float = 0.002
    w_resolution: float = 0.02


HarnessFactory = Callable[[], AbstractContextManager[BackendHarness]]


class BackendContractError(AssertionError):
    """A backend broke its contract: the message names the backend, the check and what happened."""


def _fail(h: BackendHarness, check: str, what: str) -> BackendContractError:
    return BackendContractError(f"backend {h.name!r}, {check}: {what}")


def _wait_for(cond: Callable[[], bool], timeout: float) -> bool:
    """Poll `cond` until it holds (True) or `timeout` [s] of wall time pass (its last value)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.005)
    return cond()


def _near(a: Twist | None, b: Twist, h: BackendHarness) -> bool:
    return a is not None and abs(a.v - b.v) <= h.v_resolution and abs(a.w - b.w) <= h.w_resolution


def _finite(state: RobotState) -> bool:
    p = state.pose
    return all(math.isfinite(v) for v in (state.time, p.x, p.y, p.theta, state.velocity.v, state.velocity.w))


def _drive(robot: Robot, twist: Twist, ticks: int) -> RobotState:
    """Command `twist` at each of `ticks` control ticks (as a control loop does); the state after."""
    clock = robot.make_clock(PERIOD)
    for _ in range(ticks):
        robot.command(twist)
        clock.tick()
    return robot.read()


def _arrives(h: BackendHarness, check: str, twist: Twist, timeout: float = 2.0) -> None:
    if not _wait_for(lambda: _near(h.received(), twist, h), timeout):
        raise _fail(h, check, f"the emulator's last command is {h.received()!r}, not {twist!r} "
                              f"(within {h.v_resolution} m/s, {h.w_resolution} rad/s) after {timeout} s")


def _stopped(h: BackendHarness, check: str, after: str, timeout: float = 2.0) -> None:
    if not _wait_for(lambda: _near(h.received(), Twist.ZERO, h), timeout):
        raise _fail(h, check, f"{after}, the last command the emulator heard is {h.received()!r}, not a stop")


def check_handshake(make: HarnessFactory) -> None:
    """Connect, read a finite state, see robot time advance over control ticks, close (twice).

    Raises:
        BackendContractError: what broke.
    """
    check = "handshake"
    with make() as h:
        robot = h.connect()
        try:
            if robot.closed:
                raise _fail(h, check, "the robot reports closed right after connecting")
            if not (robot.radius > 0 and robot.limits.v_max > 0 and robot.limits.w_max > 0):
                raise _fail(h, check, f"radius {robot.radius} m and limits {robot.limits} must be > 0")
            first = robot.read()
            if not _finite(first):
                raise _fail(h, check, f"the first state is not finite: {first}")
            clock = robot.make_clock(PERIOD)
            for _ in range(3):
                clock.tick()
            later = robot.read()
            if not later.time - first.time >= 3 * PERIOD - 0.011:
                raise _fail(h, check, f"robot time went from {first.time} s to {later.time} s over three "
                                      f"ticks of {PERIOD} s")
        finally:
            robot.close()
        if not robot.closed:
            raise _fail(h, check, "the robot does not report closed after close()")
        try:
            robot.read()
        except RobotError:
            pass
        else:
            raise _fail(h, check, "read() after close() did not raise RobotError")
        robot.close()                   # a second close is harmless


def check_velocity(make: HarnessFactory) -> None:
    """Commands reach the emulator in SI (clamped to the limits) and the reported speed follows.

    Raises:
        BackendContractError: what broke.
    """
    check = "velocity"
    with make() as h, h.connect() as robot:
        lim = robot.limits
        forward, turn = round(lim.v_max / 3, 2), round(lim.w_max / 5, 2)
        for twist in (Twist(forward, 0.0), Twist(0.0, -2 * turn), Twist(-forward / 2, turn)):
            _drive(robot, twist, 3)
            _arrives(h, check, twist)
        _drive(robot, Twist(10 * lim.v_max, 0.0), 3)
        _arrives(h, check, Twist(lim.v_max, 0.0))        # Robot.command clamps to the limits
        # the robot's own report of its speed follows the command (acceleration limits allowing)
        target = Twist(forward, 0.0)
        ticks = int(math.ceil((lim.v_max / lim.a_max + 1.0) / PERIOD))
        state = _drive(robot, target, ticks)
        if not abs(state.velocity.v - forward) <= max(0.1 * forward, 0.02):
            raise _fail(h, check, f"after {ticks * PERIOD:.1f} s at {forward} m/s the robot reports "
                                  f"v = {state.velocity.v:.3f} m/s")


def check_stop_on_close(make: HarnessFactory) -> None:
    """Closing a moving robot leaves a stop as the last command the emulator heard.

    Raises:
        BackendContractError: what broke.
    """
    check = "stop on close"
    with make() as h:
        with h.connect() as robot:
            twist = Twist(round(robot.limits.v_max / 3, 2), round(robot.limits.w_max / 5, 2))
            _drive(robot, twist, 3)
            _arrives(h, check, twist)
        _stopped(h, check, "after close()")


def check_watchdog(make: HarnessFactory, *, watchdog: float = 0.3) -> None:
    """A control loop that stops calling `command()` has the robot stopped by the backend.

    Args:
        make: the harness factory.
        watchdog: [s] the backend's watchdog for this check (passed as `connect(watchdog=...)`).

    Raises:
        BackendContractError: what broke.
    """
    check = "watchdog"
    with make() as h, h.connect(watchdog=watchdog) as robot:
        twist = Twist(round(robot.limits.v_max / 3, 2), 0.0)
        robot.command(twist)
        _arrives(h, check, twist)
        before = getattr(robot, "watchdog_stops", None)
        _stopped(h, check, f"with no command() for {watchdog} s + 1 s", timeout=watchdog + 1.0)
        after = getattr(robot, "watchdog_stops", None)
        if before is not None and after != before + 1:
            raise _fail(h, check, f"watchdog_stops went from {before} to {after}, not up by one")
        robot.read()                    # the link is fine: the watchdog stopped the robot, nothing failed


def _until_lost(h: BackendHarness, check: str, robot: Robot, twist: Twist, bound: float) -> float:
    """Drive until the backend raises; the wall time it took [s]. The error must be ConnectionLost."""
    t0 = time.monotonic()
    clock = robot.make_clock(PERIOD)
    try:
        while time.monotonic() - t0 < bound + 5.0:
            robot.command(twist)
            clock.tick()
            robot.read()
    except ConnectionLost:
        return time.monotonic() - t0
    except RobotError as exc:
        raise _fail(h, check, f"raised {type(exc).__name__} ({exc}), not ConnectionLost") from exc
    raise _fail(h, check, f"no ConnectionLost within {bound + 5.0:.1f} s")


def _lose_link(h: BackendHarness, check: str, robot: Robot, fault: Callable[[], None], what: str,
               slack: float) -> Twist:
    """Drive, then inject `fault`: ConnectionLost must end the loop within the silence timeout plus
    `slack` [s]. Returns the command the loop was sending."""
    twist = Twist(round(robot.limits.v_max / 3, 2), 0.0)
    _drive(robot, twist, 3)
    _arrives(h, check, twist)
    fault()
    bound = h.timeout + slack
    took = _until_lost(h, check, robot, twist, bound)
    if took > bound:
        raise _fail(h, check, f"ConnectionLost came {took:.2f} s after {what} (bound: {h.timeout} s silence "
                              f"+ {slack} s)")
    return twist


def check_peer_vanishing(make: HarnessFactory, *, slack: float = 0.6) -> None:
    """The emulator going away: ConnectionLost within `timeout + slack` [s], motion refused, quiet close.

    Raises:
        BackendContractError: what broke.
    """
    check = "peer vanishing"
    with make() as h:
        robot = h.connect()
        try:
            twist = _lose_link(h, check, robot, h.vanish, "the peer vanished", slack)
            try:
                robot.command(twist)
            except RobotError:
                pass
            else:
                raise _fail(h, check, "a motion command after the link was lost did not raise RobotError")
        finally:
            try:
                robot.close()
            except Exception as exc:
                raise _fail(h, check, f"close() after the link was lost raised {type(exc).__name__}: {exc}") from exc
        sim = getattr(h.emulator, "sim", None)
        if sim is not None and not sim.closed and not _wait_for(lambda: sim.commanded == Twist.ZERO, 2.0):
            raise _fail(h, check, f"the emulated robot still has the command {sim.commanded} in force after its "
                                  "client vanished")


def check_garbage(make: HarnessFactory, *, seed: int = 7, size: int = 2000) -> None:
    """`size` random bytes (and wrong checksums) in the stream are survived without a jump or an error.

    Raises:
        BackendContractError: what broke.
    """
    check = "garbage"
    rng = random.Random(seed)
    with make() as h:
        with h.connect() as robot:
            lim = robot.limits
            twist = Twist(round(lim.v_max / 3, 2), 0.0)
            state = _drive(robot, twist, 3)
            h.garbage(bytes(rng.randrange(256) for _ in range(size)))
            if h.corrupt is not None:
                h.corrupt(3)
            clock = robot.make_clock(PERIOD)
            t0 = state.time
            try:
                for _ in range(20):
                    robot.command(twist)
                    clock.tick()
                    new = robot.read()
                    step = state.pose.distance_to(new.pose)
                    if not _finite(new) or step > lim.v_max * (new.time - state.time + PERIOD) + 0.05:
                        raise _fail(h, check, f"the pose jumped {step:.3f} m between robot times {state.time:.2f} "
                                              f"and {new.time:.2f} s: {state.pose} -> {new.pose}")
                    state = new
            except RobotError as exc:
                raise _fail(h, check, f"{size} garbage bytes ended the link: {type(exc).__name__}: {exc}") from exc
            if not state.time - t0 >= 20 * PERIOD - 0.011:
                raise _fail(h, check, f"robot time went only from {t0} s to {state.time} s over 20 ticks")
            _arrives(h, check, twist)
        _stopped(h, check, "after close()")


def check_stall(make: HarnessFactory, *, slack: float = 0.6) -> None:
    """An emulator that stops sending: ConnectionLost within `timeout + slack` [s], then a stop is the
    last command it heard.

    Raises:
        BackendContractError: what broke.
    """
    check = "stall"
    with make() as h:
        robot = h.connect()
        try:
            _lose_link(h, check, robot, h.stall, "the stream stopped", slack)
            _stopped(h, check, "after the silence was detected")
        finally:
            robot.close()


CHECKS: tuple[Callable[[HarnessFactory], None], ...] = (
    check_handshake, check_velocity, check_stop_on_close, check_watchdog, check_peer_vanishing, check_garbage,
    check_stall,
)


def check_backend(make: HarnessFactory) -> None:
    """Run every check of the contract, each on a fresh pair from `make`.

    Raises:
        BackendContractError: the first check that fails.
    """
    for check in CHECKS:
        check(make)
