"""`LocalizedRobot`: a robot whose reported pose is corrected by scan matching, for any run loop.

It wraps another `Robot` and sits between it and everything that reads it (the mapper, the explorer):
each new state's odometry pose is replaced by the `Localizer`'s corrected pose, so explorers receive
the corrected pose, never the true one (`true_pose`, where a simulator knows it, stays as it is, for
the metrics only). It keeps the pairs (corrected, true) for the absolute trajectory error.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from robotexp.clock import Clock
from robotexp.localization import covariance as C
from robotexp.localization import kernels as K
from robotexp.localization.calibration import OdometryCalibration
from robotexp.localization.matcher import Localizer, MatcherConfig, ScanMatcher
from robotexp.localization.metrics import ate
from robotexp.localization.online import OnlineGraph, OnlineLoopConfig
from robotexp.mapping.geometry import GridGeometry
from robotexp.robot import Pose, Robot, RobotState, Twist, new_scan

__all__ = ["LocalizedRobot", "MOTION_NOISE", "GATE", "MAX_TURN_RATE"]

# The motion prior between matches: 2 cm + 5 % of the distance, 0.5 deg + 2 deg/m + 5 % of the turn.
# Wheel odometry over 0.1 m or 5 deg is better than that (the P3-DX preset: 0.17 deg/m of curve); a
# loose prior let the matcher turn the map by 1 deg while the robot spun in place in a corridor.
MOTION_NOISE = (0.02, 0.05, math.radians(0.5), math.radians(2.0), 0.05)
GATE = 4.0      # a match farther than this many sigmas of the motion prior is refused
# The matcher of whole runs: never-seen points left out of the search too (see `MatcherConfig.drop_unseen`).
# (A field of sigma 0.1 m instead of 0.05 m matched a scan against its own map better, 0.964 of the field
# against 0.865, but corrected the P3-DX's heading less: 3.9 deg off after 3.5 m of corridor.)
# ... and Gauss-Newton on the exact field of the hit points' wall segments (sub-millimetre against a right map;
# see `MatcherConfig.exact_field` and docs/localization, "The dense map IoU gap").
RUN_MATCHER = MatcherConfig(drop_unseen=True, exact_field=True)
# The `Localizer`'s covariance of (x, y, theta, k): per metre driven, (1 cm)^2 of position and (0.3 deg)^2 of
# heading random walk (the P3-DX preset's slip, 0.2 % per wheel and step, makes (0.09 deg)^2 per metre), the
# heading bias k [rad/m] uncertain by 0.05 rad/m (2.9 deg/m: the preset's 1.74 deg/m within 0.6 sigma) at the
# start (so that the heading's uncertainty grows with the distance driven), drifting by 1e-7 rad^2/m^3. In
# sparse (3 m laser, seeds 0-3, before main's sub-cell matcher) it took frontier's ATE from 2.7-15.2 m to 3.3-5.5 m
# (docs/localization, "The sparse hall").
COVARIANCE = (1e-4, math.radians(0.3) ** 2, 0.05, 1e-7)
MAP_UNCERTAIN = 1.0     # [m] the `Localizer` option: unmatched scans leave the matching map alone after this
MAP_TRAVEL, MAP_TURN = 0.3, math.radians(15.0)   # [m], [rad]: the `Localizer`'s map update thresholds
MAX_TURN_RATE = 0.5     # [rad/s] no matching while turning faster (see `Localizer`)


class LocalizedRobot(Robot):
    """`inner` with its pose corrected by a `Localizer` over `geo` (the matching map's extent).

    Args:
        inner: the robot (open); closed with this one.
        geo: the extent and cells of the localizer's matching map (the explorer's map geometry).
        matcher: the scan matcher (default `ScanMatcher(RUN_MATCHER)`).
        start: the corrected pose at the first reading (default: the robot's own first pose; a
            simulator starts at its true pose).
        range_max: [m] the matching map's beam cap (default the scans' own).
        skip_unseen: the `Localizer` option; on here: a robot turning in place with a short-range
            laser sees walls run on past the mapped part at every scan (without it, rotating in a
            corridor of `dense` lost 0.4 deg and 0.2 m in 3 s).
        min_travel: [m] the `Localizer` option: match once the robot has moved this far ...
        min_turn: [rad] ... or turned this much (a 10 Hz loop otherwise matches every 3 cm).
        motion_noise: the `Localizer` option (MOTION_NOISE by default).
        gate: the `Localizer` option (GATE by default).
        calibrate: estimate odometry's systematic heading error online (`OdometryCalibration`).
        max_turn_rate: [rad/s] the `Localizer` option (none by default: a simulator's scan is taken at
            the state's instant; MAX_TURN_RATE for a laser of its own, whose stamps are not).
        loop_closure: keyframes and online loop closure (`robotexp.localization.online`) with these
            settings (True: the defaults; None: none).

    Attributes:
        localizer: the localizer (its `counts` say how the matches went).
        track: (corrected, true) poses of every new state, where the true pose is known.
        odometry: beside each `track` entry, the inner robot's own pose (to replay the localizer:
            `benchmarks/studies/bench_localized_iou.py`).
        graph: the online pose graph with `loop_closure` (else None).
        keyframe: the index of the graph's latest keyframe at the last new state (-1: none yet).
        steps: beside each `track` entry: (robot time [s], the localizer's status, the scan's echoes,
            the odometry calibration's heading bias k [rad/m]); `benchmarks/studies/bench_localized_explore.py
            --trace` writes them with the errors.
    """

    def __init__(self, inner: Robot, geo: GridGeometry, *, matcher: ScanMatcher | None = None,  # noqa: PLR0913
                 start: Pose | None = None, range_max: float | None = None, skip_unseen: bool = True,
                 min_travel: float = 0.1, min_turn: float = math.radians(5.0),
                 motion_noise: tuple[float, float, float, float, float] | None = MOTION_NOISE,
                 gate: float = GATE, calibrate: bool = True, max_turn_rate: float = math.inf,
                 loop_closure: OnlineLoopConfig | bool | None = None) -> None:
        self.inner = inner
        self.name = f"{inner.name}+scan-match"         # type: ignore[misc]
        self.capabilities = inner.capabilities          # type: ignore[misc]
        self.limits = inner.limits
        self.radius = inner.radius
        self.address = inner.address
        self.localizer = Localizer(geo, matcher or ScanMatcher(RUN_MATCHER), range_max=range_max,
                                   skip_unseen=skip_unseen, min_travel=min_travel, min_turn=min_turn,
                                   motion_noise=motion_noise,
                                   gate=gate, calibration=OdometryCalibration() if calibrate else None,
                                   max_turn_rate=max_turn_rate, map_uncertain=MAP_UNCERTAIN,
                                   map_travel=MAP_TRAVEL, map_turn=MAP_TURN, covariance=COVARIANCE)
        self.graph: OnlineGraph | None = None
        if loop_closure:
            self.graph = OnlineGraph(self.localizer, self.localizer.matcher.config,
                                     loop_closure if isinstance(loop_closure, OnlineLoopConfig) else None)
        self.keyframe = -1
        K.warm()                                        # every matcher kernel compiled before the run starts
        C.warm()                                        # ... and the covariance's
        self.track: list[tuple[Pose, Pose]] = []
        self.odometry: list[Pose] = []
        self.steps: list[tuple[float, str, int, float]] = []
        self._start = start
        self._last: tuple[float, RobotState] | None = None
        self._matched: float | None = None                  # the stamp of the last scan matched
        self._version = -1                                  # the localizer's map version at the last state
        super().__init__()

    def _read(self) -> RobotState:
        state = self.inner.read()
        if self._last is not None and self._last[0] == state.time:
            return self._last[1]                        # the same instant: do not match twice
        if self._last is None:
            pose = self._start or state.pose
            self.localizer.reset(state.pose, pose)
            if state.laser is not None:
                self.localizer.integrate(pose, state.laser)
        else:
            scan = state.laser if new_scan(state.laser, self._matched) else None    # each scan matched once
            pose = self.localizer.locate(state.pose, scan, state.velocity.w)
            if self.graph is not None and self.localizer.prediction is not None:
                self.graph.step(self.localizer.prediction, pose)
        if self.graph is not None and state.laser is not None and self.localizer.version != self._version:
            self.graph.add_keyframe(pose, state.laser, state.pose, self.localizer.status or "matched")
            pose = self.localizer.pose or pose          # moved with its keyframe when a loop closed
            self.keyframe = len(self.graph.keyframes) - 1
        self._version = self.localizer.version
        if state.laser is not None:
            self._matched = state.laser.stamp
        out = replace(state, pose=pose)
        if state.true_pose is not None:
            self.track.append((pose, state.true_pose))
            self.odometry.append(state.pose)
            cal = self.localizer.calibration
            hits = 0 if state.laser is None else int(np.count_nonzero(np.isfinite(state.laser.ranges)))
            self.steps.append((state.time, self.localizer.status, hits, 0.0 if cal is None else cal.k))
        self._last = (state.time, out)
        return out

    @property
    def model(self) -> str:
        """The inner robot's model (run records name the robot, not the wrapper)."""
        return self.inner.model

    def describe(self) -> dict[str, str]:
        """The inner robot's description, with the localization named."""
        return {**self.inner.describe(), "localization": "scan-match"}

    def ate_m(self) -> float | None:
        """[m] RMSE of the corrected positions against the true ones (no alignment), None when unknown."""
        if not self.track:
            return None
        est = np.array([[p.x, p.y] for p, _ in self.track])
        truth = np.array([[t.x, t.y] for _, t in self.track])
        return ate(est, truth)

    def detach(self) -> None:
        """Done with this wrapper: mark it closed and leave the inner robot open."""
        self._closed = True

    def _command(self, twist: Twist) -> None:
        if self.inner.closed and twist == Twist.ZERO:
            return                                      # closing after the inner robot: it stopped already
        self.inner.command(twist)

    def _close(self) -> None:
        self.inner.close()                              # safe when the inner robot is closed already

    def make_clock(self, period: float) -> Clock:
        """The inner robot's clock."""
        return self.inner.make_clock(period)

    def set_max_speed(self, v_max: float) -> None:
        """Set the inner robot's limit, and mirror it."""
        self.inner.set_max_speed(v_max)
        self.limits = self.inner.limits

    def move_to(self, pose: Pose) -> None:
        """Teleport the inner robot (simulators) and restart localization there."""
        self.inner.move_to(pose)
        self._last = None
        self._start = pose
        if self.graph is not None:                      # a new start: a new graph
            self.graph = OnlineGraph(self.localizer, self.graph.matcher_config, self.graph.config)
            self.keyframe = -1
