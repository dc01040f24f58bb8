"""robotexp: mobile-robot exploration experiments, the same on a simulator and on real robots.

Importing this package is cheap: the names below are imported on first use (PEP 562), and pybullet,
numba, lupa and pymavlink load only in the modules that need them. What plugin and script authors
need is here (docs/architecture.md, "Public API", names the public subpackages beside it):

- explorers: `Explorer`, `ExplorerContext`, `Done`, `Twist`, `RobotState`, `LaserScan`, `SonarScan`,
  `Pose`, `Limits`, `OccupancyGrid`, `GridGeometry`, `wrap_angle`, `compose_pose`, `relative_pose`, and
  `check_explorer` for a plugin's own tests;
- coordinators of a team: `Coordinator`, `Candidates`, `TeamContext`, and `check_coordinator`;
- robot backends and laser drivers: `Robot`, `Capability`, `RobotEmulator`, `Clock`, `PacedClock`, `Laser`,
  `LaserGeometry`, `StampedScan`, `ScanSource`, `PoseHistory`, `scan_in_robot_frame`;
- runs: `RunSpec`, `run_experiment`, `run_on_robot`, `RunOutput`, `ExplorationRun`, `RunInfo`,
  `RunObserver`, `StepEvent`, `RunRecord`, `EndReason`, `load_world`, `World`;
- errors: `RobotexpError`, `RobotError`, `ConnectionLost`, `ProtocolError`, `WorldError`,
  `ScriptError`, `PluginError`, `ConfigError`.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

# public name -> the module that defines it
_EXPORTS = {
    "Explorer": "robotexp.explorer", "ExplorerContext": "robotexp.explorer", "Done": "robotexp.explorer",
    "ExplorationRun": "robotexp.run.loop", "RunInfo": "robotexp.run.loop",
    "Twist": "robotexp.robot", "Pose": "robotexp.robot", "RobotState": "robotexp.robot",
    "LaserScan": "robotexp.robot", "SonarScan": "robotexp.robot", "Limits": "robotexp.robot",
    "Footprint": "robotexp.robot", "Robot": "robotexp.robot", "Capability": "robotexp.robot",
    "RobotEmulator": "robotexp.robot",
    "wrap_angle": "robotexp.robot", "compose_pose": "robotexp.robot", "relative_pose": "robotexp.robot",
    "Clock": "robotexp.clock", "PacedClock": "robotexp.clock",
    "Laser": "robotexp.laser", "LaserGeometry": "robotexp.laser", "StampedScan": "robotexp.laser",
    "ScanSource": "robotexp.laser", "PoseHistory": "robotexp.laser", "scan_in_robot_frame": "robotexp.laser",
    "OccupancyGrid": "robotexp.mapping.grid", "GridGeometry": "robotexp.mapping.geometry",
    "RunSpec": "robotexp.run.spec", "RunOutput": "robotexp.experiment",
    "run_experiment": "robotexp.experiment", "run_on_robot": "robotexp.experiment",
    "RunObserver": "robotexp.run.observers", "StepEvent": "robotexp.run.observers",
    "RunRecord": "robotexp.run.record", "EndReason": "robotexp.run.record",
    "load_world": "robotexp.world.loader", "World": "robotexp.world.model",
    "RobotexpError": "robotexp.errors", "RobotError": "robotexp.errors", "ConnectionLost": "robotexp.errors",
    "ProtocolError": "robotexp.errors", "WorldError": "robotexp.errors", "ScriptError": "robotexp.errors",
    "PluginError": "robotexp.errors", "ConfigError": "robotexp.errors",
    "check_explorer": "robotexp.testing.explorer_contract",
    "Coordinator": "robotexp.coordinator", "Candidates": "robotexp.coordinator", "TeamContext": "robotexp.coordinator",
    "check_coordinator": "robotexp.testing.coordinator_contract",
}

__all__ = [
    "__version__",
    "Explorer", "ExplorerContext", "Done", "ExplorationRun", "RunInfo",
    "Twist", "Pose", "RobotState", "LaserScan", "SonarScan", "Limits", "Footprint", "Robot", "Capability",
    "RobotEmulator", "wrap_angle", "compose_pose", "relative_pose", "Clock", "PacedClock",
    "Laser", "LaserGeometry", "StampedScan", "ScanSource", "PoseHistory", "scan_in_robot_frame",
    "OccupancyGrid", "GridGeometry",
    "RunSpec", "RunOutput", "run_experiment", "run_on_robot", "RunObserver", "StepEvent", "RunRecord", "EndReason",
    "load_world", "World",
    "RobotexpError", "RobotError", "ConnectionLost", "ProtocolError", "WorldError", "ScriptError", "PluginError",
    "ConfigError", "check_explorer", "Coordinator", "Candidates", "TeamContext", "check_coordinator",
]

if TYPE_CHECKING:
    from robotexp.errors import (ConfigError, ConnectionLost, PluginError, ProtocolError, RobotError, RobotexpError,
                                 ScriptError, WorldError)
    from robotexp.experiment import RunOutput, run_experiment, run_on_robot
    from robotexp.run.spec import RunSpec
    from robotexp.coordinator import Candidates, Coordinator, TeamContext
    from robotexp.explorer import Done, Explorer, ExplorerContext
    from robotexp.testing.coordinator_contract import check_coordinator
    from robotexp.run.loop import ExplorationRun, RunInfo
    from robotexp.testing.explorer_contract import check_explorer
    from robotexp.clock import Clock, PacedClock
    from robotexp.laser import Laser, LaserGeometry, PoseHistory, ScanSource, StampedScan, scan_in_robot_frame
    from robotexp.mapping.geometry import GridGeometry
    from robotexp.mapping.grid import OccupancyGrid
    from robotexp.run.observers import RunObserver, StepEvent
    from robotexp.run.record import EndReason, RunRecord
    from robotexp.robot import (Capability, Footprint, LaserScan, Limits, Pose, Robot, RobotEmulator, RobotState,
                                SonarScan, Twist,
                                compose_pose, relative_pose, wrap_angle)
    from robotexp.world.loader import load_world
    from robotexp.world.model import World


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'robotexp' has no attribute {name!r}")
    value = getattr(import_module(module), name)
    globals()[name] = value             # imported once
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])
