"""Online calibration of systematic odometry error from scan matches.

Wheel odometry errs systematically (Borenstein & Feng's UMBmark: unequal wheel diameters, an uncertain
wheelbase): a P3-DX whose wheels differ by 1 % turns 1.7 deg per metre it believes straight. Scan
matching corrects that only where the scan pins the heading down against an already-mapped part; in an
unmapped corridor, or in a hall the laser does not reach across, the pose follows odometry and the
heading drifts. And where it matches, the matcher's motion prior pulls towards a prediction that is
biased the same way every time, so the corrected path is still bent by a fraction of the bias.

`OdometryCalibration` estimates the two systematic heading terms of a differential drive from the
heading corrections of well-conditioned matches (in the spirit of Kümmerle et al. 2011, "Simultaneous
calibration, localization, and mapping", and Censi et al. 2013, where the calibration is estimated
from the same scan matches that localize the robot): per odometry increment of forward distance d [m]
and turn dth [rad], the true turn is dth + k d + e dth (k [rad/m]: unequal wheel diameters; e: the
wheelbase's relative error). `apply` corrects an increment with the current (k, e); `observe` adds the
heading correction c a match made after odometry moved (d, dth) since the last one, and refits (k, e)
by exponentially forgotten, regularised least squares on y = k_used d + e_used dth + c (the
corrections measured with the estimate then in use, added back, so the fixed point is the true bias
even when the matcher only corrects part of the error at each match).
"""

from __future__ import annotations

import math

from robotexp.errors import ConfigError
from robotexp.robot import Pose

__all__ = ["OdometryCalibration"]


class OdometryCalibration:
    """Online estimate of odometry's systematic heading error (see the module docstring).

    Args:
        forget: weight of the past at each new observation (0.995: the last ~200 matches count).
        ridge: (distance [m^2], turn [rad^2]) of pseudo-observations of the estimate in use: with little
            motion of one kind the estimate of its term moves slowly (from 0 at first).
        k_max: [rad/m] the curvature bias is clamped to +-k_max (0.1 rad/m = 5.7 deg/m, three times
            a 1 % wheel mismatch on a P3-DX).
        e_max: the wheelbase's relative error is clamped to +-e_max.

    Attributes:
        k: [rad/m] heading error per metre driven forward.
        e: relative turn error (true turn = (1 + e) odometry turn, plus k d).
        samples: observations used.
    """

    def __init__(self, *, forget: float = 0.995, ridge: tuple[float, float] = (0.05, 0.1), k_max: float = 0.1,
                 e_max: float = 0.1) -> None:
        if not 0.0 < forget <= 1.0:
            raise ConfigError(f"odometry calibration: forget must be in (0, 1], got {forget}")
        if min(ridge) <= 0 or k_max < 0 or e_max < 0:
            raise ConfigError(f"odometry calibration: ridge must be > 0 and the clamps >= 0, got {ridge}, "
                              f"{k_max}, {e_max}")
        self.forget = forget
        self.ridge = ridge
        self.k_max, self.e_max = k_max, e_max
        self.k = 0.0
        self.e = 0.0
        self.samples = 0
        self._a = (0.0, 0.0, 0.0)      # the forgotten sums of d d, d dth, dth dth
        self._b = (0.0, 0.0)           # ... and of d y, dth y

    def apply(self, inc: Pose) -> Pose:
        """The odometry increment `inc` (in the frame of its start) with its heading corrected; the
        position is turned by half the correction (the chord of an arc)."""
        dth = self.k * inc.x + self.e * inc.theta
        if dth == 0.0:
            return inc
        c, s = math.cos(dth / 2), math.sin(dth / 2)
        return Pose(c * inc.x - s * inc.y, s * inc.x + c * inc.y, inc.theta + dth)

    def observe(self, d: float, dth: float, correction: float) -> None:
        """Add one match: odometry moved `d` [m] forward and turned `dth` [rad] since the last match (with
        the current estimate applied to the prediction), and the match turned the prediction by
        `correction` [rad]."""
        y = self.k * d + self.e * dth + correction
        w = self.forget
        self._a = (w * self._a[0] + d * d, w * self._a[1] + d * dth, w * self._a[2] + dth * dth)
        self._b = (w * self._b[0] + d * y, w * self._b[1] + dth * y)
        a00, a01, a11 = self._a[0] + self.ridge[0], self._a[1], self._a[2] + self.ridge[1]
        det = a00 * a11 - a01 * a01          # > 0: the ridge makes the 2x2 normal matrix positive definite
        b0 = self._b[0] + self.ridge[0] * self.k      # the ridge pulls towards the estimate in use (0 at
        b1 = self._b[1] + self.ridge[1] * self.e      # first), so that it leaves no lasting bias
        k = (a11 * b0 - a01 * b1) / det
        e = (a00 * b1 - a01 * b0) / det
        self.k = min(max(k, -self.k_max), self.k_max)
        self.e = min(max(e, -self.e_max), self.e_max)
        self.samples += 1
