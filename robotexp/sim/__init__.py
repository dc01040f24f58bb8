"""The embedded simulator: a pybullet world and the `SimRobot` backend (imports pybullet)."""

from robotexp.sim.presets import (
    ODOMETRY_PRESETS,
    PRESETS,
    LaserConfig,
    OdometryError,
    RobotPreset,
    SonarConfig,
    odometry_error,
    preset,
)
from robotexp.sim.robot import SimRobot, mounted_source
from robotexp.sim.team import SharedWorld, SimTeam, spread_starts

__all__ = ["SimRobot", "mounted_source", "LaserConfig", "SonarConfig", "OdometryError", "RobotPreset", "PRESETS",
           "preset", "ODOMETRY_PRESETS", "odometry_error",
           "SimTeam", "SharedWorld", "spread_starts"]
