"""Start poses: parsing "x,y,theta" (mm, mm, degrees) and resolving a pose name, a text pose or the
default of a world into a `Pose` (SI units) with the label its records carry."""

from __future__ import annotations

import math


from robotexp.errors import ConfigError
from robotexp.robot import Pose
from robotexp.world.model import World

__all__ = ["parse_pose", "resolve_pose", "pose_name", "pose_text", "central_free_pose"]


POSE_LIMIT_MM = 1e7     # [mm] |x|, |y| of a pose given as numbers (10 km: larger is a typo or an attack)


def parse_pose(text: str) -> Pose:
    """Parse "x,y,theta" (mm, mm, degrees; theta optional) into a Pose in SI units.

    Raises:
        ConfigError: not two or three finite numbers, |x| or |y| over `POSE_LIMIT_MM`, or |theta| over 360 degrees.
    """
    parts = text.split(",")
    try:
        if len(parts) not in (2, 3):
            raise ValueError
        x, y = float(parts[0]), float(parts[1])
        th = float(parts[2]) if len(parts) == 3 else 0.0
        if not all(math.isfinite(v) for v in (x, y, th)):
            raise ValueError
    except ValueError:
        raise ConfigError(f"pose {text!r}: expected a pose name or x,y,theta in mm, mm, degrees "
                          "(e.g. -5000,7500,0)") from None
    if max(abs(x), abs(y)) > POSE_LIMIT_MM or abs(th) > 360:
        raise ConfigError(f"pose {text!r}: x and y must be within +-{POSE_LIMIT_MM:.0f} mm and theta within "
                          "+-360 degrees")
    return Pose(x / 1000, y / 1000, math.radians(th))


def pose_text(pose: Pose) -> str:
    """`pose` as "x,y,theta" in mm, mm, degrees (rounded to whole units), as records label it."""
    return f"{pose.x * 1000:.0f},{pose.y * 1000:.0f},{math.degrees(pose.theta):.0f}"


def resolve_pose(world: World, pose: str | None, radius: float) -> tuple[Pose, str]:
    """The start pose and its label: a named pose, "x,y,theta", or the default.

    The default is the world's `home` (a .map file's RobotHome cairn), else its first named pose,
    else a point well inside the largest region where a robot of `radius` [m] fits.

    Raises:
        WorldError: an unknown pose name (the message lists the world's), or no place for the robot.
        ConfigError: a malformed "x,y,theta".
    """
    if pose is None:
        if world.home is not None:
            return world.home, "home"
        if world.poses:
            name = next(iter(world.poses))
            return world.poses[name], name
        return central_free_pose(world, radius), "centre"
    name = _named(world, pose)
    if name is not None:
        return world.poses[name], name
    if "," not in pose:
        world.pose(pose)                    # raises: lists the names the world has
    p = parse_pose(pose)
    return p, pose_text(p)


def pose_name(world: World, pose: str | None) -> str | None:
    """The world's name for the start pose `pose` (a name, or None for the default), else None."""
    if pose is None:
        return None if world.home is not None or not world.poses else next(iter(world.poses))
    return _named(world, pose)


def _named(world: World, pose: str) -> str | None:
    """The world's pose name `pose` stands for: itself, else the one name equal to it but for case
    ("Home" and "home" are the same pose, as in campaigns and the CLI), else None."""
    if pose in world.poses:
        return pose
    folded = [key for key in world.poses if key.casefold() == pose.casefold()]
    return folded[0] if len(folded) == 1 else None


def central_free_pose(world: World, radius: float) -> Pose:
    """The default start of a world that names none: a point well inside the largest region where a
    robot of `radius` [m] fits (`robotexp.world.start.default_start`; the name is from the time it
    was the free cell nearest the map's centre).

    Raises:
        WorldError: the robot fits nowhere.
    """
    from robotexp.world.start import default_start

    return default_start(world, radius).pose
