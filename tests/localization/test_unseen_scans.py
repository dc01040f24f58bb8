"""Scans that fall where the localizer's matching map has seen nothing: they extend the map even once
the pose is uncertain (sparse: the map froze and the localizer never matched again)."""

from __future__ import annotations

import math

import numpy as np

from robotexp.localization import Localizer, MatcherConfig, ScanMatcher, scan_points
from robotexp.robot import Pose

from test_matcher import CELL, cast, room, true_map  # the hand-made room and its laser, written out there


def test_points_on_never_seen_cells_make_an_unseen_match() -> None:
    world = room()
    occ, geo = true_map(world)
    known = np.zeros(occ.shape, np.uint8)
    known[:, : geo.cols // 2] = 1                     # the west half of the room seen, the east half not
    matcher = ScanMatcher(MatcherConfig(drop_unseen=True))
    p = Pose(5.5, 2.0, 0.0)                            # facing the east wall: every point on unseen cells
    px, py = scan_points(cast(world, p))
    m = matcher.match(occ, geo, px, py, p, known=known)
    assert m.status == "unseen" and m.pose == p and m.points == 0
    # the same scan over a map that has seen everything matches
    assert matcher.match(occ, geo, px, py, p, known=np.ones_like(known)).status == "matched"
    # a handful of points where the map has seen everything: too few to match; where it has seen
    # nothing: still new ground (a glimpse of a pillar goes into the map)
    assert matcher.match(occ, geo, px[:5], py[:5], p, known=np.ones_like(known)).status == "few-points"
    assert matcher.match(occ, geo, px[:5], py[:5], p, known=known).status == "unseen"


def test_an_uncertain_pose_still_maps_new_ground_and_matches_again() -> None:
    world = room()
    _, geo = true_map(world)
    loc = Localizer(geo, ScanMatcher(MatcherConfig(drop_unseen=True)), skip_unseen=True, map_uncertain=1.0)
    start = Pose(4.0, 2.0, math.pi)
    loc.reset(start, start)
    loc.integrate(start, cast(world, start))          # the map: what the robot saw facing west
    loc.locate(Pose(4.0, 2.0, 0.0), None)             # turned east and drove 1.5 m with no scan:
    loc.locate(Pose(5.5, 2.0, 0.0), None)             # more than map_uncertain without a correction
    version = loc.version
    loc.locate(Pose(5.5, 2.0, 0.0), cast(world, Pose(5.5, 2.0, 0.0)))
    # the east half was never seen: the scan goes into the map (it froze here before: "few-points"
    # for every later scan, since all their points fell on never-seen cells)
    assert loc.status == "unseen" and loc.version == version + 1
    truth = Pose(5.75, 2.03, 0.01)                    # odometry says 5.7, 2.0, 0
    pose = loc.locate(Pose(5.7, 2.0, 0.0), cast(world, truth))
    assert loc.status == "matched"
    assert math.hypot(pose.x - truth.x, pose.y - truth.y) < CELL
    assert abs(math.degrees(pose.theta - truth.theta)) < 0.5
