"""Small recordings written by hand (the mcap writer and robotexp.bag.cdr, no simulation), good or
broken on purpose, for the tests of how replay, figure and video read a recording."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from mcap.writer import CompressionType, Writer

from robotexp.bag import cdr
from robotexp.bag.recorder import stamp_ns
from robotexp.bag.schemas import EXACT_SCAN, LASER_SCAN, OCCUPANCY_GRID, ODOMETRY, TF_MESSAGE

ROWS, COLS, CELL = 40, 40, 0.1       # a 4 x 4 m grid from (-2, -2)


def meta() -> dict[str, Any]:
    """The `robotexp.run` metadata of the crafted run."""
    return {"format": 1, "run": "crafted", "method": "frontier", "world": "box", "world_source": None,
            "pose": "centre", "robot": "sim", "max_speed_m_s": 0.5, "laser_range_m": 3.0, "radius_m": 0.2,
            "period_s": 0.1, "sample_period_s": 1.0, "max_time_s": 10.0, "seed": 0, "start": [0.0, 0.0, 0.0],
            "grid": {"origin_x": -2.0, "origin_y": -2.0, "cell": CELL, "rows": ROWS, "cols": COLS,
                     "model": "logodds", "range_max": None}, "epoch_s": 1_700_000_000.0}


def record() -> dict[str, Any]:
    return {"run": "crafted", "completed": False, "reason": "time limit", "collisions": 0}


class Crafter:
    """Writes a recording of `ticks` ticks of a robot turning in place in a 2 x 2 m box; each hook
    may change what is written (see `write`)."""

    def __init__(self, path: Path, *, compression: CompressionType = CompressionType.NONE) -> None:
        self.file = open(path, "wb")
        self.writer = Writer(self.file, compression=compression)
        self.writer.start(profile="ros2", library="robotexp")
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}

    def channel(self, topic: str, schema: tuple[str, str]) -> int:
        if topic not in self.channels:
            name, text = schema
            if name not in self.schemas:
                self.schemas[name] = self.writer.register_schema(name, "ros2msg", text.encode())
            self.channels[topic] = self.writer.register_channel(topic, "cdr", self.schemas[name])
        return self.channels[topic]

    def message(self, topic: str, schema: tuple[str, str], data: bytes, ns: int) -> None:
        self.writer.add_message(self.channel(topic, schema), log_time=ns, data=data, publish_time=ns)

    def close(self) -> None:
        self.writer.finish()
        self.file.close()


def scan_ranges(theta: float, n: int = 90) -> tuple[np.ndarray, np.ndarray]:
    """Angles and ranges of a scan from the centre of a 2 x 2 m box (walls at +-1 m)."""
    angles = theta + np.linspace(-math.pi, math.pi, n, endpoint=False)
    c, s = np.abs(np.cos(angles)), np.abs(np.sin(angles))
    with np.errstate(divide="ignore"):
        r = np.minimum(np.where(c > 0, 1.0 / c, np.inf), np.where(s > 0, 1.0 / s, np.inf))
    return angles, r


def write(path: Path, *, ticks: int = 5, run_meta: Any = "default", run_record: Any = "default",
          pose: Callable[[int], tuple[float, float, float]] = lambda i: (0.0, 0.0, 0.1 * i),
          odom_schema: tuple[str, str] = ODOMETRY, odom_data: Callable[[bytes], bytes] = lambda b: b,
          truth: Callable[[np.ndarray], tuple[int, int, bytes]] | None = None,
          compression: CompressionType = CompressionType.NONE, raw_meta: str | None = None,
          stamp: Callable[[int], float] = lambda i: 0.1 * i) -> Path:
    """A crafted recording at `path` (see Crafter); the keywords break one part of it."""
    c = Crafter(path, compression=compression)
    m = meta() if run_meta == "default" else run_meta
    c.writer.add_metadata("robotexp.run", {"json": raw_meta if raw_meta is not None else json.dumps(m)})
    states = np.zeros((ROWS, COLS), np.int8)
    states[:10, :] = states[-10:, :] = states[:, :10] = states[:, -10:] = -1
    states[10, 10:30] = states[29, 10:30] = states[10:30, 10] = states[10:30, 29] = 100
    rows, cols, data = (ROWS, COLS, states.tobytes()) if truth is None else truth(states)
    c.message("/ground_truth/map", OCCUPANCY_GRID,
              cdr.occupancy_grid(stamp_ns(0.0), "map", -2.0, -2.0, CELL, rows, cols,
                                 np.frombuffer(data, np.int8)), stamp_ns(0.0))
    for i in range(ticks):
        ns = stamp_ns(stamp(i))
        x, y, th = pose(i)
        c.message("/odom", odom_schema, odom_data(cdr.odometry(ns, "odom", "base_link", x, y, th, 0.0, 1.0)), ns)
        c.message("/ground_truth", ODOMETRY, cdr.odometry(ns, "map", "base_link_true", x, y, th, 0.0, 0.0), ns)
        if i == 0:
            c.message("/tf_static", TF_MESSAGE, cdr.tf_message(ns, [("base_link", "laser", 0.0, 0.0, 0.0)]), ns)
        angles, ranges = scan_ranges(th)
        c.message("/scan", LASER_SCAN, cdr.laser_scan(ns, "laser", float(angles[0]), float(angles[-1]),
                                                      float(angles[1] - angles[0]), 0.1, 0.0, 5.0, ranges), ns)
        c.message("/robotexp/scan", EXACT_SCAN, cdr.exact_scan(ns, "laser", float(angles[0]),
                                                               float(angles[1] - angles[0]), (), ranges, 5.0, 0.0),
                  ns)
    r = record() if run_record == "default" else run_record
    if r is not None:
        c.writer.add_metadata("robotexp.run.record", {"json": json.dumps(r)})
    c.close()
    return path
