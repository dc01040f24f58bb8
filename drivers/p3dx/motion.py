"""`ArcosMotion`: the P3-DX's motion controller as ARCOS runs it, for the emulator.

ARCOS (and MobileSim) drive translation and rotation independently, each in one of two modes:

- translation: velocity (VEL) or position (MOVE: travel a distance, then stop and hold);
- rotation: velocity (RVEL / ROTATE) or heading (HEAD: turn to an absolute heading of the
  odometry frame, DHEAD: relative to the current heading, DCHEAD: relative to the heading setpoint).

A later command of the other mode of the same axis cancels the first (VEL cancels a MOVE, RVEL a
HEAD); STOP is VEL 0 and RVEL 0. The position controllers drive a trapezoidal profile: at most the
maximum speed set with SETV (SETRV for rotation), and never faster than the speed from which the
deceleration stops the robot on the goal (`stopping_speed`, about sqrt(2 decel remaining)), nor faster than reaching it
within one control cycle. Every speed change is ramped with the acceleration (speeding up) or the
deceleration (slowing down) set with SETA / SETRA (positive argument: acceleration, negative:
deceleration); SETV and SETRV (and SETRVDIR per direction) also cap VEL and RVEL.

Units are the protocol's (mm, mm/s, mm/s^2, deg, deg/s, deg/s^2): the controller sits at the wire.
Sources: aria-sip.md §4 (command meanings), AriaCoda ArCommands.h and ArRobot::stateReflector (what
ARIA sends), MobileSim StageInterface.cc (translation and rotation modes set apart; MOVE / DHEAD
progress reset by a new command; ESTOP decelerates at once).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from robotexp import ConfigError

__all__ = ["ArcosMotion", "TransMode", "RotMode", "approach", "speeding_up", "stopping_speed"]

MOVE_DONE_MM = 0.5            # a MOVE is done within this distance of its goal
HEAD_DONE_DEG = 0.5           # a HEAD is held (no turning) within this angle of its goal


class TransMode(Enum):
    """What drives translation."""

    VEL = "vel"
    MOVE = "move"


class RotMode(Enum):
    """What drives rotation."""

    VEL = "vel"
    HEAD = "head"


def speeding_up(current: float, target: float) -> bool:
    """Going from speed `current` to `target` speeds up (same direction, or from a standstill)."""
    return abs(target) > abs(current) and (current == 0 or (current > 0) == (target > 0))


def approach(current: float, target: float, accel: float, decel: float, dt: float) -> float:
    """`current` moved towards `target` by at most `accel * dt` when speeding up, `decel * dt` when
    slowing down (towards or through zero).

    Args:
        current, target: speeds (any unit u).
        accel, decel: [u/s] magnitudes, > 0.
        dt: [s] time step.

    Returns:
        The speed after the step.
    """
    step = (accel if speeding_up(current, target) else decel) * dt
    if abs(target - current) <= step:
        return target
    return current + math.copysign(step, target - current)


def stopping_speed(left: float, decel: float, dt: float) -> float:
    """The highest speed from which steps of `dt`, each `decel * dt` slower, stop within `left`.

    Held over a step and lowered by a dt at each (a control loop's steps), speed v covers
    a dt^2 n (n + 1) / 2 with v = n a dt; so v (v + a dt) = 2 a left, and one step later the speed
    is exactly a dt less (the continuous-time sqrt(2 a left) overshoots by about v dt / 2).

    Args:
        left: distance to go (>= 0, any unit u).
        decel: [u/s^2] deceleration, > 0.
        dt: [s] step.
    """
    ad = decel * dt
    return (math.sqrt(ad * ad + 8.0 * decel * left) - ad) / 2.0


def _wrap_deg(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


@dataclass
class ArcosMotion:
    """Both axes' modes, goals and limits (see the module docstring); `step()` once per cycle.

    Args:
        trans_vel_max: [mm/s] SETV's maximum (MOVE speed, VEL cap).
        rot_vel_max: [deg/s] SETRV's maximum (HEAD speed, RVEL cap).
        trans_accel, trans_decel: [mm/s^2] SETA's values.
        rot_accel, rot_decel: [deg/s^2] SETRA's values.

    Raises:
        ConfigError: a limit that is not > 0.
    """

    trans_vel_max: float
    rot_vel_max: float
    trans_accel: float
    trans_decel: float
    rot_accel: float
    rot_decel: float

    def __post_init__(self) -> None:
        for name in ("trans_vel_max", "rot_vel_max", "trans_accel", "trans_decel", "rot_accel", "rot_decel"):
            value = getattr(self, name)
            if not (value > 0 and math.isfinite(value)):
                raise ConfigError(f"p3dx motion: {name} must be > 0, got {value}")
        self.rot_vel_max_pos = self.rot_vel_max     # SETRVDIR caps per direction (SETRV resets both)
        self.rot_vel_max_neg = self.rot_vel_max
        self.trans_mode, self.rot_mode = TransMode.VEL, RotMode.VEL
        self.vel = 0.0                   # [mm/s] VEL in force
        self.rot_vel = 0.0               # [deg/s] RVEL in force
        self.move_left = 0.0             # [mm] of the MOVE in progress, signed
        self.heading_goal = 0.0          # [deg] HEAD's goal in the odometry frame

    # -- commands ------------------------------------------------------------------------
    def set_vel(self, mm_s: float) -> None:
        """VEL: translate at this speed (cancels a MOVE)."""
        self.trans_mode, self.vel = TransMode.VEL, float(mm_s)

    def move(self, mm: float) -> None:
        """MOVE: translate this distance (forward > 0) from where the robot is, then stop."""
        self.trans_mode, self.move_left = TransMode.MOVE, float(mm)

    def set_rot_vel(self, deg_s: float) -> None:
        """RVEL / ROTATE: turn at this rate, counter-clockwise > 0 (cancels a HEAD)."""
        self.rot_mode, self.rot_vel = RotMode.VEL, float(deg_s)

    def head(self, deg: float) -> None:
        """HEAD: turn to this heading of the odometry frame and hold it."""
        self.rot_mode, self.heading_goal = RotMode.HEAD, _wrap_deg(float(deg))

    def delta_head(self, deg: float, heading_now: float) -> None:
        """DHEAD: turn by `deg` from the current heading `heading_now` [deg]."""
        self.head(heading_now + deg)

    def delta_setpoint(self, deg: float, heading_now: float) -> None:
        """DCHEAD: move the heading setpoint by `deg` (from the current heading when none is held)."""
        self.head((self.heading_goal if self.rot_mode is RotMode.HEAD else heading_now) + deg)

    def stop(self) -> None:
        """STOP (and ARIA's `stop()`): VEL 0 and RVEL 0, decelerating."""
        self.set_vel(0.0)
        self.set_rot_vel(0.0)

    def set_trans_max(self, mm_s: float) -> None:
        """SETV (the argument's magnitude; 0 is ignored)."""
        if mm_s:
            self.trans_vel_max = abs(float(mm_s))

    def set_rot_max(self, deg_s: float) -> None:
        """SETRV (the argument's magnitude; 0 is ignored); both directions."""
        if deg_s:
            self.rot_vel_max = self.rot_vel_max_pos = self.rot_vel_max_neg = abs(float(deg_s))

    def set_rot_max_dir(self, deg_s: float) -> None:
        """SETRVDIR: > 0 caps counter-clockwise rates, < 0 clockwise ones (by its magnitude)."""
        if deg_s > 0:
            self.rot_vel_max_pos = float(deg_s)
        elif deg_s < 0:
            self.rot_vel_max_neg = -float(deg_s)

    def set_trans_accel(self, value: float) -> None:
        """SETA: > 0 sets the acceleration, < 0 the deceleration (by its magnitude); 0 is ignored."""
        if value > 0:
            self.trans_accel = float(value)
        elif value < 0:
            self.trans_decel = -float(value)

    def set_rot_accel(self, value: float) -> None:
        """SETRA: as `set_trans_accel` for rotation."""
        if value > 0:
            self.rot_accel = float(value)
        elif value < 0:
            self.rot_decel = -float(value)

    # -- control ---------------------------------------------------------------------------
    def targets(self, heading_now: float, dt: float) -> tuple[float, float]:
        """The speeds each axis aims at this cycle before ramping: ([mm/s], [deg/s]).

        Args:
            heading_now: [deg] odometry heading.
            dt: [s] control cycle.
        """
        if self.trans_mode is TransMode.VEL:
            v = max(-self.trans_vel_max, min(self.trans_vel_max, self.vel))
        else:
            left = self.move_left
            v = math.copysign(min(self.trans_vel_max, stopping_speed(abs(left), self.trans_decel, dt),
                                  abs(left) / dt), left) if abs(left) > MOVE_DONE_MM else 0.0
        if self.rot_mode is RotMode.VEL:
            w = self.rot_vel
        else:
            err = _wrap_deg(self.heading_goal - heading_now)
            w = math.copysign(min(self.rot_vel_max, stopping_speed(abs(err), self.rot_decel, dt), abs(err) / dt),
                              err) if abs(err) > HEAD_DONE_DEG else 0.0
        w = max(-self.rot_vel_max_neg, min(self.rot_vel_max_pos, w))
        return v, w

    def step(self, v_now: float, w_now: float, heading_now: float, dt: float) -> tuple[float, float]:
        """The speeds to drive this cycle: the targets ramped from the current speeds.

        Args:
            v_now: [mm/s] current translational speed.
            w_now: [deg/s] current rotational speed.
            heading_now: [deg] odometry heading.
            dt: [s] control cycle.

        Returns:
            ([mm/s], [deg/s]).
        """
        v_goal, w_goal = self.targets(heading_now, dt)
        return (approach(v_now, v_goal, self.trans_accel, self.trans_decel, dt),
                approach(w_now, w_goal, self.rot_accel, self.rot_decel, dt))

    def ramp_rates(self, v_now: float, w_now: float, v_goal: float, w_goal: float) -> tuple[float, float]:
        """The acceleration each axis ramps with this cycle: SETA's / SETRA's acceleration when
        speeding up, deceleration otherwise ([mm/s^2], [deg/s^2])."""
        return (self.trans_accel if speeding_up(v_now, v_goal) else self.trans_decel,
                self.rot_accel if speeding_up(w_now, w_goal) else self.rot_decel)

    def travelled(self, mm: float) -> None:
        """Account for `mm` of signed travel (odometry, forward > 0) during the last cycle."""
        if self.trans_mode is TransMode.MOVE:
            before = self.move_left
            self.move_left -= mm
            if abs(self.move_left) <= MOVE_DONE_MM or (before > 0) != (self.move_left > 0):
                self.move_left = 0.0        # done (or overshot): stop and hold, as ARCOS
