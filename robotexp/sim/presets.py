"""Robot presets for the simulator: geometry, limits and sensors of the P3-DX and the Kobuki."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from robotexp.errors import ConfigError
from robotexp.robot import Limits

__all__ = ["LaserConfig", "SonarConfig", "OdometryError", "RobotPreset", "PRESETS", "preset", "P3DX_SONAR",
           "P3DX_SONAR_ARIA"]


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
    """Odometry error model: a systematic wheel-diameter mismatch and random slip (both off by default).

    `wheel_mismatch` is the relative diameter difference (right - left) / nominal, which makes a
    straight command drift into a curve (the thesis's P3-DX); `slip_sigma` is the standard deviation
    of the relative error of each wheel's travel per step.
    """

    wheel_mismatch: float = 0.0
    slip_sigma: float = 0.0

    def __post_init__(self) -> None:
        if abs(self.wheel_mismatch) >= 0.5 or self.slip_sigma < 0:
            raise ConfigError("odometry: wheel_mismatch must be in (-0.5, 0.5) and slip_sigma >= 0, "
                              f"got {self.wheel_mismatch} and {self.slip_sigma}")


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
    """What the simulator needs to know of a robot model."""

    name: str
    radius: float             # [m]
    height: float             # [m]
    wheel_base: float         # [m]
    limits: Limits
    laser: LaserConfig = field(default_factory=LaserConfig)
    sonar: SonarConfig | None = None


PRESETS: dict[str, RobotPreset] = {
    # Pioneer P3-DX: radius 250 mm (SPEC), wheel base ~330 mm, ARIA's default limits are far above
    # the thesis's 100 mm/s; 1.2 m/s and 300 deg/s are the robot's own maxima.
    "p3dx": RobotPreset("p3dx", radius=0.25, height=0.25, wheel_base=0.33,
                        limits=Limits(v_max=1.2, w_max=math.radians(300), a_max=0.3,
                                      alpha_max=math.radians(100)),
                        sonar=P3DX_SONAR),
    # Kobuki: radius ~175 mm, wheel base 230 mm (kobuki.md), 0.7 m/s and 180 deg/s.
    "kobuki": RobotPreset("kobuki", radius=0.175, height=0.12, wheel_base=0.23,
                          limits=Limits(v_max=0.7, w_max=math.pi, a_max=0.5, alpha_max=math.pi),
                          laser=LaserConfig(height=0.15)),
}


def preset(name: str, **changes: object) -> RobotPreset:
    """The preset called `name`, with fields replaced by `changes`. Raises ConfigError."""
    try:
        base = PRESETS[name]
    except KeyError:
        raise ConfigError(f"unknown robot preset {name!r} (available: {', '.join(PRESETS)})") from None
    return replace(base, **changes) if changes else base   # type: ignore[arg-type]
