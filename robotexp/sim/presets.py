"""Robot presets for the simulator: geometry, limits and sensors of the P3-DX and the Kobuki."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.robot import Footprint, Limits

__all__ = ["LaserConfig", "SonarConfig", "OdometryError", "ODOMETRY_PRESETS", "odometry_error", "RobotPreset",
           "PRESETS", "preset", "P3DX_SONAR", "P3DX_SONAR_ARIA"]


@dataclass(frozen=True)
class LaserConfig:
    """A planar laser: `beams` over `fov` [rad] centred on the heading, up to `range_max` [m].

    Noise is added to ranges that hit something: gaussian with `sigma` [m] and uniform in
    +-`uniform` [m] (the UFMG study's +-10 cm). The default is a SICK LMS200-like scanner.
    """

    beams: int = 181
    fov: float = math.pi
    range_max: float = 3.0
    sigma: float = 0.0
    uniform: float = 0.0
    offset_x: float = 0.0     # [m] ahead of the robot centre
    height: float = 0.2       # [m] above the floor

    def __post_init__(self) -> None:
        if self.beams < 1:
            raise ConfigError(f"laser: beams must be >= 1, got {self.beams}")
        if not 0 < self.fov <= 2 * math.pi:
            raise ConfigError(f"laser: field of view must be in (0, 2 pi] rad, got {self.fov}")
        if not self.range_max > 0:
            raise ConfigError(f"laser: range must be > 0 m, got {self.range_max}")
        if self.sigma < 0 or self.uniform < 0:
            raise ConfigError(f"laser: noise must be >= 0 m, got sigma={self.sigma} uniform={self.uniform}")

    def angles(self) -> npt.NDArray[np.float64]:
        """Beam angles [rad] relative to the heading, (beams,) float64."""
        if self.beams == 1:
            return np.zeros(1)
        if self.fov >= 2 * math.pi - 1e-12:     # a full circle: do not count -pi and +pi twice
            return np.linspace(-math.pi, math.pi, self.beams, endpoint=False)
        return np.linspace(-self.fov / 2, self.fov / 2, self.beams)


@dataclass(frozen=True)
class SonarConfig:
    """A sonar ring: transducers at `angles` [deg] on a ring of `ring_radius` [m] (or at `offsets`,
    (x forward, y left) [m] in the robot frame, one per transducer, when given), each a cone of
    `cone` [deg] sampled by `rays_per_cone` rays, reading the nearest echo up to `range_max` [m].

    A reading is the nearest echo anywhere in the cone, so the cone is sampled every degree (16
    rays): with coarser sampling a door frame between two rays goes unheard, and a perception that
    reads the cone as free (SRT-Star) claims the frame as free space.
    """

    angles_deg: tuple[float, ...] = ()
    ring_radius: float = 0.2
    cone_deg: float = 15.0
    rays_per_cone: int = 16
    range_max: float = 5.0
    offsets: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        if self.offsets and len(self.offsets) != len(self.angles_deg):
            raise ConfigError(f"sonar: {len(self.offsets)} offsets for {len(self.angles_deg)} transducers")

    def angles(self) -> npt.NDArray[np.float64]:
        """Transducer headings [rad] in the robot frame."""
        return np.radians(np.asarray(self.angles_deg, dtype=np.float64))

    def origins(self) -> npt.NDArray[np.float64]:
        """Transducer positions (x forward, y left) [m] in the robot frame, (n, 2) float64."""
        if self.offsets:
            return np.asarray(self.offsets, dtype=np.float64).reshape(-1, 2)
        ring = self.angles()
        return self.ring_radius * np.column_stack([np.cos(ring), np.sin(ring)])


@dataclass(frozen=True)
class OdometryError:
    """Odometry error model: systematic wheel-diameter mismatch, random slip and heading drift (all off
    by default; `ODOMETRY_PRESETS` holds the documented robot figures).

    `wheel_mismatch` is the relative diameter difference (right - left) / nominal. With `wheel_servo`
    False the robot moves exactly as commanded and the mismatch bends what odometry believes; with
    `wheel_servo` True the wheel speeds are servoed on the encoders, as the P3-DX and Kobuki firmware
    do, so the encoders (and odometry) follow the command and the true path bends: a robot told to go
    straight believes it goes straight and curves (the thesis's P3-DX). Either way the true path and
    odometry differ by the same wheel model. `slip_sigma` is the standard deviation of the relative
    error of each wheel's travel per step (random, not systematic). `heading_drift` [rad/m] is a
    systematic heading error odometry accrues per metre travelled (a misaligned axle or a gyro bias).
    """

    wheel_mismatch: float = 0.0
    slip_sigma: float = 0.0
    heading_drift: float = 0.0
    wheel_servo: bool = False

    def __post_init__(self) -> None:
        if abs(self.wheel_mismatch) >= 0.5 or self.slip_sigma < 0:
            raise ConfigError("odometry: wheel_mismatch must be in (-0.5, 0.5) and slip_sigma >= 0, "
                              f"got {self.wheel_mismatch} and {self.slip_sigma}")
        if not abs(self.heading_drift) < 1.0:
            raise ConfigError(f"odometry: heading_drift must be in (-1, 1) rad/m, got {self.heading_drift}")

    @property
    def active(self) -> bool:
        """True when the model makes any error at all."""
        return bool(self.wheel_mismatch or self.slip_sigma or self.heading_drift)


# Where the numbers come from (estimates are named as such):
# - p3dx: the thesis (Ribacki 2011, 4.4.2) reports that its P3-DX's wheels differ in size so that it
#   curves when told to go straight, large enough to make its real runs only qualitative, and that ARIA
#   could not be calibrated; it gives no figure. Borenstein & Feng's UMBmark (1996) found uncalibrated
#   differential robots with wheel-diameter ratios off by some tenths of a percent to about one
#   percent; pneumatic tyres such as the P3-DX's change diameter with pressure and load. 1 % is our
#   ESTIMATE at the large end of that range: commanded straight for 5 m, the true heading turns by
#   5 * 0.01 / 0.33 = 0.15 rad (8.7 deg) and the end lies 0.38 m off the line. The slip (0.2 % per
#   wheel per step) is an ESTIMATE for a carpeted office floor.
# - kobuki: hard rubber wheels of fixed diameter and a factory-calibrated gyro that the driver uses
#   for heading. The 0.2 % mismatch and 0.1 deg/m residual heading drift are ESTIMATES, an order of
#   magnitude below the P3-DX, as users report for gyro-fused Kobuki odometry.
ODOMETRY_PRESETS: dict[str, OdometryError] = {
    "none": OdometryError(),
    "p3dx": OdometryError(wheel_mismatch=0.01, slip_sigma=0.002, wheel_servo=True),
    "kobuki": OdometryError(wheel_mismatch=0.002, slip_sigma=0.001, heading_drift=math.radians(0.1),
                            wheel_servo=True),
}

_ODOMETRY_KEYS = {"mismatch": "wheel_mismatch", "slip": "slip_sigma", "drift": "heading_drift"}


def odometry_error(spec: str) -> OdometryError:
    """Parse an `--odometry-error` value: a preset name (`none`, `p3dx`, `kobuki`), optionally
    followed by `:key=value,...` overrides, or the overrides alone (on the error-free model). Keys:
    `mismatch` (relative wheel-diameter difference), `slip` (relative per-step sigma), `drift`
    [deg/m], `servo` (0/1).

    Examples: `p3dx`, `p3dx:mismatch=0.02`, `mismatch=0.005,drift=0.5,servo=1`.

    Raises:
        ConfigError: unknown preset or key, or a value that is not a number or out of range.
    """
    text = spec.strip()
    name, _, rest = text.partition(":")
    if "=" in name:
        name, rest = "none", text
    name = name.strip().lower() or "none"
    if name not in ODOMETRY_PRESETS:
        raise ConfigError(f"--odometry-error: unknown preset {name!r} (available: {', '.join(ODOMETRY_PRESETS)}; "
                          "or key=value pairs: mismatch, slip, drift [deg/m], servo)")
    changes: dict[str, object] = {}
    for item in filter(None, (part.strip() for part in rest.split(","))):
        key, eq, value = item.partition("=")
        key = key.strip().lower()
        if not eq or key not in (*_ODOMETRY_KEYS, "servo"):
            raise ConfigError(f"--odometry-error: {item!r} is not key=value with key one of "
                              f"{', '.join((*_ODOMETRY_KEYS, 'servo'))}")
        try:
            number = float(value)
        except ValueError:
            raise ConfigError(f"--odometry-error: {key}={value!r} is not a number") from None
        if not math.isfinite(number):
            raise ConfigError(f"--odometry-error: {key}={value!r} is not a finite number")
        if key == "servo":
            changes["wheel_servo"] = bool(number)
        elif key == "drift":
            changes["heading_drift"] = math.radians(number)
        else:
            changes[_ODOMETRY_KEYS[key]] = number
    return replace(ODOMETRY_PRESETS[name], **changes) if changes else ODOMETRY_PRESETS[name]  # type: ignore[arg-type]


# The P3-DX sonar ring (ARIA p3dx.p): 8 front transducers, 8 rear, on a 0.2 m ring.
P3DX_SONAR = SonarConfig(angles_deg=(90, 50, 30, 10, -10, -30, -50, -90,
                                     -90, -130, -150, -170, 170, 150, 130, 90))
# The same transducers where ARIA's p3dx.p puts them ("SonarUnit n x y th", mm and deg): what ARIA
# and a real P3-DX read (the side ones 64 mm nearer the centre than on the ring). The P3-DX emulator
# casts from here; the simulator's "p3dx" preset keeps the ring its explorers were tuned on (with
# these poses srt-star covers 70% of dense from pose 1 instead of 99.5%).
P3DX_SONAR_ARIA = SonarConfig(angles_deg=P3DX_SONAR.angles_deg,
                              offsets=((0.069, 0.136), (0.114, 0.119), (0.148, 0.078), (0.166, 0.027),
                                       (0.166, -0.027), (0.148, -0.078), (0.114, -0.119), (0.069, -0.136),
                                       (-0.157, -0.136), (-0.203, -0.119), (-0.237, -0.078), (-0.255, -0.027),
                                       (-0.255, 0.027), (-0.237, 0.078), (-0.203, 0.119), (-0.157, 0.136)))


@dataclass(frozen=True)
class RobotPreset:
    """What the simulator needs to know of a robot model. `radius` is half the footprint's width (what the
    planners keep from walls); `footprint` the outline the simulator collides with (None: a disc of `radius`)."""

    name: str
    radius: float             # [m]
    height: float             # [m]
    wheel_base: float         # [m]
    limits: Limits
    laser: LaserConfig = field(default_factory=LaserConfig)
    sonar: SonarConfig | None = None
    footprint: Footprint | None = None

    def __post_init__(self) -> None:
        if self.footprint is None:
            object.__setattr__(self, "footprint", Footprint.disc(self.radius))

    @property
    def outline(self) -> Footprint:
        """The robot's outline (`footprint`, never None once built)."""
        assert self.footprint is not None
        return self.footprint


PRESETS: dict[str, RobotPreset] = {
    # Pioneer P3-DX: radius 250 mm (SPEC), wheel base ~330 mm, ARIA's default limits are far above
    # the thesis's 100 mm/s; 1.2 m/s and 300 deg/s are the robot's own maxima.
    "p3dx": RobotPreset("p3dx", radius=0.25, height=0.25, wheel_base=0.33,
                        limits=Limits(v_max=1.2, w_max=math.radians(300), a_max=0.3,
                                      alpha_max=math.radians(100)),
                        sonar=P3DX_SONAR),
    # The P3-DX as its 455 x 381 mm body (the maker's data sheet): passages open from 381 mm, turning in
    # place sweeps a 297 mm radius (the simulator collides with the rectangle, the guards sweep it).
    "p3dx-body": RobotPreset("p3dx-body", radius=0.1905, height=0.25, wheel_base=0.33,
                             footprint=Footprint.rectangle(0.455, 0.381),
                             limits=Limits(v_max=1.2, w_max=math.radians(300), a_max=0.3,
                                           alpha_max=math.radians(100)),
                             sonar=P3DX_SONAR),
    # Kobuki: radius ~175 mm, wheel base 230 mm (kobuki.md), 0.7 m/s and 180 deg/s.
    "kobuki": RobotPreset("kobuki", radius=0.175, height=0.12, wheel_base=0.23,
                          limits=Limits(v_max=0.7, w_max=math.pi, a_max=0.5, alpha_max=math.pi),
                          laser=LaserConfig(height=0.15)),
}


def preset(name: str, **changes: object) -> RobotPreset:
    """The preset called `name`, with fields replaced by `changes` (a new `radius` without a `footprint`
    makes the robot a disc of that radius). Raises ConfigError."""
    try:
        base = PRESETS[name]
    except KeyError:
        raise ConfigError(f"unknown robot preset {name!r} (available: {', '.join(PRESETS)})") from None
    if "radius" in changes and "footprint" not in changes:
        changes = {**changes, "footprint": None}
    return replace(base, **changes) if changes else base   # type: ignore[arg-type]
