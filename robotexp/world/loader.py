"""`load_world`: a built-in world by name, a generated one (`generated:KIND:SEED`), or a MobileSim `.map` /
ROS map_server `.yaml` file."""

from __future__ import annotations

from pathlib import Path

from robotexp.errors import WorldError
from robotexp.world.builtin import BUILTIN, builtin_world
from robotexp.world.model import World

__all__ = ["load_world"]


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
    path = Path(spec)
    suffix = path.suffix.lower()
    if suffix not in (".map", ".yaml", ".yml"):
        return builtin_world(spec)          # raises the "unknown world" error
    if not path.is_file():
        raise WorldError(f"{spec}: no such map file (give a built-in world: {', '.join(BUILTIN)}, "
                         "or the path of a .map or ROS .yaml file)")
    if suffix == ".map":
        from robotexp.world.mobilesim import load_mobilesim
        return load_mobilesim(path)
    from robotexp.world.rosmap import load_ros_world
    return load_ros_world(path)
