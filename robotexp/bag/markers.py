"""Explorer markers (`robotexp.markers`) as a visualization_msgs/MarkerArray, and back.

A MarkerArray message starts with a DELETEALL marker (a viewer such as Foxglove drops the previous
message's markers: a tree that grew, a target that moved), then one marker per name and kind, in
frame `map`, namespace "KIND/NAME" (what a replay reads the kind and name back from):

    points    SPHERE_LIST, 0.2 m spheres at z = 0, one marker per name
    lines     LINE_LIST, 0.04 m wide, the segments' end points in order
    polygons  LINE_STRIP per outline, 0.03 m wide, closed (its first point repeated at the end)
    circles   CYLINDER per circle, 0.02 m high, diameter 2 r at the circle's centre

Coordinates are float64 as the markers had them, so a replay gets the same numbers back.
"""

from __future__ import annotations

import struct
from typing import Any

from robotexp.bag.cdr import Cdr
from robotexp.markers import Markers

__all__ = ["marker_array", "markers_of", "COLOURS"]

SPHERE_LIST, LINE_LIST, LINE_STRIP, CYLINDER = 7, 5, 4, 3
ADD, DELETEALL = 0, 3
POINT_SIZE = 0.2        # [m]
LINE_WIDTH = 0.04       # [m]
OUTLINE_WIDTH = 0.03    # [m]
DISC_HEIGHT = 0.02      # [m]

# r, g, b, a as the live view draws them (nodes green, targets magenta, regions translucent green)
COLOURS = {"node": (0.04, 0.54, 0.35, 1.0), "target": (0.69, 0.0, 0.69, 1.0), "lines": (0.04, 0.54, 0.35, 1.0),
           "polygons": (0.04, 0.54, 0.35, 0.6), "circles": (0.04, 0.54, 0.35, 0.3)}


def _colour(kind: str, name: str) -> tuple[float, float, float, float]:
    if kind == "points":
        return COLOURS["node"] if "node" in name.lower() else COLOURS["target"]
    return COLOURS[kind]


def _marker(c: Cdr, ns: int, space: str, ident: int, kind: int, action: int, pose: tuple[float, float],
            scale: tuple[float, float, float], colour: tuple[float, float, float, float],
            points: list[float] | None) -> None:
    """One visualization_msgs/Marker: planar `points` (x, y, ...) at z = 0."""
    c.header(ns, "map")
    c.string(space)
    c.i32(ident)
    c.i32(kind)
    c.i32(action)
    c.f64s(pose[0], pose[1], 0.0, 0.0, 0.0, 0.0, 1.0)     # Pose: position, identity orientation
    c.f64s(*scale)
    c.f32s(*colour)
    c.i32(0)                                             # lifetime 0: forever (until the next DELETEALL)
    c.u32(0)
    c.buf += b"\x00"                                     # frame_locked false
    xy = points or []
    c.u32(len(xy) // 2)
    if xy:
        c._align(8)
        c.buf += b"".join(struct.pack("<3d", xy[i], xy[i + 1], 0.0) for i in range(0, len(xy), 2))
    c.u32(0)                                             # colors: none (one colour per marker)
    c.string("")                                         # texture_resource
    c.header(0, "")                                      # texture: an empty CompressedImage
    c.string("")
    c.u32(0)
    c.u32(0)                                             # uv_coordinates
    c.string("")                                         # text
    c.string("")                                         # mesh_resource
    c.string("")                                         # mesh_file: filename, data
    c.u32(0)
    c.buf += b"\x00"                                     # mesh_use_embedded_materials false


def marker_array(ns: int, markers: Markers) -> bytes:
    """The CDR bytes of a visualization_msgs/MarkerArray of `markers` (checked: `markers_problem` is None)
    stamped `ns` [ns]."""
    items: list[tuple[str, int, int, tuple[float, float], tuple[float, float, float], Any, list[float] | None]] = []
    for kind, named in markers.items():
        for name, values in named.items():
            space = f"{kind}/{name}"
            colour = _colour(kind, name)
            if kind == "points" and values:
                items.append((space, SPHERE_LIST, 0, (0.0, 0.0), (POINT_SIZE,) * 3, colour, list(values)))
            elif kind == "lines" and values:
                items.append((space, LINE_LIST, 0, (0.0, 0.0), (LINE_WIDTH, 0.0, 0.0), colour, list(values)))
            elif kind == "polygons":
                for i, outline in enumerate(values):
                    closed = list(outline) + list(outline[:2])
                    items.append((space, LINE_STRIP, i, (0.0, 0.0), (OUTLINE_WIDTH, 0.0, 0.0), colour, closed))
            elif kind == "circles":
                for i in range(0, len(values), 3):
                    x, y, r = values[i:i + 3]
                    items.append((space, CYLINDER, i // 3, (x, y), (2 * r, 2 * r, DISC_HEIGHT), colour, None))
    c = Cdr()
    c.u32(len(items) + 1)
    _marker(c, ns, "", 0, 0, DELETEALL, (0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), None)
    for space, shape, ident, pose, scale, colour, points in items:
        _marker(c, ns, space, ident, shape, ADD, pose, scale, colour, points)
    return c.data()


def markers_of(msg: Any) -> Markers:
    """The markers of a decoded MarkerArray written by `marker_array` (markers of other namespaces and
    types, as another tool writes them, are left out)."""
    out: Markers = {}
    for m in msg.markers:
        kind, _, name = str(m.ns).partition("/")
        if m.action != ADD or not name:
            continue
        xy = [float(v) for p in m.points for v in (p.x, p.y)]
        if kind == "points" and m.type == SPHERE_LIST:
            out.setdefault(kind, {})[name] = xy
        elif kind == "lines" and m.type == LINE_LIST:
            out.setdefault(kind, {})[name] = xy
        elif kind == "polygons" and m.type == LINE_STRIP and len(xy) >= 8:
            out.setdefault(kind, {}).setdefault(name, []).append(xy[:-2])
        elif kind == "circles" and m.type == CYLINDER:
            out.setdefault(kind, {}).setdefault(name, []).extend(
                [float(m.pose.position.x), float(m.pose.position.y), float(m.scale.x) / 2])
    return out
