"""`load_world`: a built-in world by name, a generated one (`generated:KIND:SEED`), or a MobileSim `.map` /
ROS map_server `.yaml` file."""

from __future__ import annotations

from pathlib import Path

from robotexp.errors import WorldError
from robotexp.world.builtin import BUILTIN, builtin_world
from robotexp.world.model import World

__all__ = ["load_world", "is_map_file", "MAP_SUFFIXES"]

MAP_SUFFIXES = (".map", ".yaml", ".yml")      # a world named by a path with one of these is a map file


def is_map_file(spec: str) -> bool:
    """Whether the world `spec` names a map file (a MobileSim .map or a ROS map_server .yaml), not a built-in
    or generated world."""
    return not spec.startswith("generated:") and Path(spec).suffix.lower() in MAP_SUFFIXES


def load_world(spec: str) -> World:
    """The world named `spec`, generated (`generated:KIND:SEED[:WxH][:scanned]`, see
    `robotexp.world.generate`), or loaded from the file at `spec` (by its extension).

    Raises:
        WorldError: unknown name (lists the built-in ones), missing or malformed file.
    """
    if spec in BUILTIN:
        return builtin_world(spec)
    if spec.startswith("generated:"):
        from robotexp.world.generate import generated_world, parse_generated
        kind, seeds, size, scanned = parse_generated(spec)
        if len(seeds) != 1:
            raise WorldError(f"world {spec!r}: a range of seeds names many worlds, expected one seed here "
                             "(campaigns expand ranges)")
        return generated_world(kind, seeds[0], size, scanned=scanned)
    if not is_map_file(spec):
        return builtin_world(spec)          # raises the "unknown world" error
    path = Path(spec)
    suffix = path.suffix.lower()
    if not path.is_file():
        raise WorldError(f"{spec}: no such map file (give a built-in world: {', '.join(BUILTIN)}, "
                         "or the path of a .map or ROS .yaml file)")
    if suffix == ".map":
        from robotexp.world.mobilesim import load_mobilesim
        return load_mobilesim(path)
    from robotexp.world.rosmap import load_ros_world
    return load_ros_world(path)
