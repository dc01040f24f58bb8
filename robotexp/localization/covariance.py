"""The `Localizer`'s covariance of (x, y, theta, k), k odometry's heading bias [rad/m]: carried along
odometry (`propagate`) and updated by a scan match (`fuse`), as numba kernels, each with a plain-numpy
reference (`propagate_ref`, `fuse_ref`; tested equal).

A heading error moves the position sideways by the displacement turned a right angle; an error of k
turns the heading by the distance driven times it (and the position by half that, the chord of the
arc). A match fixes the pose in the directions its scan pins down (eigenvectors of the scan's normal
matrix with the heading scaled by the points' RMS range, whose eigenvalue reaches `ratio` of the
largest); `fuse` is a Kalman update in those directions with the scan's information there as the
measurement's. The pose keeps the match's correction in them and takes the update's in the others: a
lone pillar seen sideways of where it should be, after driving with a heading error, turns the heading
by what the covariance built while driving ties to that sideways error, and moves k. Then a direction of
the position that the translation block of the normal matrix hardly fixes (its eigenvalue below `along` of
the block's largest: along a corridor whose door frames and wall bumps give a sliver of information) takes
the update's step as well, not the match's correction.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robotexp.localization.kernels import kernel

__all__ = ["propagate", "propagate_ref", "fuse", "fuse_ref", "warm"]


@kernel
def propagate(cov: npt.NDArray[np.float64], dx: float, dy: float, dist: float, q_xy: float, q_th: float,
              q_k: float) -> None:
    """In place: cov <- F cov F^T + Q for a step of (dx, dy) [m] in the world frame and `dist` [m] of
    odometry, Q = diag(q_xy, q_xy, q_th, q_k) * dist."""
    f = np.eye(4)
    f[0, 2] = -dy
    f[1, 2] = dx
    f[0, 3] = -dy * dist / 2
    f[1, 3] = dx * dist / 2
    f[2, 3] = dist
    cov[:, :] = f @ cov @ np.ascontiguousarray(f.T)
    cov[0, 0] += q_xy * dist
    cov[1, 1] += q_xy * dist
    cov[2, 2] += q_th * dist
    cov[3, 3] += q_k * dist


def propagate_ref(cov: npt.NDArray[np.float64], dx: float, dy: float, dist: float, q_xy: float, q_th: float,
                  q_k: float) -> None:
    """`propagate` in numpy."""
    f = np.eye(4)
    f[0, 2], f[1, 2] = -dy, dx
    f[0, 3], f[1, 3], f[2, 3] = -dy * dist / 2, dx * dist / 2, dist
    cov[:, :] = f @ cov @ f.T + np.diag([q_xy, q_xy, q_th, q_k]) * dist


@kernel
def fuse(cov: npt.NDArray[np.float64], info: npt.NDArray[np.float64], lever: float, ratio: float, along: float,
         dx: float, dy: float, dth: float) -> tuple[float, float, float, float]:
    """Update the covariance `cov` of (x, y, theta, k) in place by a match that moved the prediction by
    (dx, dy, dth) [m, m, rad] and whose scan's normal matrix is `info` (x, y, theta), its points' RMS
    range `lever` [m].

    Returns:
        (step x, step y, step theta, step k): the correction of the pose (the match's in the directions
        its scan fixes, the update's in the others) and of k. No direction fixed (a zero `info`):
        the match's correction and k unchanged, `cov` as it was.
    """
    scale = np.array([1.0, 1.0, max(lever, 1e-3)])
    hs = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            hs[i, j] = info[i, j] / (scale[i] * scale[j])
    vals, vecs = np.linalg.eigh(hs)
    if vals[2] <= 0.0:
        return dx, dy, dth, 0.0
    d = np.array([dx, dy, dth * scale[2]])
    m = 0
    for i in range(3):
        if vals[i] >= ratio * vals[2]:
            m += 1
    s4 = np.zeros((4, m))
    w3 = np.zeros((3, 3 - m))
    r = np.zeros((m, m))
    a = 0
    b = 0
    for i in range(3):
        if vals[i] >= ratio * vals[2]:
            s4[:3, a] = vecs[:, i]
            r[a, a] = 1.0 / vals[i]
            a += 1
        else:
            w3[:, b] = vecs[:, i]
            b += 1
    scale4 = np.array([1.0, 1.0, scale[2], 1.0])
    ps = np.empty((4, 4))
    for i in range(4):
        for j in range(4):
            ps[i, j] = cov[i, j] * scale4[i] * scale4[j]
    innovation = s4[:3].T @ d
    gain = ps @ s4 @ np.linalg.inv(s4.T @ ps @ s4 + r)
    delta = gain @ innovation
    ps = ps - gain @ s4.T @ ps
    for i in range(4):
        for j in range(4):
            cov[i, j] = ps[i, j] / (scale4[i] * scale4[j])
    step = s4[:3] @ innovation + w3 @ (w3.T @ delta[:3])
    v2, e2 = np.linalg.eigh(np.ascontiguousarray(info[:2, :2]))
    if v2[1] > 0.0:
        for i in range(2):
            if v2[i] < along * v2[1]:
                u0, u1 = e2[0, i], e2[1, i]
                shift = u0 * (delta[0] - step[0]) + u1 * (delta[1] - step[1])
                step[0] += u0 * shift
                step[1] += u1 * shift
    return step[0], step[1], step[2] / scale[2], delta[3]


def fuse_ref(cov: npt.NDArray[np.float64], info: npt.NDArray[np.float64], lever: float, ratio: float,
             along: float, dx: float, dy: float, dth: float) -> tuple[float, float, float, float]:
    """`fuse` in numpy."""
    scale = np.array([1.0, 1.0, max(lever, 1e-3)])
    vals, vecs = np.linalg.eigh(info / np.outer(scale, scale))
    if vals[-1] <= 0:
        return dx, dy, dth, 0.0
    strong = vals >= ratio * vals[-1]
    s3, w3 = vecs[:, strong], vecs[:, ~strong]
    s4 = np.vstack([s3, np.zeros((1, s3.shape[1]))])
    scale4 = np.append(scale, 1.0)
    ps = cov * np.outer(scale4, scale4)
    innovation = s3.T @ (np.array([dx, dy, dth]) * scale)
    gain = ps @ s4 @ np.linalg.inv(s4.T @ ps @ s4 + np.diag(1.0 / vals[strong]))
    delta = gain @ innovation
    cov[:, :] = (ps - gain @ s4.T @ ps) / np.outer(scale4, scale4)
    step = s3 @ innovation + w3 @ (w3.T @ delta[:3])
    v2, e2 = np.linalg.eigh(info[:2, :2])
    if v2[-1] > 0:
        for i in np.flatnonzero(v2 < along * v2[-1]):
            u = np.append(e2[:, i], 0.0)
            step = step + u * (u @ (delta[:3] - step))
    step = step / scale
    return float(step[0]), float(step[1]), float(step[2]), float(delta[3])


_warmed = False


def warm() -> None:
    """Call `propagate` and `fuse` once with the argument types the `Localizer` passes, so that numba
    compiles (or loads) them before a run starts, not mid-run on a real robot (once per process)."""
    global _warmed
    if _warmed:
        return
    cov = np.eye(4) * 1e-4
    propagate(cov, 0.01, 0.0, 0.01, 1e-4, 1e-5, 1e-7)
    fuse(cov, np.eye(3), 1.0, 0.03, 0.2, 0.0, 0.0, 0.0)
    _warmed = True
