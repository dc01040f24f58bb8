"""Localization: scan-to-map matching that corrects odometry, and trajectory metrics."""

from robotexp.localization.correction import FrameCorrection
from robotexp.localization.matcher import (
    HitMap,
    Localizer,
    Match,
    MatcherConfig,
    ScanMatcher,
    compose,
    fill_walls,
    relative,
    scan_points,
)
from robotexp.localization.metrics import ate, rigid_alignment

__all__ = ["FrameCorrection", "HitMap", "Localizer", "Match", "MatcherConfig", "ScanMatcher", "compose", "relative",
           "scan_points", "fill_walls", "ate", "rigid_alignment"]
