"""Worlds: the ground truth of environments, built in or loaded from map files."""

from robotexp.world.model import Mover, World, segment_box

__all__ = ["World", "Mover", "segment_box"]
