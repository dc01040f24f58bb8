"""The live view's data feed: what a run looks like, as a stream of frames, and the hub that keeps
the newest of it for every browser.

A producer (the run observer `robotexp.view.observer.ViewObserver`; a replay later) calls
`ViewHub.start(meta)` once per run, then `ViewHub.publish(frame)` as the run goes and
`ViewHub.finish(reason)` at its end. The hub merges frames into one current state: the newest pose,
laser and status, the path and coverage curve appended (points, never resent), the newest map and
overlays (each with a version number). A browser's connection asks `ViewHub.message_for(client)` for
what it has not seen yet: a slow or absent browser only ever gets the newest state, and never makes
the producer wait (the hub holds no queue per client, just what each client has already received).

Map encoding (`encode_classes`): a grid as uint8 classes (0 unknown, 1 free, 2 occupied, row 0 =
the southmost row), zlib-compressed and base64-encoded: the browser inflates it with its built-in
`DecompressionStream("deflate")`. A producer sends a map at a bounded rate (the observer: at most
`map_rate` per wall second, and only when it changed), so a large map never stalls the loop.
"""

from __future__ import annotations

import base64
import math
import threading
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["UNKNOWN", "FREE", "OCCUPIED", "Frame", "MapLayer", "ViewClient", "ViewHub", "classes_of_states",
           "encode_classes", "decode_classes", "laser_points", "vector_arrows"]

UNKNOWN, FREE, OCCUPIED = 0, 1, 2


def classes_of_states(states: npt.NDArray[np.int8]) -> npt.NDArray[np.uint8]:
    """Uint8 classes (UNKNOWN, FREE, OCCUPIED) of ROS-convention states (-1 unknown, 0 free, 100 occupied;
    anything in 1..99 counts as occupied from 50 up, else free)."""
    s = np.asarray(states)
    out = np.zeros(s.shape, np.uint8)
    out[(s >= 0) & (s < 50)] = FREE
    out[s >= 50] = OCCUPIED
    return out


def encode_classes(classes: npt.NDArray[np.uint8]) -> str:
    """Base64 text of the zlib-compressed (level 1) bytes of `classes` in row-major order."""
    return base64.b64encode(zlib.compress(np.ascontiguousarray(classes, np.uint8).tobytes(), 1)).decode("ascii")


def decode_classes(text: str, rows: int, cols: int) -> npt.NDArray[np.uint8]:
    """The inverse of `encode_classes` for a grid of `rows` x `cols`.

    Raises:
        ValueError: the text does not hold rows * cols bytes.
    """
    raw = zlib.decompress(base64.b64decode(text))
    if len(raw) != rows * cols:
        raise ValueError(f"map holds {len(raw)} bytes, expected {rows} x {cols}")
    return np.frombuffer(raw, np.uint8).reshape(rows, cols)


def laser_points(x: float, y: float, theta: float, angles: npt.NDArray[np.float64],
                 ranges: npt.NDArray[np.float64], offset_x: float = 0.0, max_points: int = 360) -> list[float]:
    """World points [m] of the finite beams of a scan taken at pose (x, y, theta), as a flat list
    x0, y0, x1, y1, ... rounded to mm, at most `max_points` (every k-th beam beyond that)."""
    ok = np.flatnonzero(np.isfinite(ranges))
    if len(ok) > max_points:
        ok = ok[:: math.ceil(len(ok) / max_points)]
    a = theta + angles[ok]
    sx, sy = x + offset_x * math.cos(theta), y + offset_x * math.sin(theta)
    pts = np.empty((len(ok), 2))
    pts[:, 0] = sx + ranges[ok] * np.cos(a)
    pts[:, 1] = sy + ranges[ok] * np.sin(a)
    return [float(v) for v in np.round(pts.ravel(), 3)]


def vector_arrows(vectors: npt.NDArray[np.float64], origin: tuple[float, float], cell: float,
                  max_arrows: int = 1500) -> tuple[float, list[float]]:
    """Arrows of a (rows, cols, 2) field on a lattice of at most about `max_arrows` cells: (spacing [m],
    flat list x, y, dx, dy, ... with (x, y) the cell centre [m] and (dx, dy) the unit direction;
    zero vectors are left out)."""
    rows, cols = vectors.shape[:2]
    step = max(1, math.ceil(math.sqrt(rows * cols / max_arrows)))
    r = np.arange(step // 2, rows, step)
    c = np.arange(step // 2, cols, step)
    v = vectors[np.ix_(r, c)]
    norm = np.hypot(v[..., 0], v[..., 1])
    rr, cc = np.nonzero(norm > 1e-9)
    out = np.empty((len(rr), 4))
    out[:, 0] = origin[0] + (c[cc] + 0.5) * cell
    out[:, 1] = origin[1] + (r[rr] + 0.5) * cell
    out[:, 2] = v[rr, cc, 0] / norm[rr, cc]
    out[:, 3] = v[rr, cc, 1] / norm[rr, cc]
    return step * cell, [float(x) for x in np.round(out.ravel(), 3)]


@dataclass
class MapLayer:
    """A per-cell layer at the grid's geometry: `data` is `encode_classes` text (classes) or the same
    encoding of a potential quantized to 0..254 (255: no value)."""

    data: str
    rows: int
    cols: int


@dataclass
class Frame:
    """One update of a run's view; fields left None keep their previous value.

    `path` and `curve` are appended to what was sent before (path: x, y pairs [m]; curve: robot
    time [s], coverage pairs). `overlays` replaces the explorer's overlays: any of "potential"
    (a MapLayer), "vectors" ({"spacing": m, "arrows": [x, y, dx, dy, ...]}) and markers
    ("points": {name: [x, y, ...]}, "circles": {name: [x, y, r, ...]}, "lines": {name: [x0, y0, x1, y1, ...]},
    "polygons": {name: [[x, y, ...], ...]}), from an explorer's `markers()`.
    """

    time: float                                     # [s] robot time
    pose: tuple[float, float, float] | None = None  # [m, m, rad] the pose the map is built from
    laser: list[float] | None = None                # [m] world points x, y, ...
    path: list[float] = field(default_factory=list)
    curve: list[float] = field(default_factory=list)
    map: MapLayer | None = None
    overlays: dict[str, Any] | None = None
    speedup: float | None = None                    # robot time per wall time, recently
    coverage: float | None = None


@dataclass
class ViewClient:
    """What one browser connection has received: the hub's epoch (a new run starts a new one), how
    many path and curve numbers, and the map and overlay versions."""

    epoch: int = -1
    path: int = 0
    curve: int = 0
    map_version: int = 0
    overlay_version: int = 0
    seq: int = -1


class ViewHub:
    """The current state of the view, shared by the producer's thread and the server's.

    Args:
        controls: what the page's buttons may do: a subset of "pause", "step", "stop", "speed".
        on_command: called (in the server's thread) with each command a page sends:
            {"cmd": "pause" | "resume" | "step" | "stop" | "speed", "value": ...}.
    """

    def __init__(self, controls: tuple[str, ...] = ("pause", "step", "stop", "speed"),
                 on_command: Callable[[dict[str, Any]], None] | None = None) -> None:
        self.controls = controls
        self.on_command = on_command
        self._lock = threading.Lock()
        self._listeners: list[Callable[[], None]] = []
        self.epoch = 0
        self.meta: dict[str, Any] = {}
        self.status: dict[str, Any] = {"state": "waiting", "reason": "", "speed": None}
        self.seq = 0
        self._reset()

    def _reset(self) -> None:
        self.time = 0.0
        self.pose: tuple[float, float, float] | None = None
        self.laser: list[float] = []
        self.path: list[float] = []
        self.curve: list[float] = []
        self.map: MapLayer | None = None
        self.map_version = 0
        self.overlays: dict[str, Any] = {}
        self.overlay_version = 0
        self.speedup: float | None = None
        self.coverage: float | None = None

    def add_listener(self, wake: Callable[[], None]) -> None:
        """`wake()` is called (in the producer's thread: it must only schedule work) after each change."""
        with self._lock:
            self._listeners.append(wake)

    def remove_listener(self, wake: Callable[[], None]) -> None:
        """Stop calling `wake`."""
        with self._lock:
            if wake in self._listeners:
                self._listeners.remove(wake)

    def _changed(self) -> None:
        self.seq += 1
        for wake in list(self._listeners):
            wake()

    def start(self, meta: dict[str, Any]) -> None:
        """A new run: `meta` names it and gives its map geometry ({"geo": {"origin_x", "origin_y",
        "cell", "rows", "cols"}, "radius": m, "title": text, ...}); the state so far is dropped."""
        with self._lock:
            self.epoch += 1
            self.meta = dict(meta)
            self._reset()
            self.status = {**self.status, "state": "running", "reason": ""}
        self._changed()

    def publish(self, frame: Frame) -> None:
        """Merge `frame` into the current state."""
        with self._lock:
            self.time = frame.time
            if frame.pose is not None:
                self.pose = frame.pose
            if frame.laser is not None:
                self.laser = frame.laser
            self.path.extend(frame.path)
            self.curve.extend(frame.curve)
            if frame.map is not None:
                self.map = frame.map
                self.map_version += 1
            if frame.overlays is not None:
                self.overlays = frame.overlays
                self.overlay_version += 1
            if frame.speedup is not None:
                self.speedup = frame.speedup
            if frame.coverage is not None:
                self.coverage = frame.coverage
        self._changed()

    def set_status(self, **status: Any) -> None:
        """Update the status the page shows: `state` ("running", "paused", "ended"), `reason`, `speed`."""
        with self._lock:
            self.status = {**self.status, **status}
        self._changed()

    def finish(self, reason: str) -> None:
        """The run ended with `reason`; the page keeps its final state."""
        self.set_status(state="ended", reason=reason)

    def message_for(self, client: ViewClient) -> dict[str, Any] | None:
        """What `client` has not received yet, as one JSON-ready message (None: nothing new); marks it sent."""
        with self._lock:
            if client.seq == self.seq:
                return None
            msg: dict[str, Any] = {"type": "frame", "seq": self.seq, "t": self.time, "status": dict(self.status),
                                   "controls": list(self.controls)}
            if client.epoch != self.epoch and self.meta:
                client.epoch, client.path, client.curve = self.epoch, 0, 0
                client.map_version = client.overlay_version = 0
                msg["meta"] = self.meta
            msg["pose"] = self.pose
            msg["laser"] = self.laser
            msg["path_from"], msg["path"] = client.path // 2, self.path[client.path:]
            msg["curve_from"], msg["curve"] = client.curve // 2, self.curve[client.curve:]
            client.path, client.curve = len(self.path), len(self.curve)
            if self.map is not None and client.map_version != self.map_version:
                msg["map"] = {"data": self.map.data, "rows": self.map.rows, "cols": self.map.cols}
                client.map_version = self.map_version
            if client.overlay_version != self.overlay_version:
                msg["overlays"] = {k: (v.__dict__ if isinstance(v, MapLayer) else v)
                                   for k, v in self.overlays.items()}
                client.overlay_version = self.overlay_version
            msg["speedup"], msg["coverage"] = self.speedup, self.coverage
            client.seq = self.seq
            return msg

    def command(self, msg: dict[str, Any]) -> None:
        """A command from a page (see `on_command`); unknown or disallowed ones are ignored."""
        cmd = msg.get("cmd")
        allowed = {"pause": "pause", "resume": "pause", "step": "step", "stop": "stop", "speed": "speed"}
        if self.on_command is not None and allowed.get(str(cmd)) in self.controls:
            self.on_command(msg)
