"""Mapping, part of the explorers' toolkit (public): `GridGeometry` (geometry.py), `OccupancyGrid`
(grid.py, log-odds or HIMM) and the numba kernels that update and read grids (kernels.py, with their
plain references in reference.py). Import the modules."""
