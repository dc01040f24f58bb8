"""MAVLink ground rovers (ArduPilot Rover, GUIDED mode): codec on pymavlink, links, `MavlinkRobot`
(entry point ``mavlink``) and `MavlinkEmulator` (``robotexp emulate mavlink``).

The emulator is imported lazily: it needs the simulator (pybullet).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .robot import ROVER_LIMITS, MavlinkRobot

if TYPE_CHECKING:
    from .emulator import MavlinkEmulator

__all__ = ["MavlinkRobot", "MavlinkEmulator", "ROVER_LIMITS"]


def __getattr__(name: str) -> Any:
    if name == "MavlinkEmulator":
        from .emulator import MavlinkEmulator
        return MavlinkEmulator
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
