"""The live view's data feed: what a run looks like, as a stream of frames, and the hub that keeps
the newest of it for every browser.

A producer (the run observer `robotexp.view.observer.ViewObserver`; a replay later) calls
`ViewHub.start(meta)` once per run, then `ViewHub.publish(frame)` as the run goes and
`ViewHub.finish(reason)` at its end. The hub merges frames into one current state: the newest pose,
laser and status, the path and coverage curve appended (points, never resent), the newest map and
overlays (each with a version number). A browser's connection asks `ViewHub.message_for(client)` for
what it has not seen yet: a slow or absent browser only ever gets the newest state, and never makes
the producer wait (the hub holds no queue per client, just what each client has already received).

Maps travel as tiles: a producer publishes the grid as uint8 classes (0 unknown, 1 free, 2 occupied,
row 0 = the southmost row; `classes_of_states`) at a bounded rate (the observer: at most `map_rate` per
wall second, only when it changed). The hub keeps the newest classes and, per tile of `TILE` x `TILE`
cells, the map version that last changed it; a browser is sent only the tiles changed since the
version it has (`encode_tiles`: the tiles' cells concatenated, zlib-compressed, base64; the browser
inflates them with its built-in `DecompressionStream("deflate")` and paints just those tiles). The
encoding happens in the server's thread when a browser is ready for a message, never in the run's;
laser points are likewise made from the scan when a message is sent. Whether anybody watches is
known (`ViewHub.watched`): a producer may skip the map and overlays while nobody does.
"""

from __future__ import annotations

import base64
import math
import threading
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from robotexp.robot import LaserScan

__all__ = ["UNKNOWN", "FREE", "OCCUPIED", "TILE", "Frame", "MapLayer", "ViewClient", "ViewHub", "classes_of_states",
           "encode_classes", "decode_classes", "changed_tiles", "encode_tiles", "decode_tiles", "laser_points",
           "packed_laser", "unpack_laser", "vector_arrows", "command_problem", "COMMANDS", "DEFAULT_SPEED",
           "MIN_SPEED", "MAX_SPEED", "SPEEDS", "speed_value"]


DEFAULT_SPEED = 10.0        # robot time per wall time of a simulated run watched in the view (observer.py too)


MIN_SPEED, MAX_SPEED = 0.01, 1000.0     # the speeds the view takes (a tick of 0.1 s: at most 10 s of wall time)


SPEEDS = f"a number within {MIN_SPEED:g}..{MAX_SPEED:g} (times real time) or 'max'"


def speed_value(value: object) -> float | None:
    """A view speed as the CLI or a page gives it: a number within MIN_SPEED..MAX_SPEED (robot time per wall
    time; a number's text too) or "max" / None (as fast as it goes: None).

    Raises:
        ValueError: anything else (says what is taken).
    """
    if value is None or (isinstance(value, str) and value.strip().lower() == "max"):
        return None
    speed = math.nan
    if isinstance(value, (int, float, str)) and not isinstance(value, bool):
        try:
            speed = float(value)
        except ValueError:
            pass
    if not MIN_SPEED <= speed <= MAX_SPEED:         # NaN too
        raise ValueError(f"speed {value!r}: expected {SPEEDS}")
    return speed

UNKNOWN, FREE, OCCUPIED = 0, 1, 2
TILE = 32           # [cells] side of the map tiles sent to browsers
COMMANDS = ("pause", "resume", "step", "stop", "speed", "seek")     # what a page may send


def command_problem(msg: object) -> str | None:
    """Why `msg` is not a command a page may send (None: it is one): a JSON object {"cmd": one of COMMANDS},
    a speed's "value" within MIN_SPEED..MAX_SPEED or "max", a seek's a finite number of seconds."""
    pass

    if not isinstance(msg, dict) or not isinstance(msg.get("cmd"), str):
        return 'expected a JSON object like {"cmd": "pause"}'
    cmd = msg["cmd"]
    if cmd not in COMMANDS:
        return f"unknown command {cmd[:40]!r}; the view takes {', '.join(COMMANDS)}"
    value = msg.get("value")
    if cmd == "speed":
        try:
            speed_value(value)
        except ValueError as exc:
            return str(exc)[:200]
    elif cmd == "seek" and not (isinstance(value, (int, float)) and not isinstance(value, bool)
                                and math.isfinite(value)):
        return "seek: expected a robot time in seconds as a number, like {\"cmd\": \"seek\", \"value\": 12.5}"
    return None


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


def changed_tiles(old: npt.NDArray[np.uint8] | None, new: npt.NDArray[np.uint8],
                  tile: int = TILE) -> npt.NDArray[np.bool_]:
    """Which tiles of `tile` x `tile` cells differ between two class grids (all of them when `old` is
    None or of another shape): a bool array of ceil(rows / tile) x ceil(cols / tile)."""
    rows, cols = new.shape
    tr, tc = -(-rows // tile), -(-cols // tile)
    if old is None or old.shape != new.shape:
        return np.ones((tr, tc), bool)
    diff = np.zeros((tr * tile, tc * tile), bool)
    np.not_equal(old, new, out=diff[:rows, :cols])
    out: npt.NDArray[np.bool_] = np.any(diff.reshape(tr, tile, tc, tile), axis=(1, 3))
    return out


def encode_tiles(classes: npt.NDArray[np.uint8], which: npt.NDArray[np.bool_], tile: int = TILE) -> dict[str, Any]:
    """The tiles `which` (see `changed_tiles`) of `classes` as one JSON-ready message: {"rows", "cols",
    "tile", "tiles": [tile row, tile column, ...] in row-major order, "data": `encode_classes`-style text
    of the tiles' cells one tile after the other, each tile row-major (edge tiles are smaller)}."""
    rows, cols = classes.shape
    rr, cc = np.nonzero(which)
    parts = [classes[r * tile:(r + 1) * tile, c * tile:(c + 1) * tile].tobytes()
             for r, c in zip(rr.tolist(), cc.tolist(), strict=True)]
    data = base64.b64encode(zlib.compress(b"".join(parts), 1)).decode("ascii")
    return {"rows": rows, "cols": cols, "tile": tile,
            "tiles": [v for rc in zip(rr.tolist(), cc.tolist(), strict=True) for v in rc], "data": data}


def decode_tiles(msg: dict[str, Any], into: npt.NDArray[np.uint8]) -> None:
    """Paint the tiles of an `encode_tiles` message into `into` (rows x cols; what a browser does).

    Raises:
        ValueError: the message's size or tiles do not fit `into`.
    """
    rows, cols, tile = int(msg["rows"]), int(msg["cols"]), int(msg["tile"])
    if into.shape != (rows, cols):
        raise ValueError(f"tiles of a {rows} x {cols} map, given {into.shape[0]} x {into.shape[1]}")
    raw = zlib.decompress(base64.b64decode(msg["data"]))
    at = 0
    idx = msg["tiles"]
    for k in range(0, len(idx), 2):
        r0, c0 = idx[k] * tile, idx[k + 1] * tile
        h, w = min(tile, rows - r0), min(tile, cols - c0)
        if h <= 0 or w <= 0 or at + h * w > len(raw):
            raise ValueError(f"tile ({idx[k]}, {idx[k + 1]}) does not fit the map or the data")
        into[r0:r0 + h, c0:c0 + w] = np.frombuffer(raw, np.uint8, h * w, at).reshape(h, w)
        at += h * w
    if at != len(raw):
        raise ValueError(f"tiles hold {at} cells, data {len(raw)}")


def _laser_xy(x: float, y: float, theta: float, angles: npt.NDArray[np.float64], ranges: npt.NDArray[np.float64],
              offset_x: float, max_points: int) -> tuple[float, float, npt.NDArray[np.float64]]:
    """The laser's position [m] and the (n, 2) world points [m] of the finite beams (every k-th beyond
    `max_points`) of a scan taken at pose (x, y, theta)."""
    ok = np.flatnonzero(np.isfinite(ranges))
    if len(ok) > max_points:
        ok = ok[:: math.ceil(len(ok) / max_points)]
    a = theta + angles[ok]
    sx, sy = x + offset_x * math.cos(theta), y + offset_x * math.sin(theta)
    pts = np.empty((len(ok), 2))
    pts[:, 0] = sx + ranges[ok] * np.cos(a)
    pts[:, 1] = sy + ranges[ok] * np.sin(a)
    return sx, sy, pts


def laser_points(x: float, y: float, theta: float, angles: npt.NDArray[np.float64],
                 ranges: npt.NDArray[np.float64], offset_x: float = 0.0, max_points: int = 360) -> list[float]:
    """World points [m] of the finite beams of a scan taken at pose (x, y, theta), as a flat list
    x0, y0, x1, y1, ... rounded to mm, at most `max_points` (every k-th beam beyond that)."""
    pts = _laser_xy(x, y, theta, angles, ranges, offset_x, max_points)[2]
    return [float(v) for v in np.round(pts.ravel(), 3)]


def packed_laser(x: float, y: float, theta: float, angles: npt.NDArray[np.float64],
                 ranges: npt.NDArray[np.float64], offset_x: float = 0.0, max_points: int = 360) -> dict[str, Any]:
    """The points of `laser_points` as a browser is sent them: {"x", "y": the laser's position [m], "cm":
    base64 of int16 little-endian offsets from it [cm], x0, y0, x1, y1, ...} (a few bytes a point, no
    float formatting; the page adds them back, see `unpack_laser`)."""
    sx, sy, pts = _laser_xy(x, y, theta, angles, ranges, offset_x, max_points)
    pts[:, 0] -= sx
    pts[:, 1] -= sy
    cm = np.clip(np.round(pts * 100), -32768, 32767).astype("<i2")
    return {"x": round(sx, 3), "y": round(sy, 3), "cm": base64.b64encode(cm.tobytes()).decode("ascii")}


def unpack_laser(packed: dict[str, Any]) -> list[float]:
    """The world points [m] x0, y0, ... of a `packed_laser` message (what the page computes)."""
    cm = np.frombuffer(base64.b64decode(packed["cm"]), "<i2").reshape(-1, 2) / 100.0
    return [float(v) for v in (cm + [packed["x"], packed["y"]]).ravel()]


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
    time [s], coverage pairs). `map` is the whole grid as classes (`classes_of_states`; the hub sends
    browsers only its changed tiles). The laser is either `laser` (world points x, y, ... [m]) or
    `scan` (a scan in the frame of `pose`, turned into points when a message is sent). `overlays`
    replaces the explorer's overlays: any of "potential" (a MapLayer), "vectors" ({"spacing": m,
    "arrows": [x, y, dx, dy, ...]}) and markers ("points": {name: [x, y, ...]}, "circles": {name: [x, y,
    r, ...]}, "lines": {name: [x0, y0, x1, y1, ...]}, "polygons": {name: [[x, y, ...], ...]}), from an
    explorer's `markers()`. `team` gives a team's other robots (robots 2, 3, ...): each one's pose and
    new path points.
    """

    time: float                                     # [s] robot time
    pose: tuple[float, float, float] | None = None  # [m, m, rad] the pose the map is built from
    laser: list[float] | None = None                # [m] world points x, y, ...
    scan: LaserScan | None = None                   # instead of `laser`: the scan taken at `pose`
    path: list[float] = field(default_factory=list)
    curve: list[float] = field(default_factory=list)
    map: npt.NDArray[np.uint8] | None = None        # classes, rows x cols (the hub keeps it: do not change it)
    overlays: dict[str, Any] | None = None
    speedup: float | None = None                    # robot time per wall time, recently
    coverage: float | None = None
    rows: list[dict[str, Any]] = field(default_factory=list)   # a campaign's finished runs, appended
    # a team's robots 2, 3, ...: each one's pose [m, m, rad] (None: unchanged) and new path points, appended
    team: list[tuple[tuple[float, float, float] | None, list[float]]] | None = None


@dataclass
class ViewClient:
    """What one browser connection has received: the hub's run and epoch (a new run or a seek starts a
    new epoch), how many path, curve and row items, and the map and overlay versions."""

    run: int = -1
    epoch: int = -1
    path: int = 0
    curve: int = 0
    rows: int = 0
    team_paths: list[int] = field(default_factory=list)    # path items of each of a team's robots 2, 3, ...
    map_version: int = 0
    overlay_version: int = 0
    seq: int = -1


class ViewHub:
    """The current state of the view, shared by the producer's thread and the server's.

    Args:
        controls: what the page's buttons may do: a subset of "pause", "step", "stop", "speed", "seek".
        on_command: called (in the server's thread) with each command a page sends:
            {"cmd": "pause" | "resume" | "step" | "stop" | "speed" | "seek", "value": ...}.
    """

    def __init__(self, controls: tuple[str, ...] = ("pause", "step", "stop", "speed"),
                 on_command: Callable[[dict[str, Any]], None] | None = None) -> None:
        self.controls = controls
        self.on_command = on_command
        self._lock = threading.Lock()
        self._listeners: list[Callable[[], None]] = []
        self.run = 0            # runs started
        self.epoch = 0          # runs started and restarts (seeks)
        self.meta: dict[str, Any] = {}
        self.status: dict[str, Any] = {"state": "waiting", "reason": "", "speed": None}
        self.seq = 0
        self._reset()

    def _reset(self) -> None:
        self.time = 0.0
        self.pose: tuple[float, float, float] | None = None
        self.laser: list[float] | dict[str, Any] = []     # world points, or `packed_laser` of a scan
        self._scan: tuple[tuple[float, float, float], LaserScan] | None = None
        self.path: list[float] = []
        self.curve: list[float] = []
        self.classes: npt.NDArray[np.uint8] | None = None
        self.tile_version = np.zeros((0, 0), np.int64)
        self.map_version = 0
        self.overlays: dict[str, Any] = {}
        self.overlay_version = 0
        self.speedup: float | None = None
        self.coverage: float | None = None
        self.rows: list[dict[str, Any]] = []
        self.team: list[tuple[float, float, float] | None] = []    # a team's robots 2, 3, ...: poses
        self.team_paths: list[list[float]] = []                     # ... and paths (x, y, ... [m])

    @property
    def watched(self) -> bool:
        """Whether a browser is connected."""
        return bool(self._listeners)

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
            self.run += 1
            self.epoch += 1
            self.meta = dict(meta)
            self._reset()
            self.status = {**self.status, "state": "running", "reason": ""}
        self._changed()

    def restart(self, time: float) -> None:
        """The same run seen again from robot time `time` (a replay that seeks): the path and curve
        are dropped (the producer sends them again up to then); the map and overlays stay until new
        ones come (only the map's tiles that differ are sent again)."""
        with self._lock:
            self.time = time
            self.path, self.curve = [], []
            self.team_paths = [[] for _ in self.team_paths]
            self.laser, self._scan = [], None
            self.epoch += 1
        self._changed()

    def _set_map(self, classes: npt.NDArray[np.uint8]) -> None:
        """Take `classes` as the map (under the lock): the tiles that differ get a new version."""
        changed = changed_tiles(self.classes, classes)
        if self.classes is None or self.classes.shape != classes.shape:
            self.tile_version = np.zeros(changed.shape, np.int64)
        if changed.any():
            self.map_version += 1
            self.tile_version[changed] = self.map_version
        self.classes = classes

    def publish(self, frame: Frame) -> None:
        """Merge `frame` into the current state."""
        with self._lock:
            self.time = frame.time
            if frame.pose is not None:
                self.pose = frame.pose
            if frame.scan is not None and frame.pose is not None:
                self._scan, self.laser = (frame.pose, frame.scan), []
            elif frame.laser is not None:
                self._scan, self.laser = None, frame.laser
            self.path.extend(frame.path)
            self.curve.extend(frame.curve)
            self.rows.extend(frame.rows)
            for i, (pose, points) in enumerate(frame.team or ()):
                if i == len(self.team):
                    self.team.append(None)
                    self.team_paths.append([])
                if pose is not None:
                    self.team[i] = pose
                self.team_paths[i].extend(points)
            if frame.map is not None:
                self._set_map(frame.map)
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
        """What `client` has not received yet, as one JSON-ready message (None: nothing new); marks it sent.
        Called in the server's thread: the laser points and the map's tiles are made here, outside the
        lock (a producer's `publish` never waits for them; the classes it gave are never changed)."""
        with self._lock:
            if client.seq == self.seq:
                return None
            msg: dict[str, Any] = {"type": "frame", "seq": self.seq, "t": self.time, "status": dict(self.status),
                                   "controls": list(self.controls)}
            if client.epoch != self.epoch and self.meta:
                if client.run != self.run:          # a new run: everything afresh
                    client.run, client.rows, client.map_version, client.overlay_version = self.run, 0, 0, 0
                    msg["meta"] = self.meta
                client.epoch, client.path, client.curve, client.team_paths = self.epoch, 0, 0, []
            scan = self._scan
            msg["pose"] = self.pose
            msg["laser"] = self.laser
            msg["path_from"], msg["path"] = client.path // 2, self.path[client.path:]
            msg["curve_from"], msg["curve"] = client.curve // 2, self.curve[client.curve:]
            client.path, client.curve = len(self.path), len(self.curve)
            if self.team:
                sent = client.team_paths + [0] * (len(self.team) - len(client.team_paths))
                msg["team"] = [{"pose": pose, "path_from": k // 2, "path": path[k:]}
                               for pose, path, k in zip(self.team, self.team_paths, sent, strict=True)]
                client.team_paths = [len(path) for path in self.team_paths]
            if len(self.rows) > client.rows:
                msg["rows_from"], msg["rows"] = client.rows, self.rows[client.rows:]
                client.rows = len(self.rows)
            classes = tiles = None
            if self.classes is not None and client.map_version != self.map_version:
                classes, tiles = self.classes, self.tile_version > client.map_version
                client.map_version = self.map_version
            overlays = None
            if client.overlay_version != self.overlay_version:
                overlays = self.overlays
                client.overlay_version = self.overlay_version
            msg["speedup"], msg["coverage"] = self.speedup, self.coverage
            client.seq = self.seq
        if scan is not None:
            (x, y, theta), sc = scan
            msg["laser"] = packed_laser(x, y, theta, sc.angles, sc.ranges, sc.offset_x)
            with self._lock:
                if self._scan is scan:              # kept for the other browsers
                    self._scan, self.laser = None, msg["laser"]
        if classes is not None and tiles is not None:
            msg["map"] = encode_tiles(classes, tiles)
        if overlays is not None:
            msg["overlays"] = {k: (v.__dict__ if isinstance(v, MapLayer) else v) for k, v in overlays.items()}
        return msg

    def command(self, msg: dict[str, Any]) -> None:
        """A command from a page (see `on_command`); unknown or disallowed ones are ignored."""
        cmd = msg.get("cmd")
        allowed = {"pause": "pause", "resume": "pause", "step": "step", "stop": "stop", "speed": "speed",
                   "seek": "seek"}
        if self.on_command is not None and allowed.get(str(cmd)) in self.controls:
            self.on_command(msg)
