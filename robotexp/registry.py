"""Entry-point discovery of robot backends (`robotexp.robots`) and explorers (`robotexp.explorers`).

Listing reads distribution metadata only; a target is imported when its name is chosen, then
checked to subclass the right ABC. A third-party plugin is exactly as first-class as a built-in.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from importlib import import_module
from importlib.metadata import distributions

from robotexp.errors import PluginError

__all__ = ["PluginInfo", "ROBOTS", "EXPLORERS", "available", "load", "lua_name"]

ROBOTS = "robotexp.robots"
EXPLORERS = "robotexp.explorers"
_NAME = re.compile(r"^[a-z0-9][a-z0-9-]*$")


@dataclass(frozen=True)
class PluginInfo:
    """One entry point: its name, `module:attr` target and source distribution."""

    name: str
    target: str
    distribution: str
    version: str


def available(group: str) -> dict[str, PluginInfo]:
    """Every entry point of `group`, by name, sorted. Raises PluginError on a name in two
    distributions or a malformed name."""
    found: dict[str, PluginInfo] = {}
    seen_dists: set[str] = set()
    for dist in distributions():
        dist_name = dist.metadata["Name"] or "?"
        key = f"{dist_name}@{dist.version}"
        if key in seen_dists:        # the same distribution seen twice on sys.path
            continue
        seen_dists.add(key)
        for ep in dist.entry_points:
            if ep.group != group:
                continue
            if not _NAME.match(ep.name):
                raise PluginError(f"{group}: plugin name {ep.name!r} of {dist_name} is not lowercase "
                                  "letters, digits and '-'")
            info = PluginInfo(ep.name, ep.value, dist_name, dist.version)
            other = found.get(ep.name)
            if other is not None and other.distribution != dist_name:
                raise PluginError(f"{group}: the name {ep.name!r} is claimed by both {other.distribution} "
                                  f"and {dist_name}: uninstall one of them")
            found[ep.name] = info
    return dict(sorted(found.items()))


def load(group: str, name: str, base: type) -> type:
    """Import the class registered as `name` in `group` and check it subclasses `base`.

    Raises:
        PluginError: unknown name (lists the available ones and the closest), failed import,
            or a target that is not a subclass of `base`.
    """
    plugins = available(group)
    info = plugins.get(name)
    if info is None:
        kind = "method" if group == EXPLORERS else "robot backend"
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
