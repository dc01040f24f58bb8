"""Entry-point discovery and construction of explorers (`robotexp.explorers`), robot backends
(`robotexp.robots`) and their emulators (`robotexp.emulators`).

Listing reads distribution metadata only; a target is imported when its name is chosen, then
checked to subclass the right ABC. A third-party plugin is exactly as first-class as a built-in:
nothing here knows a plugin by name; what differs between backends is declared on their classes
(`Robot.by_address`, `RobotEmulator.radius` and `.options`).
"""

from __future__ import annotations

import difflib
import math
import os
import re
import sys
import types
import typing
from dataclasses import dataclass
from importlib import import_module
from importlib.metadata import distributions
from typing import TYPE_CHECKING, Any

from robotexp.errors import ConfigError, PluginError

if TYPE_CHECKING:
    from robotexp.coordinator import Coordinator
    from robotexp.explorer import Explorer
    from robotexp.robot import Pose, Robot, RobotEmulator
    from robotexp.world.model import World

__all__ = ["PluginInfo", "ROBOTS", "EXPLORERS", "EMULATORS", "available", "load", "lua_name",
           "make_explorer", "make_coordinator", "connect_robot", "make_emulator", "COORDINATORS"]

ROBOTS = "robotexp.robots"
EXPLORERS = "robotexp.explorers"
COORDINATORS = "robotexp.coordinators"   # `robotexp.coordinator.Coordinator` subclasses (teams)
EMULATORS = "robotexp.emulators"     # robot backend name -> its emulator class (`robotexp.robot.RobotEmulator`)
_NAME = re.compile(r"^[a-z0-9][a-z0-9-]*$")


@dataclass(frozen=True)
class PluginInfo:
    """One entry point: its name, `module:attr` target and source distribution."""

    name: str
    target: str
    distribution: str
    version: str


_SCANS: dict[tuple[tuple[str, int], ...], dict[str, dict[str, PluginInfo] | PluginError]] = {}


def available(group: str) -> dict[str, PluginInfo]:
    """Every entry point of `group`, by name, sorted. Raises PluginError on a name in two
    distributions or a malformed name.

    One scan (0.5 s: every installed distribution's metadata is parsed) finds the entry points of every
    robotexp group; it is kept while sys.path and the modification times of its folders are unchanged (an
    install adds a folder to one of them), so a campaign worker making runs one after another scans once,
    and a run that asks for a second group later opens no file then (a live view's clients may hold all the
    process may open)."""
    key = tuple((entry, _mtime_ns(entry)) for entry in sys.path)
    groups = _SCANS.get(key)
    if groups is None:
        if len(_SCANS) > 16:
            _SCANS.clear()
        groups = _SCANS[key] = _scan()
    found = groups.get(group, {})
    if isinstance(found, PluginError):
        raise PluginError(str(found))
    return dict(found)


def _mtime_ns(entry: str) -> int:
    try:
        return os.stat(entry or ".").st_mtime_ns
    except OSError:
        return -1


def _scan() -> dict[str, dict[str, PluginInfo] | PluginError]:
    """`available` of every robotexp group without the cache: by group, its entry points or the error a
    lookup of the group raises."""
    found: dict[str, dict[str, PluginInfo]] = {}
    errors: dict[str, PluginError] = {}
    seen_dists: set[str] = set()
    for dist in distributions():
        dist_name = dist.metadata["Name"] or "?"
        key = f"{dist_name}@{dist.version}"
        if key in seen_dists:        # the same distribution seen twice on sys.path
            continue
        seen_dists.add(key)
        for ep in dist.entry_points:
            group = ep.group
            if not group.startswith("robotexp.") or group in errors:
                continue
            if not _NAME.match(ep.name):
                errors[group] = PluginError(f"{group}: plugin name {ep.name!r} of {dist_name} is not lowercase "
                                            "letters, digits and '-'")
                continue
            info = PluginInfo(ep.name, ep.value, dist_name, dist.version)
            other = found.setdefault(group, {}).get(ep.name)
            if other is not None and other.distribution != dist_name:
                errors[group] = PluginError(f"{group}: the name {ep.name!r} is claimed by both {other.distribution} "
                                            f"and {dist_name}: uninstall one of them")
                continue
            found[group][ep.name] = info
    groups: dict[str, dict[str, PluginInfo] | PluginError] = {g: dict(sorted(v.items())) for g, v in found.items()}
    groups.update(errors)
    return groups


def load(group: str, name: str, base: type) -> type:
    """Import the class registered as `name` in `group` and check it subclasses `base`.

    Raises:
        PluginError: unknown name (lists the available ones and the closest), failed import,
            or a target that is not a subclass of `base`.
    """
    plugins = available(group)
    info = plugins.get(name)
    if info is None:
        kind = {EXPLORERS: "method", EMULATORS: "emulator", COORDINATORS: "coordinator"}.get(group, "robot backend")
        close = difflib.get_close_matches(name, list(plugins), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise PluginError(f"unknown {kind} {name!r}{hint}; available: {', '.join(plugins) or 'none'}. "
                          "After installing a plugin run `pip install -e .` again if it is missing")
    module_name, _, attr = info.target.partition(":")
    try:
        obj: object = import_module(module_name)
        for part in attr.split(".") if attr else []:
            obj = getattr(obj, part)
    except Exception as exc:
        raise PluginError(f"plugin {name!r} of {info.distribution} ({info.target}) failed to import: "
                          f"{type(exc).__name__}: {exc}") from exc
    if not (isinstance(obj, type) and issubclass(obj, base)):
        raise PluginError(f"plugin {name!r} of {info.distribution} ({info.target}) is not a subclass of "
                          f"{base.__module__}.{base.__name__}")
    return obj


def lua_name(name: str) -> str:
    """IfTEA's spelling of a plugin name in Lua: `srt-laser` -> `SRT_LASER`."""
    return name.upper().replace("-", "_")


# -- construction ---------------------------------------------------------------------------------

def make_explorer(method: str, params: dict[str, Any]) -> Explorer:
    """Instantiate the explorer plugin `method` with keyword `params` (each checked against its
    annotation, see `_typed_parameter`).

    Raises:
        PluginError: unknown method.
        ConfigError: an unknown or invalid parameter.
    """
    from robotexp.explorer import Explorer

    return _make(load(EXPLORERS, method, Explorer), method, params)


def make_coordinator(name: str, params: dict[str, Any]) -> Coordinator:
    """Instantiate the coordinator plugin `name` (`robotexp.coordinators`) with keyword `params`, checked
    as an explorer's are.

    Raises:
        PluginError: unknown coordinator.
        ConfigError: an unknown or invalid parameter.
    """
    from robotexp.coordinator import Coordinator

    return _make(load(COORDINATORS, name, Coordinator), name, params, "coordinator")


def _make(cls: type, method: str, params: dict[str, Any], kind: str = "method") -> Any:
    """`cls(**params)`, every parameter checked against its annotation and declared bounds (errors name the
    plugin as `kind` NAME: a method, a coordinator)."""
    accepted = _parameter_names(cls)
    unknown = [key for key in params if accepted is not None and key not in accepted]
    if unknown:
        listing = ", ".join(accepted) if accepted else "none"
        raise ConfigError(f"{kind} {method!r}: unknown parameter(s) {', '.join(unknown)}; its parameters: {listing}")
    params = {key: _typed_parameter(method, cls, key, value, kind) for key, value in params.items()}
    bounds = parameter_bounds(cls)
    for key, value in params.items():
        if key in bounds:
            check_bounds(method, key, value, bounds[key], kind)
    try:
        return cls(**params)
    except TypeError as exc:
        raise ConfigError(f"{kind} {method!r}: {exc} (parameters given: {', '.join(params) or 'none'})") from exc


_KINDS = {bool: "true or false", int: "a whole number", float: "a number", str: "a string"}


def parameter_bounds(cls: type) -> dict[str, tuple[float | None, float | None]]:
    """The declared range of each numeric parameter of explorer class `cls` (its `parameter_bounds`
    and its bases', a subclass's entries winning)."""
    out: dict[str, tuple[float | None, float | None]] = {}
    for klass in reversed(cls.__mro__):
        out.update(vars(klass).get("parameter_bounds", {}))
    return out


def _number(x: float) -> str:
    """A bound or a value as written: whole numbers in full (100000, not 1e+05)."""
    if isinstance(x, int) or (math.isfinite(x) and float(x).is_integer() and abs(x) < 1e15):
        return str(int(x))
    return f"{x:g}"


def bounds_text(bounds: tuple[float | None, float | None]) -> str:
    """A range as `-p help` shows it: "1..100000", ">= 0", "<= 10"."""
    lo, hi = bounds
    if lo is not None and hi is not None:
        return f"{_number(lo)}..{_number(hi)}"
    return f">= {_number(lo)}" if lo is not None else f"<= {_number(hi)}" if hi is not None else ""


def check_bounds(method: str, key: str, value: Any, bounds: tuple[float | None, float | None],
                 kind: str = "method") -> None:
    """Refuse a numeric `value` of parameter `key` outside its declared (inclusive) `bounds`; a value
    that is not a number (None, a boolean, a string, a list) is left to the parameter's type check.

    Raises:
        ConfigError: out of range, or not a number (NaN).
    """
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return
    lo, hi = bounds
    if hi is not None and value > hi:
        raise ConfigError(f"{kind} {method!r}: parameter {key!r} must be <= {_number(hi)}, got {_number(value)}")
    if lo is not None and value < lo:
        raise ConfigError(f"{kind} {method!r}: parameter {key!r} must be >= {_number(lo)}, got {_number(value)}")
    if value != value:
        raise ConfigError(f"{kind} {method!r}: parameter {key!r} must be a number in {bounds_text(bounds)}, "
                          f"got {value}")


def _parameter_names(cls: type) -> list[str] | None:
    """The keyword parameters of `cls` by name (None: it takes **kwargs, or has no signature to read)."""
    import inspect

    try:
        sig = inspect.signature(cls)
    except (TypeError, ValueError):
        return None
    names = []
    for p in sig.parameters.values():
        if p.kind is inspect.Parameter.VAR_KEYWORD:
            return None
        if p.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY):
            names.append(p.name)
    return names


def _typed_parameter(method: str, cls: type, key: str, value: Any, what: str = "method") -> Any:
    """`value` for the keyword `key` of `cls`, checked against its annotation (bool, int, float, str,
    or one of these or None); a whole float for an int and an int for a float are converted.
    Parameters without such an annotation pass unchecked. Raises ConfigError."""
    try:
        hint = typing.get_type_hints(cls.__init__).get(key)   # type: ignore[misc]
    except Exception:       # an annotation that does not resolve: leave the value to the plugin
        return value
    allowed = typing.get_args(hint) if typing.get_origin(hint) in (typing.Union, types.UnionType) else (hint,)
    if value is None and type(None) in allowed:
        return None
    kinds = [t for t in allowed if t in _KINDS]
    if not kinds or len(kinds) < len([t for t in allowed if t is not type(None)]):
        return value
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    for kind in kinds:
        if kind is bool and isinstance(value, bool) or kind is str and isinstance(value, str):
            return value
        if kind is int and number and float(value).is_integer():
            return int(value)
        if kind is float and number:
            return float(value)
    raise ConfigError(f"{what} {method!r}: parameter {key!r} must be {' or '.join(_KINDS[k] for k in kinds)}, "
                      f"got {value!r}")


def connect_robot(backend: str, address: str, **options: Any) -> Robot:
    """Connect the robot backend registered as `backend` (`robotexp.robots`) at `address`, with the
    backend's keyword `options` (e.g. `robotexp.run.laser_mount.robot_options`).

    Raises:
        PluginError: unknown backend.
        ConfigError: a backend that is not reached at an address (`Robot.by_address` false: the
            embedded simulator).
        RobotError: the robot cannot be reached or the handshake fails.
    """
    from robotexp.robot import Robot

    cls = load(ROBOTS, backend, Robot)
    if not getattr(cls, "by_address", True):
        raise ConfigError(f"robot {backend!r} has no address ({cls.__qualname__} runs in this process, "
                          "e.g. the embedded simulator); run without --address")
    return cls(address, **options)


def make_emulator(backend: str, world: str | World, *, pose: str | Pose | None = None, port: int | None = None,
                  pty: bool = False, speedup: float = 1.0, **options: Any) -> RobotEmulator:
    """The emulator of robot `backend` (entry-point group `robotexp.emulators`) serving `world` (a name, a
    map path or a loaded world) from `pose` (a name, x,y,theta in mm, mm, deg, or a `Pose`).

    The emulator is not started: call its `start()` (and `close()`); `address` tells where it is.
    `options` (given, not None) must be named in the emulator class's `options` (mavlink: `udp`,
    "HOST:PORT" of a ground station to send to instead of listening).

    Raises:
        PluginError: no emulator for `backend`, or an emulator class that does not declare `radius`.
        WorldError: unknown world or a start pose in an obstacle.
        ConfigError: a parameter out of range, or an option the emulator does not take.
    """
    from robotexp.robot import Pose
    from robotexp.world.loader import load_world
    from robotexp.world.poses import resolve_pose

    if not (speedup > 0 and math.isfinite(speedup)):
        raise ConfigError(f"speedup must be > 0, got {speedup}")
    cls = load(EMULATORS, backend, object)
    radius = getattr(cls, "radius", None)
    if not isinstance(radius, (int, float)):
        raise PluginError(f"emulator {backend!r} ({cls.__module__}.{cls.__qualname__}) declares no `radius` "
                          "(see robotexp.robot.RobotEmulator)")
    accepted: frozenset[str] = getattr(cls, "options", frozenset())
    given = {key: value for key, value in options.items() if value is not None}
    for key in given:
        if key not in accepted:
            flag = "--odometry-error" if key == "odometry" else f"--{key.replace('_', '-')}"
            raise ConfigError(f"{flag} is not an option of the {backend!r} emulator "
                              f"(its options: {', '.join(sorted(accepted)) or 'none'})")
    w = load_world(world) if isinstance(world, str) else world
    start = pose if isinstance(pose, Pose) else resolve_pose(w, pose, float(radius))[0]
    kwargs: dict[str, Any] = {"pose": start, "pty": pty, "speedup": speedup, **given}
    if port is not None:
        kwargs["port"] = port
    return cls(w, **kwargs)
