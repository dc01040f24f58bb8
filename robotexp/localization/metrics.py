"""Trajectory metrics: the absolute trajectory error (ATE) of an estimated path against the true one."""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError

__all__ = ["ate", "rigid_alignment"]


def rigid_alignment(est: npt.ArrayLike, truth: npt.ArrayLike) -> tuple[float, float, float]:
    """The rotation and translation (theta [rad], tx, ty [m]) that best map the (n, 2) estimated
    positions onto the true ones in the least-squares sense (Horn / Umeyama without scale)."""
    e = np.asarray(est, np.float64)[:, :2]
    t = np.asarray(truth, np.float64)[:, :2]
    me, mt = e.mean(axis=0), t.mean(axis=0)
    a, b = e - me, t - mt
    # maximise sum b . R a: theta = atan2(sum a x b, sum a . b)
    theta = math.atan2(float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])), float(np.sum(a * b)))
    c, s = math.cos(theta), math.sin(theta)
    return theta, float(mt[0] - (c * me[0] - s * me[1])), float(mt[1] - (s * me[0] + c * me[1]))


def ate(est: npt.ArrayLike, truth: npt.ArrayLike, align: Literal["none", "rigid"] = "none") -> float:
    """Absolute trajectory error [m]: the RMSE of the positions of `est` against `truth`, pose by pose.

    Args:
        est: (n, 2) or (n, 3) estimated poses [m, m(, rad)]; only x, y count.
        truth: the true poses at the same instants, same shape.
        align: "none" compares the paths as they are (both start in the same frame: the robot's
            start pose is known); "rigid" first applies the rotation and translation that fit `est`
            best onto `truth` (for paths in different frames).

    Raises:
        ConfigError: the shapes differ, the paths are empty, or `align` is unknown.
    """
    e = np.asarray(est, np.float64)
    t = np.asarray(truth, np.float64)
    if e.ndim != 2 or e.shape != t.shape or e.shape[1] < 2 or len(e) == 0:
        raise ConfigError(f"ate: paths must be equal non-empty (n, 2) or (n, 3) arrays, got {e.shape} and {t.shape}")
    xy = e[:, :2]
    if align == "rigid":
        th, tx, ty = rigid_alignment(xy, t)
        c, s = math.cos(th), math.sin(th)
        xy = np.column_stack([c * xy[:, 0] - s * xy[:, 1] + tx, s * xy[:, 0] + c * xy[:, 1] + ty])
    elif align != "none":
        raise ConfigError(f"ate: align must be 'none' or 'rigid', got {align!r}")
    return float(np.sqrt(np.mean(np.sum((xy - t[:, :2]) ** 2, axis=1))))
