"""Numba kernels for occupancy-grid mapping (work in progress)."""

from __future__ import annotations

import numba

kernel = numba.njit(cache=True)
