"""Laser rangefinder drivers (entry-point group `robotexp.lasers`): SICK LMS2xx, Hokuyo SCIP 2.0,
Slamtec RPLidar; each a codec / link / `Laser` backend / emulator, sharing `base`."""
