"""The `team` table of the Lua API (`TeamCalls`, `Session.team`): a script explores with a team of
simulated robots.

`team.setRobots`, `team.setCoordinator` (with `team.setCoordinatorParameter`) and `team.setCommRange` set the
team; `team.explore()` runs one team exploration at once with the exploration settings of the other tables
(method and its parameters, world, start, seed, time limit, speed, laser range and noise, cell size, map
limits, record and frame folders) and returns its record as a table (the keys of docs/reference/results.md, with
`team_size` and the list `robots`). `team.getPath(i)` and `team.getPose(i)` give robot i's path and
last pose of that run. The run is written to OUT/results.jsonl as every other run of the script, and
`exploration.results()`, `exploration.elapsedTime()`, `robot.pathLength()` and `mapView.saveMapImage`
then speak of it (the team's totals; the map image draws every robot).

The calls go through the same checks as the single-robot ones: the world is the one `exploration.setWorld`
checked (under `--sandbox`, a file inside the output folder), a team has 1..`MAX_TEAM` robots, the presets
and coordinator are installed names, and a team runs on the embedded simulator only.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from robotexp.errors import ScriptError
from robotexp.lua.sandbox import lua_kind, parameter_args

if TYPE_CHECKING:
    from robotexp.lua.api import Session
    from robotexp.run.loop import ExplorationRun
    from robotexp.run.team import TeamRun

__all__ = ["TeamCalls", "DEFAULT_TEAM"]

DEFAULT_TEAM = 2        # robots of the robot.setModel preset when the script names no team


class TeamCalls:
    """The `team` table's functions and settings, for the script of `session` (`Session.team`)."""

    def __init__(self, session: Session) -> None:
        self.session = session
        self.robots: int | tuple[str, ...] = DEFAULT_TEAM   # robots of the robot.setModel preset, or presets
        self.coordinator = "none"
        self.coordinator_params: dict[str, Any] = {}     # checked at team.explore()
        self.comm_range: float | None = None        # [m] (None: one shared map)
        self.last: TeamRun | None = None            # the last team run

    def lua_team__setRobots(self, *args: Any) -> None:
        """The team: a number of robots of the robot.setModel preset (2), or their presets "p3dx,p3dx,kobuki"."""
        from robotexp.sim import PRESETS
        from robotexp.sim.team import MAX_TEAM

        usage = "count_or_presets"
        if len(args) != 1:
            raise ScriptError(f"team.setRobots({usage}): expected 1 argument, got {len(args)}")
        (value,) = args
        if isinstance(value, int) and not isinstance(value, bool):
            if not 1 <= value <= MAX_TEAM:
                raise ScriptError(f"team.setRobots({value}): a team has 1..{MAX_TEAM} robots")
            self.robots = value
            return
        if not isinstance(value, str):
            raise ScriptError(f"team.setRobots({usage}): expected an integer 1..{MAX_TEAM} or a string of presets "
                              f"like \"p3dx,kobuki\", got {lua_kind(value)}")
        names = tuple(t.strip() for t in value.split(","))
        if not any(names):
            names = ()
        elif "" in names:
            raise ScriptError(f"team.setRobots({value!r}): robot {names.index('') + 1} is empty: give one preset per "
                              "robot, separated by single commas (\"p3dx,p3dx,kobuki\")")
        unknown = [n for n in names if n not in PRESETS]
        if not names or unknown:
            raise ScriptError(f"team.setRobots({value!r}): " + (f"unknown robot preset {unknown[0]!r}" if unknown else
                              "no preset given") + f"; available: {', '.join(PRESETS)}")
        if len(names) > MAX_TEAM:
            raise ScriptError(f"team.setRobots({value!r}): a team has 1..{MAX_TEAM} robots, got {len(names)}")
        self.robots = names

    def lua_team__setCoordinator(self, *args: Any) -> None:
        """The coordinator that shares out frontier targets: none, greedy, burgard, minpos (an installed plugin)."""
        from robotexp.registry import COORDINATORS, available

        usage = "name"
        if len(args) != 1 or not isinstance(args[0], str):
            got = "nothing" if not args else ", ".join(lua_kind(a) for a in args)
            raise ScriptError(f"team.setCoordinator({usage}): expected a coordinator name, got {got}")
        names = available(COORDINATORS)
        if args[0] not in names:
            raise ScriptError(f"team.setCoordinator({args[0]!r}): unknown coordinator; available: {', '.join(names)}")
        self.coordinator = args[0]

    def lua_team__setCoordinatorParameter(self, *args: Any) -> None:
        """A coordinator keyword parameter (SI units, as `--coordinator-param`); checked at team.explore()."""
        name, value = parameter_args("team.setCoordinatorParameter", args)
        self.coordinator_params[name] = value

    def lua_team__clearCoordinatorParameters(self, *args: Any) -> None:
        """Forget every parameter given with setCoordinatorParameter."""
        if args:
            raise ScriptError(f"team.clearCoordinatorParameters(): expected 0 arguments, got {len(args)}")
        self.coordinator_params = {}

    def lua_team__setCommRange(self, *args: Any) -> None:
        """Each robot keeps its own map and merges the scans of robots within this range [mm]; nil: one shared map."""
        usage = "range_mm"
        if len(args) == 1 and args[0] is None:
            self.comm_range = None
            return
        if len(args) != 1 or isinstance(args[0], bool) or not isinstance(args[0], (int, float)) \
                or not math.isfinite(args[0]) or not args[0] > 0:
            got = "nothing" if not args else ", ".join(lua_kind(a) for a in args)
            raise ScriptError(f"team.setCommRange({usage}): expected a range > 0 mm or nil, got {got}")
        self.comm_range = args[0] / 1000.0

    def lua_team__explore(self, *args: Any) -> dict[str, Any]:
        """Run a team exploration now with the exploration settings; returns its record (team_size, robots, ...)."""
        from robotexp.experiment import run_team
        from robotexp.run.team import TeamRun, TeamSpec

        usage = ""
        if args:
            raise ScriptError(f"team.explore({usage}): expected 0 arguments, got {len(args)}")
        session = self.session
        session.finish()
        if session.on_robot:
            raise ScriptError(f"team.explore: a team runs on the embedded simulator, and robot.setAddress named "
                              f"{session.address!r}; call robot.setAddress(\"sim\") first")
        spec = session._spec()
        robots = self.robots
        team = TeamSpec(robots=(spec.robot,) * robots if isinstance(robots, int) else robots,
                        coordinator=self.coordinator, comm_range=self.comm_range,
                        coordinator_params=dict(self.coordinator_params))
        team.validate()
        if self.coordinator_params:
            from robotexp.errors import ConfigError
            from robotexp.registry import make_coordinator

            try:
                make_coordinator(team.coordinator, team.coordinator_params)   # names, types, ranges: before the run
            except ConfigError as exc:
                raise ScriptError(f"team.explore: {exc} (team.setCoordinatorParameter)") from None
        session._next_frame = 0.0
        with session.control.running():
            output = run_team(spec, team, session.out, observers=session._observers(spec), image=False,
                              record_extra={"script": session.script})
        assert isinstance(output.run, TeamRun)
        session.last, self.last, session._moved = output, output.run, False
        session.records.append(output.record)
        state = output.run.members[0].state
        if state is not None:
            session.pose = state.true_pose or state.pose
        if session.control.check():
            raise ScriptError("exploration stopped")    # the runtime reports the real reason
        return output.record.as_dict()

    def _team_member(self, fname: str, args: tuple[Any, ...], usage: str) -> ExplorationRun:
        """The member of the last team run that `args` (one robot number, 1-based) names."""
        if len(args) != 1 or isinstance(args[0], bool) or not isinstance(args[0], int):
            got = "nothing" if not args else ", ".join(lua_kind(a) for a in args)
            raise ScriptError(f"{fname}({usage}): expected a robot number (an integer from 1), got {got}")
        if self.last is None:
            raise ScriptError(f"{fname}: no team exploration has run yet; call team.explore() first")
        members = self.last.members
        if not 1 <= args[0] <= len(members):
            raise ScriptError(f"{fname}({args[0]}): the last team had robots 1..{len(members)}")
        return members[args[0] - 1]

    def lua_team__getPath(self, *args: Any) -> list[list[float]]:
        """Robot i's path in the last team run: a list of {x, y} [mm], one point per control tick."""
        m = self._team_member("team.getPath", args, usage="robot")
        return [[round(x * 1000.0, 1), round(y * 1000.0, 1)] for x, y in m.metrics.path]

    def lua_team__getPose(self, *args: Any) -> tuple[float, float, float]:
        """Where robot i stood at the end of the last team run (x [mm], y [mm], theta [deg])."""
        m = self._team_member("team.getPose", args, usage="robot")
        s = m.state
        assert s is not None        # a member of a team that ran read its robot
        p = s.true_pose or s.pose
        return p.x * 1000.0, p.y * 1000.0, math.degrees(p.theta)
