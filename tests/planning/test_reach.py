"""`robotexp.planning.reach`: the kernels against `distance_transform(...) <= reach`, cell for cell."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robotexp.errors import ConfigError
from robotexp.planning.reach import max_d2, near_cells, probe_cells, within_reference


def test_max_d2_by_hand() -> None:
    assert max_d2(5.5) == 30            # 5.477 <= 5.5 < 5.568
    assert max_d2(5.0) == 25            # exactly 5: included, as distance_transform's 5.0 <= 5.0
    assert max_d2(math.sqrt(2)) == 2    # float32(sqrt 2) rounds below float64 sqrt 2: 1 offset diagonal kept
    assert max_d2(0.0) == 0 and max_d2(0.99) == 0 and max_d2(-1.0) == -1
    with pytest.raises(ConfigError):
        max_d2(float("nan"))


@pytest.mark.parametrize("reach", [0.0, 1.0, math.sqrt(2), 3.25, 5.5, 7.0])
@pytest.mark.parametrize("density", [0.0, 0.003, 0.05, 0.6])
def test_kernels_equal_the_distance_transform(reach: float, density: float) -> None:
    rng = np.random.default_rng(int(reach * 100) + int(density * 1000))
    src = rng.random((47, 61)) < density
    cand = rng.random((47, 61)) < 0.3
    want = within_reference(src, reach)
    assert np.array_equal(near_cells(src, reach), want)
    assert np.array_equal(probe_cells(src, cand, reach), cand & want)


def test_bad_masks() -> None:
    with pytest.raises(ConfigError, match="probe_cells"):
        probe_cells(np.zeros((3, 3), bool), np.zeros((3, 4), bool), 1.0)
    with pytest.raises(ConfigError, match="near_cells"):
        near_cells(np.zeros((3, 3), np.int8), 1.0)      # type: ignore[arg-type]
