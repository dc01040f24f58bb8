"""A second third-party peer reads the LMS2xx emulator: ROS sicktoolbox's SickLMS2xx driver.

sicktoolbox exercises what ARIA does not: it reads the type (0x3A), the 152-byte status (0x31: variant,
measuring mode, units, baud at sicktoolbox's offsets) and the 34-byte configuration (0x74), switches the
variant (0x3B) and writes the units through installation mode and 0x77, then streams (0x20 0x24).
A small client (written here, built in a temporary directory against SICKTOOLBOX_DIR's sources: its
`include/` and `c++/drivers/lms2xx/sicklms2xx/*.cc`) prints what the driver reports and three scans of raw
values; the script checks them against the emulator's ScanSource (a curved wall and no-echo beams):

1. default session at 38400 baud: type LMS200-30106, the emulator's power-on variant 180/0.5 and mm;
2. `SetSickVariant(180, 1 deg)` and `SetSickMeasuringUnits(cm)`: 181 values in cm.

Each value must equal the ScanSource's range rounded to the unit (within one unit), and no-echo beams must
carry a special value (>= 0x1FF7).

Run: python benchmarks/peers/sicktoolbox_lms2xx_peer.py SICKTOOLBOX_DIR
Exit status 0 when every check held, 1 otherwise, 2 on bad arguments (before anything runs).
"""

from __future__ import annotations

import argparse
import math
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robotexp_drivers.lasers.lms2xx import constants as c
from robotexp_drivers.lasers.lms2xx.emulator import LMS2xxEmulator

DUMP_CC = r"""
#include <cstdio>
#include <cstdlib>
#include <sicktoolbox/SickLMS2xx.hh>
using namespace SickToolbox;
// Usage: stb_dump DEVICE BAUD [ANGLE RES_CDEG cm]
static void dump(SickLMS2xx &sick, const char *label)
{
  printf("STB %s type %s angle %g res %g units %d mode %d\n", label,
         SickLMS2xx::SickTypeToString(sick.GetSickType()).c_str(), sick.GetSickScanAngle(),
         sick.GetSickScanResolution(), (int)sick.GetSickMeasuringUnits(), (int)sick.GetSickMeasuringMode());
  unsigned int values[SickLMS2xx::SICK_MAX_NUM_MEASUREMENTS];
  unsigned int n = 0;
  for (int k = 0; k < 3; ++k)
  {
    sick.GetSickScan(values, n);
    printf("STB scan %u", n);
    for (unsigned int i = 0; i < n; ++i)
      printf(" %u", values[i]);
    printf("\n");
  }
  fflush(stdout);
}
int main(int argc, char **argv)
{
  if (argc != 3 && argc != 6) { printf("usage\n"); return 2; }
  SickLMS2xx sick(argv[1]);
  try
  {
    sick.Initialize(SickLMS2xx::StringToSickBaud(argv[2]));
    if (argc == 6)
    {
      sick.SetSickVariant(SickLMS2xx::IntToSickScanAngle(atoi(argv[3])),
                          SickLMS2xx::IntToSickScanResolution(atoi(argv[4])));
      sick.SetSickMeasuringUnits(SickLMS2xx::SICK_MEASURING_UNITS_CM);
    }
    dump(sick, argc == 6 ? "changed" : "default");
    sick.Uninitialize();
  }
  catch (...)
  {
    printf("STB failed\n");
    return 1;
  }
  return 0;
}
"""


def scene(angles: npt.NDArray[np.float64], reach: float) -> npt.NDArray[np.float64]:
    """A curved wall within +-70 deg of ahead, 12 m on the far left, no echo elsewhere."""
    r = np.where(np.abs(angles) < math.radians(70), 2.0 + np.sin(3 * angles), np.inf)
    r = np.where(angles > math.radians(80), 12.0, r)
    return np.where(r <= reach, r, np.inf)


def _check(out: str, label: str, beams: int, unit: float, reach: float, problems: list[str]) -> None:
    head = re.search(rf"STB {label} type (.+?) angle (\S+) res (\S+) units (\d+) mode (\d+)", out)
    if head is None:
        problems.append(f"{label}: sicktoolbox printed no device summary")
        return
    print(f"sicktoolbox {label}: type {head.group(1)}, angle {head.group(2)}, resolution {head.group(3)}, "
          f"units {head.group(4)}, mode {head.group(5)}")
    res = 180 / (beams - 1)
    units = 1 if unit == 0.001 else 0
    if ("200-30106" not in head.group(1) or (float(head.group(2)), float(head.group(3))) != (180.0, res)
            or int(head.group(4)) != units):
        problems.append(f"{label}: sicktoolbox reports {head.group(1)}, {head.group(2)} deg at {head.group(3)}, "
                        f"units {head.group(4)}; expected LMS 200-30106, 180 deg at {res:g}, units {units}")
    angles = c.first_angle(180) + np.radians(res) * np.arange(beams)
    want = scene(angles, reach) / unit
    scans = [np.array(m.group(2).split(), dtype=np.int64)
             for m in re.finditer(r"STB scan (\d+)((?: \d+)*)", out)]
    if len(scans) != 3:
        problems.append(f"{label}: {len(scans)} scans from sicktoolbox, expected 3")
    for i, got in enumerate(scans):
        if got.shape != (beams,):
            problems.append(f"{label}: scan {i} has {got.size} values, expected {beams}")
            continue
        echo = np.isfinite(want)
        err = float(np.max(np.abs(got[echo] - want[echo])))
        specials = int(np.sum(got[~echo] >= c.SPECIAL_OVER_MAX))
        print(f"sicktoolbox {label}: scan {i}: {beams} values, largest error {err:.2f} units over {int(echo.sum())} "
              f"echoes, {specials}/{int((~echo).sum())} no-echo beams as special values")
        if err > 1.0 or specials != int((~echo).sum()):
            problems.append(f"{label}: scan {i} differs from the ScanSource")


def main() -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sicktoolbox", type=Path, help="sicktoolbox checkout (include/, c++/drivers/lms2xx/)")
    args = parser.parse_args()
    root = args.sicktoolbox.resolve()
    sources = sorted((root / "c++" / "drivers" / "lms2xx" / "sicklms2xx").glob("SickLMS2xx*.cc"))
    if not ((root / "include" / "sicktoolbox" / "SickLMS2xx.hh").is_file() and len(sources) == 3):
        print(f"sicktoolbox_lms2xx_peer: {root}: no include/sicktoolbox/SickLMS2xx.hh and "
              "c++/drivers/lms2xx/sicklms2xx/SickLMS2xx*.cc; give a sicktoolbox checkout", file=sys.stderr)
        return 2
    try:
        rev = subprocess.run(["git", "-C", str(root), "log", "-1", "--format=%h (%cs)"], capture_output=True,
                             text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        rev = "unknown version"
    print("sicktoolbox:", rev)
    problems: list[str] = []
    with tempfile.TemporaryDirectory(prefix="stb_lms2xx_") as tmp:
        src, exe = Path(tmp) / "stb_dump.cc", Path(tmp) / "stb_dump"
        src.write_text(DUMP_CC)
        build = subprocess.run(["g++", "-std=gnu++11", "-O1", "-w", f"-I{root / 'include'}", str(src),
                                *map(str, sources), "-o", str(exe), "-lpthread"], capture_output=True, text=True,
                               timeout=600)
        if build.returncode != 0:
            print("sicktoolbox_lms2xx_peer: cannot build the client:\n" + build.stderr[-2000:], file=sys.stderr)
            return 1
        for label, extra, beams, unit, reach in (("default", [], 361, 0.001, 8.0),
                                                 ("changed", ["180", "100", "cm"], 181, 0.01, 80.0)):
            with LMS2xxEmulator(scene, pty=True).start() as em:
                try:
                    run = subprocess.run([str(exe), em.address, "38400", *extra], capture_output=True, text=True,
                                         timeout=120)
                    out = run.stdout
                except subprocess.TimeoutExpired as exc:
                    out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
                    problems.append(f"{label}: sicktoolbox did not finish within 120 s")
                print(f"emulator ({label}): requests", " ".join(f"{r:02X}" for r in em.requests),
                      "| baud switches", em.baud_log, "| configuration writes", em.requests.count(0x77))
                if "STB failed" in out:
                    problems.append(f"{label}: sicktoolbox raised")
                if 38400 not in em.baud_log:
                    problems.append(f"{label}: sicktoolbox did not switch to 38400 baud")
            _check(out, label, beams, unit, reach, problems)
            if problems:
                print(out[-2000:])
    if problems:
        for p in sorted(set(problems)):
            print("FAIL:", p)
        return 1
    print(f"OK: sicktoolbox {rev} read the emulator as the ScanSource has it (status, type, configuration, "
          "variant and units changes, 3 + 3 scans)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
