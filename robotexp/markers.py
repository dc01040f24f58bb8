"""Explorer markers: what an explorer wants drawn over the map (`Explorer.markers()`), in world
coordinates [m] of the map frame.

A markers value is a dict of kinds, each a dict of names (shown in the view's legend and as the
marker namespace in recordings) to flat lists of numbers:

    "points":   {name: [x0, y0, x1, y1, ...]}             dots (tree nodes, a target)
    "circles":  {name: [x0, y0, r0, x1, y1, r1, ...]}     circles of radius r [m]
    "lines":    {name: [ax0, ay0, bx0, by0, ...]}         segments a -> b (tree edges)
    "polygons": {name: [[x0, y0, x1, y1, ...], ...]}      closed outlines (safe regions), each >= 3 points

Every number is a finite float (or int). Kinds left out draw nothing; `{}` (the default) draws
nothing at all. The live view draws them (`robotexp.view`), a recording holds them as
visualization_msgs/MarkerArray (`robotexp.bag.markers`), a replay gives them back to the view.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["Markers", "MARKER_KINDS", "markers_problem"]

Markers = dict[str, dict[str, Any]]

MARKER_KINDS = {"points": 2, "circles": 3, "lines": 4, "polygons": 2}   # numbers per item (per vertex: polygons)


def _flat_problem(values: object, per: int, what: str) -> str | None:
    if not isinstance(values, list | tuple):
        return f"{what} must be a list of numbers, got {type(values).__name__}"
    if len(values) % per:
        return f"{what} holds {len(values)} numbers, not a multiple of {per}"
    for v in values:
        if isinstance(v, bool) or not isinstance(v, float | int) or not math.isfinite(v):
            return f"{what} holds {v!r}; only finite numbers [m]"
    return None


def markers_problem(value: object) -> str | None:
    """What is wrong with `value` as the return of `Explorer.markers()` (None: nothing)."""
    if not isinstance(value, dict):
        return f"markers() must return a dict, got {type(value).__name__}"
    for kind, named in value.items():
        if kind not in MARKER_KINDS:
            return f"markers() kind {kind!r} is none of {', '.join(MARKER_KINDS)}"
        if not isinstance(named, dict):
            return f"markers()[{kind!r}] must be a dict of name -> list, got {type(named).__name__}"
        for name, values in named.items():
            if not isinstance(name, str) or not name:
                return f"markers()[{kind!r}] has the name {name!r}; names are non-empty strings"
            what = f"markers()[{kind!r}][{name!r}]"
            if kind == "polygons":
                if not isinstance(values, list | tuple):
                    return f"{what} must be a list of outlines, got {type(values).__name__}"
                for i, outline in enumerate(values):
                    problem = _flat_problem(outline, 2, f"{what}[{i}]")
                    if problem is None and len(outline) < 6:
                        problem = f"{what}[{i}] has {len(outline) // 2} points; an outline needs 3 or more"
                    if problem is not None:
                        return problem
            else:
                problem = _flat_problem(values, MARKER_KINDS[kind], what)
                if problem is not None:
                    return problem
    return None
