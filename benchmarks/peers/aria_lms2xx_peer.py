"""A third-party peer reads the LMS2xx emulator: AriaCoda's LMS2xx driver (ArLMS2xx), through its `lasers` example
and through a small ARIA client that prints every raw reading.

The robot is our P3-DX emulator on TCP (ARIA's laser programs connect a robot first; `-remoteIsNotSim` keeps
ARIA from swapping in its simulated laser), the laser our LMS2xxEmulator on a pseudo-terminal measuring a
made-up scene: a straight wall `--wall` m from the sensor whose normal points at `--normal` deg
(counter-clockwise from the sensor's forward axis). ARIA runs its own connection sequence (0x10 reset and
the 0x90 wait, baud switch to 38400, 0x3B variant, installation mode, its 32-byte 0x77 configuration in
32 m mode "1ref" and mm, 0x20 0x24) each time.

1. `examples/lasers` (as shipped): it must connect and report, every 3 s, as many raw readings as the
   variant has beams and as many 'current' readings as the ScanSource has echoes within ARIA's 32 m.
   (Its "closest reading" line is not checked: with this ARIA it searches an unset (inf, -inf) range.)
2. `lms2xx_dump` (written here, built in a temporary directory against ARIACODA_DIR's headers and
   libAria): prints ArLMS2xx's raw readings (beam angle on the robot [deg], range [mm]) of three scans;
   each must match the ScanSource at p3dx.p's laser pose: the angle within 0.01 deg, an echo within
   1 mm (the unit), no echo as a range beyond ARIA's 32 m.

Run: python benchmarks/peers/aria_lms2xx_peer.py ARIACODA_DIR [--increment one|half] [--seconds 8]
Exit status 0 when every check held, 1 otherwise, 2 on bad arguments (before anything runs).
"""

from __future__ import annotations

import argparse
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import numpy.typing as npt

from robotexp_drivers.lasers.lms2xx.emulator import LMS2xxEmulator
from robotexp_drivers.p3dx.emulator import P3DXEmulator


def wall(distance: float, normal_deg: float):  # noqa: ANN201 - a ScanSource
    """A ScanSource: an infinite straight wall `distance` m away along the direction `normal_deg`."""
    phi = math.radians(normal_deg)

    def source(angles: npt.NDArray[np.float64], reach: float) -> npt.NDArray[np.float64]:
        cos = np.cos(angles - phi)
        with np.errstate(divide="ignore"):
            r = np.where(cos > 1e-6, distance / np.maximum(cos, 1e-6), np.inf)
        return np.where(r <= reach, r, np.inf)
    return source


DUMP_CPP = r"""
#include "Aria/Aria.h"
#include <cstdio>
// Connect the robot and laser as the ARIA examples do, then print three scans of raw readings.
int main(int argc, char **argv)
{
  Aria::init();
  ArArgumentParser parser(&argc, argv);
  parser.loadDefaultArguments();
  ArRobot robot;
  ArRobotConnector robotConnector(&parser, &robot);
  ArLaserConnector laserConnector(&parser, &robot, &robotConnector);
  if (!robotConnector.connectRobot()) { printf("DUMP no robot\n"); Aria::exit(1); }
  if (!Aria::parseArgs()) { printf("DUMP bad arguments\n"); Aria::exit(2); }
  robot.runAsync(true);
  if (!laserConnector.connectLasers()) { printf("DUMP no laser\n"); Aria::exit(3); }
  ArUtil::sleep(1500);
  for (int k = 0; k < 3; ++k)
  {
    robot.lock();
    ArLaser *laser = robot.findLaser(1);
    laser->lockDevice();
    const std::list<ArSensorReading *> *raw = laser->getRawReadings();
    printf("DUMP scan %d readings %d\n", k, raw == NULL ? -1 : (int)raw->size());
    if (raw != NULL)
      for (std::list<ArSensorReading *>::const_iterator it = raw->begin(); it != raw->end(); ++it)
        printf("DUMP reading %.3f %u\n", (*it)->getSensorTh(), (*it)->getRange());
    fflush(stdout);
    laser->unlockDevice();
    robot.unlock();
    ArUtil::sleep(400);
  }
  Aria::exit(0);
  return 0;
}
"""
ARIA_MAX_MM = 32000         # ARIA's absolute maximum for "1ref" in mm (ArLMS2xx::laserCheckParams: 8 * 4 * 1000)


def _version(aria: Path) -> str:
    try:
        out = subprocess.run(["git", "-C", str(aria), "describe", "--always", "--tags", "--dirty"],
                             capture_output=True, text=True, timeout=10, check=True).stdout.strip()
        date = subprocess.run(["git", "-C", str(aria), "log", "-1", "--format=%cs"], capture_output=True,
                              text=True, timeout=10, check=True).stdout.strip()
        return f"{out} ({date})"
    except (OSError, subprocess.SubprocessError):
        return "unknown version (not a git checkout)"


def _run(program: Path, aria: Path, source, increment: str, seconds: float) -> tuple[str, list[int], list[int]]:  # noqa: ANN001
    """Serve the robot and the laser, run `program` with ARIA's laser options for `seconds` (or until it
    exits); its output, the laser emulator's requests and baud switches."""
    robot = P3DXEmulator("dense", port=0).start()
    laser = LMS2xxEmulator(source, pty=True, boot_time=1.0).start()
    port = robot.address.rsplit(":", 1)[1]
    cmd = [str(program), "-remoteHost", "127.0.0.1", "-remoteRobotTcpPort", port, "-remoteIsNotSim",
           "-laserType", "lms2xx", "-laserPortType", "serial", "-laserPort", laser.address, "-connectLaser",
           "-laserDegrees", "180", "-laserIncrement", increment, "-laserUnits", "1mm", "-laserAutoBaud", "38400"]
    print("running:", " ".join(cmd))
    env = dict(os.environ, LD_LIBRARY_PATH=str(aria / "lib"))
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env, cwd=str(aria))
    try:
        try:
            out, _ = proc.communicate(timeout=seconds)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGINT)
            try:
                out, _ = proc.communicate(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                out, _ = proc.communicate()
        return out, list(laser.requests), list(laser.baud_log)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        laser.close()
        robot.close()


def _expected(source, increment: str, pose: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """Beam angles on the robot [deg] and ranges [mm] (inf: no echo) as the ScanSource has them."""
    step = 1.0 if increment == "one" else 0.5
    beams = 181 if increment == "one" else 361
    angles = -90.0 + step * np.arange(beams)
    ranges = source(np.radians(angles), 32.0) * 1000
    return angles + pose[2], ranges


def main() -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("aria", type=Path, help="AriaCoda checkout with lib/libAria.so and examples/lasers built")
    parser.add_argument("--increment", choices=["one", "half"], default="one")
    parser.add_argument("--wall", type=float, default=2.0, help="[m] wall distance from the sensor (0.5..7)")
    parser.add_argument("--normal", type=float, default=20.0, help="[deg] wall normal in the sensor frame (-60..60)")
    parser.add_argument("--seconds", type=float, default=8.0, help="how long to let the lasers example run")
    args = parser.parse_args()
    aria = args.aria.resolve()
    example, lib = aria / "examples" / "lasers", aria / "lib"
    if not (example.is_file() and os.access(example, os.X_OK) and (lib / "libAria.so").exists()
            and (aria / "include" / "Aria" / "Aria.h").is_file()):
        print(f"aria_lms2xx_peer: {aria}: no built examples/lasers, lib/libAria.so and include/Aria; build "
              "AriaCoda (make lib/libAria.so examples/lasers) and give its directory", file=sys.stderr)
        return 2
    if not (0.5 <= args.wall <= 7.0 and -60 <= args.normal <= 60 and args.seconds >= 4):
        print("aria_lms2xx_peer: --wall must be 0.5..7 m, --normal -60..60 deg, --seconds >= 4", file=sys.stderr)
        return 2
    print("ARIA:", _version(aria))
    source = wall(args.wall, args.normal)
    beams = 181 if args.increment == "one" else 361
    problems: list[str] = []

    # 1. the shipped example
    out, requests, baud_log = _run(example, aria, source, args.increment, args.seconds)
    print("emulator saw requests", " ".join(f"{r:02X}" for r in requests), "| baud switches", baud_log)
    pose_m = re.search(r"laser #1: pose=\(x:(-?\d+), y:(-?\d+), z:-?\d+, th:(-?[\d.]+)\)", out)
    counts = [(int(m.group(1)), int(m.group(2))) for m in re.finditer(
        r"Have (\d+) 'current' readings.\s*Have (\d+) 'raw' readings", out)]
    pose = (0.0, 0.0, 0.0)
    if pose_m is None:
        problems.append("lasers: ARIA printed no laser pose")
    else:
        pose = (int(pose_m.group(1)) / 1000, int(pose_m.group(2)) / 1000, float(pose_m.group(3)))
    if "Connected to all lasers" not in out or not counts:
        problems.append("lasers: ARIA did not connect the laser or printed no readings")
    if 38400 not in baud_log:
        problems.append("lasers: ARIA did not switch the LMS to 38400 baud")
    _, want = _expected(source, args.increment, pose)
    echoes = int(np.sum(want <= ARIA_MAX_MM))
    for current, raw in counts:
        print(f"lasers: {raw} raw readings (variant: {beams}), {current} current (ScanSource echoes: {echoes})")
        if raw != beams or current != echoes:
            problems.append(f"lasers: {raw} raw / {current} current readings, expected {beams} / {echoes}")
    if problems:
        print("lasers output:\n" + out[-3000:])

    # 2. every raw reading, through a client built against this ARIA
    with tempfile.TemporaryDirectory(prefix="aria_lms2xx_") as tmp:
        src, exe = Path(tmp) / "lms2xx_dump.cpp", Path(tmp) / "lms2xx_dump"
        src.write_text(DUMP_CPP)
        build = subprocess.run(["g++", "-std=c++14", "-O1", f"-I{aria / 'include'}", str(src), "-o", str(exe),
                                f"-L{lib}", "-lAria", "-lpthread", "-ldl", "-lrt"], capture_output=True, text=True,
                               timeout=300)
        if build.returncode != 0:
            problems.append("dump: could not build the ARIA client: " + build.stderr.strip()[-500:])
            out = ""
        else:
            out, _, _ = _run(exe, aria, source, args.increment, 30.0)
    scans = re.split(r"DUMP scan \d+ readings -?\d+\n", out)[1:]
    if not scans:
        problems.append("dump: no scans from ARIA")
        print("dump output:\n" + out[-3000:])
    angles, ranges = _expected(source, args.increment, pose)
    for i, text in enumerate(scans):
        got = np.array([[float(a), float(r)] for a, r in re.findall(r"DUMP reading (-?[\d.]+) (\d+)", text)])
        if got.shape != (beams, 2):
            problems.append(f"dump: scan {i} has {len(got)} readings, expected {beams}")
            continue
        angle_err = float(np.max(np.abs(got[:, 0] - angles)))
        echo = ranges <= ARIA_MAX_MM
        range_err = float(np.max(np.abs(got[echo, 1] - ranges[echo]))) if echo.any() else 0.0
        missing = int(np.sum(got[~echo, 1] <= ARIA_MAX_MM))
        print(f"dump: scan {i}: {beams} readings; angle error {angle_err:.3f} deg, range error {range_err:.2f} mm "
              f"over {int(echo.sum())} echoes, {missing} of {int((~echo).sum())} no-echo beams read as echoes")
        if angle_err > 0.01 or range_err > 1.0 or missing:
            problems.append(f"dump: scan {i} differs from the ScanSource")
    if problems:
        for p in sorted(set(problems)):
            print("FAIL:", p)
        return 1
    print(f"OK: AriaCoda {_version(aria)} ArLMS2xx read the emulator as the ScanSource has it "
          f"({len(counts)} reports of the lasers example, {len(scans)} scans of {beams} readings dumped)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
