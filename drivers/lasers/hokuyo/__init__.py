"""Hokuyo URG/UTM laser driver: SCIP 2.0 over USB-ACM (a serial port) or TCP (UTM-30LX-EW).

The driver is `laser.py`; this package re-exports it."""

from __future__ import annotations

from robotexp_drivers.lasers.hokuyo.laser import HokuyoLaser

__all__ = ["HokuyoLaser"]
