"""Pioneer P3-DX driver: the ARIA robot protocol over a serial cable or TCP (MobileSim, port 8101).

`P3DXRobot` is the `p3dx` backend of `robotexp.robots`; `P3DXEmulator` serves the `sim` robot over
the same protocol (`robotexp emulate p3dx`). The emulator is imported lazily: it needs pybullet.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .robot import P3DXRobot

if TYPE_CHECKING:
    from .emulator import P3DXEmulator

__all__ = ["P3DXRobot", "P3DXEmulator"]


def __getattr__(name: str) -> Any:
    if name == "P3DXEmulator":
        from .emulator import P3DXEmulator
        return P3DXEmulator
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
