"""A third-party SCIP 2.0 client reads the Hokuyo emulator over TCP: PyPI `hokuyolx` (installed from
the `test` extra, never committed). It asks PP, VV and II, lights the laser (BM), takes a GD scan and
an MD stream of a given number of scans, and goes to standby (QT)."""

from __future__ import annotations

import numpy as np
import pytest
from scan_sources import BoxSource

from robotexp_drivers.lasers.hokuyo.emulator import HokuyoEmulator

hokuyolx = pytest.importorskip("hokuyolx")


@pytest.mark.parametrize("model", ["URG-04LX", "UTM-30LX"])
def test_hokuyolx_reads_the_emulator(model: str) -> None:
    src = BoxSource()
    with HokuyoEmulator(src, model=model) as emu:
        host, port = emu.address.split(":")
        # no time synchronisation: hokuyolx does it with %ST, a UST-series command these models lack
        lx = hokuyolx.HokuyoLX(addr=(host, int(port)), tsync=False, convert_time=False, timeout=2)
        try:
            p = emu.model.params
            assert (lx.amin, lx.amax, lx.aforw, lx.ares, lx.dmin, lx.dmax) == (
                p.amin, p.amax, p.afrt, p.ares, p.dmin_mm, p.dmax_mm)
            assert lx.scan_freq == p.scan_rpm // 60
            assert lx.version()["PROT"] == "SCIP 2.0"
            assert lx.sensor_state()["LASR"] == "ON"
            # hokuyolx's get_angles() slices by step number from AMIN (right only where AMIN is 0)
            angles = (np.arange(lx.amin, lx.amax + 1) - lx.aforw) * 2 * np.pi / lx.ares
            want = src.ranges(angles, p.dmax_mm / 1000.0) * 1000.0
            fin = np.isfinite(want)
            _, scan = lx.get_dist()
            assert scan.shape == want.shape and np.max(np.abs(scan[fin] - want[fin])) <= 0.5 + 1e-6
            assert np.all(scan[~fin] < p.dmin_mm)          # no echo: an error code below DMIN
            pending = []
            for scan, _, left in lx.iter_dist(scans=3):
                pending.append(left)
                assert np.max(np.abs(scan[fin] - want[fin])) <= 0.5 + 1e-6
            assert pending == [2, 1, 0]
            lx.standby()
            assert lx.sensor_state()["LASR"] == "OFF"
        finally:
            lx.close()


def test_hokuyolx_reads_a_wall_at_5_m_from_the_urg04lx() -> None:
    # a URG-04LX is rated 4 m but its PP says DMAX 5600: a wall 5 m ahead comes back as ~5000 mm
    src = BoxSource(-1.0, 5.0, -3.0, 3.0)
    with HokuyoEmulator(src) as emu:
        host, port = emu.address.split(":")
        lx = hokuyolx.HokuyoLX(addr=(host, int(port)), tsync=False, convert_time=False, timeout=2)
        try:
            _, scan = lx.get_dist()
        finally:
            lx.close()
    steps = np.arange(379, 390)                             # around AFRT 384 (the array starts at AMIN 44)
    want = 5000.0 / np.cos((steps - 384) * 2 * np.pi / 1024)  # 5000 mm straight ahead, 5002 mm 1.76 deg off
    assert scan[steps - 44].tolist() == pytest.approx(want.tolist(), abs=0.5 + 1e-6)
