"""Ground truth on a large open floor: only viewpoints that can see a free cell the robot cannot reach are
cast from (a 4-line map of a 400 m square took minutes when every lattice point of its floor was)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import robotexp.world.groundtruth as gt
from robotexp.run.spec import RunSpec, plan_run

SQUARE = """2D-Map
LineMinPos: 0 0
LineMaxPos: {s} {s}
NumLines: 5
LINES
0 0 {s} 0
{s} 0 {s} {s}
{s} {s} 0 {s}
0 {s} 0 0
{a} {a} {b} {a}
DATA
"""


def _plan(path: Path, monkeypatch: pytest.MonkeyPatch, restricted: bool) -> tuple[object, int]:
    casts: list[int] = []
    view_free = gt.view_free

    def counted(occ, views, offsets, skip):  # type: ignore[no-untyped-def]
        casts.append(len(views))
        return view_free(occ, views, offsets, skip)

    monkeypatch.setattr(gt, "view_free", counted)
    if not restricted:
        monkeypatch.setattr(gt, "_near", lambda mask, reach: np.ones_like(mask))
    gt._GRIDS.clear()
    plan = plan_run(RunSpec(world=str(path)), str(path), 0.25)
    monkeypatch.undo()
    return plan.truth, sum(casts)


def test_an_open_floor_is_seen_from_its_border_only_and_the_truth_is_the_same(tmp_path: Path,
                                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "square.map"          # a 40 m square with one wall inside it, in mm
    path.write_text(SQUARE.format(s=40000, a=15000, b=25000))
    fast, n_fast = _plan(path, monkeypatch, restricted=True)
    full, n_full = _plan(path, monkeypatch, restricted=False)
    assert np.array_equal(fast.reachable, full.reachable)          # type: ignore[attr-defined]
    assert np.array_equal(fast.explorable, full.explorable)        # type: ignore[attr-defined]
    # 400 x 400 cells: the old lattice cast from every other cell of the floor (~40 000 viewpoints);
    # the border bands (3 m of laser from the walls, both sides of the inner wall) are under a half of it
    assert n_full > 35_000
    assert n_fast < 0.5 * n_full


def test_near_is_a_chebyshev_neighbourhood() -> None:
    mask = np.zeros((7, 9), bool)
    mask[3, 4] = True
    near = gt._near(mask, 2)
    expected = np.zeros_like(mask)
    expected[1:6, 2:7] = True
    assert np.array_equal(near, expected)
    corner = np.zeros((5, 5), bool)
    corner[0, 0] = True
    assert gt._near(corner, 1).sum() == 4 and gt._near(corner, 0).sum() == 1
