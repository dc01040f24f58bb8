"""The Yujin Kobuki driver: codec, link, `KobukiRobot` backend (entry point ``kobuki``) and emulator.

The emulator (`robotexp_drivers.kobuki.emulator`) imports the simulator, so it is not imported here.
"""

from robotexp_drivers.kobuki.link import KobukiLink
from robotexp_drivers.kobuki.robot import KOBUKI_LIMITS, KobukiRobot, LaserSource

__all__ = ["KobukiRobot", "KobukiLink", "LaserSource", "KOBUKI_LIMITS"]
