"""Slamtec RPLidar A1/A2 laser driver: the RPLidar serial protocol at 115200 (A1, A2M8) or 256000 baud.

The driver is `laser.py`; this package re-exports it."""

from __future__ import annotations

from robotexp_drivers.lasers.rplidar.laser import RPLidarLaser

__all__ = ["RPLidarLaser"]
