"""SICK LMS2xx (LMS200/211/221/291) laser driver: RS-232/422 telegrams with CRC-16 (entry point `lms2xx`).

The driver is `laser.py`; this package re-exports it."""

from __future__ import annotations

from robotexp_drivers.lasers.lms2xx.laser import LMS2xxLaser

__all__ = ["LMS2xxLaser"]
