"""Sensor-based Random Tree explorers (thesis §3.2): `srt-ball`, `srt-star`, `srt-laser`."""

from .core import Node, SRTExplorer, SRTTree
from .explorers import SRTBallExplorer, SRTLaserExplorer, SRTStarExplorer, displace, largest_gap
from .regions import (
    BallRegion,
    PolygonRegion,
    SafeRegion,
    StarRegion,
    SweepBuffer,
    frontier_arcs,
    ray_reach,
    segment_clearance,
    star_from_sonar,
    star_from_sweep,
)

__all__ = ["SRTBallExplorer", "SRTStarExplorer", "SRTLaserExplorer", "SRTExplorer", "SRTTree", "Node",
           "SafeRegion", "BallRegion", "StarRegion", "PolygonRegion", "SweepBuffer", "frontier_arcs",
           "ray_reach", "segment_clearance", "star_from_sonar", "star_from_sweep",
           "displace", "largest_gap"]
