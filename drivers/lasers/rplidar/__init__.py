"""Slamtec RPLidar A1/A2 laser driver (work in progress)."""
