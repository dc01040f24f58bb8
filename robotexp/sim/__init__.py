"""The embedded simulator: a pybullet world and the `SimRobot` backend (imports pybullet)."""

from robotexp.sim.presets import PRESETS, LaserConfig, OdometryError, RobotPreset, SonarConfig, preset
from robotexp.sim.robot import SimRobot, mounted_source

__all__ = ["SimRobot", "mounted_source", "LaserConfig", "SonarConfig", "OdometryError", "RobotPreset", "PRESETS",
           "preset"]
