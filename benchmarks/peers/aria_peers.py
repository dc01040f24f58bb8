"""ARIA's own programs drive the P3-DX emulator as they drive MobileSim: wander and gotoActionExample.

Usage:
    python benchmarks/peers/aria_peers.py ARIACODA_DIR [--seconds 30] [--transport tcp|pty|both]

ARIACODA_DIR is a built AriaCoda checkout (lib/libAria.so, examples/wander, examples/gotoActionExample;
`make -j2 lib/libAria.so examples/wander examples/gotoActionExample`). Nothing of it is in this
repository. Each program runs against a `P3DXEmulator` (real time: ARIA's clock is the wall clock)
served on TCP (-remoteHost / -remoteRobotTcpPort) and on a pseudo-terminal (-robotPort); the
emulator's true pose is sampled every 0.1 s and the outcome checked:

- wander, in a closed corridor 3 m wide and 9 m long, starting 1 m from one end facing down it (where
  it used to drive straight into the far wall: reached after ~20 s at 0.4 m/s): no collision, turned
  (heading spread > 90 deg), never past the far wall minus the robot radius, kept moving (path > 5 m);
- gotoActionExample, in an empty 6 x 6 m room, starting at (-2.5, -2.5) facing +x: it drives the
  2.5 m square of its goals (2500, 0), (2500, 2500), (0, 2500), (0, 0) in the odometry frame: the
  corners reached within 0.3 m in order (the program cancels its goal after 30 s, so three corners
  and at least 0.5 m of the last leg), no collision.

- robot.move(500) then setDeltaHeading(90) (a 25-line client of ours, compiled here against the
  checkout: ARIA sends MOVE, then HEAD): the emulator's robot moved 500 +- 10 mm and turned 90 +- 2 deg,
  and ARIA's own pose agrees (it used to stay where it was).

Prints one line per run with the figures and PASS/FAIL; exits 1 when a run fails, 2 on bad input.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from robotexp.robot import Pose
from robotexp.world.model import World, segment_box
from robotexp_drivers.p3dx.emulator import P3DXEmulator

WALL = 0.1          # [m] wall thickness
CORNER_TOL = 0.3    # [m] a gotoActionExample goal counts as reached this close
ARIA_LIB = Path("lib")  # set from the command line: ARIACODA_DIR/lib
CORRIDOR_END = 8.0  # [m] the far wall of the wander corridor (the robot starts at x = 0 facing it)


def closed_box(x0: float, y0: float, x1: float, y1: float, name: str) -> World:
    """A closed rectangle whose inner faces are x0..x1, y0..y1 [m]."""
    h = WALL / 2
    boxes = [segment_box(x0 - h, y0 - h, x1 + h, y0 - h, WALL), segment_box(x0 - h, y1 + h, x1 + h, y1 + h, WALL),
             segment_box(x0 - h, y0 - h, x0 - h, y1 + h, WALL), segment_box(x1 + h, y0 - h, x1 + h, y1 + h, WALL)]
    return World(name, np.array(boxes))


def closed_port() -> int:
    """A local TCP port nobody listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def run_peer(aria: Path, program: str, emu: P3DXEmulator, transport: str, seconds: float,
             extra: list[str]) -> tuple[list[tuple[float, Pose, bool]], str]:
    """Run ARIA's `program` against `emu` for `seconds` (SIGINT then); the sampled (t, true pose, stalled)."""
    if transport == "tcp":
        host, port = emu.address.split(":")
        args = ["-remoteHost", host, "-remoteRobotTcpPort", port]
    else:       # ARIA tries TCP first (localhost:8101 unless -rrtp): point that at a closed port
        args = ["-robotPort", emu.address, "-remoteRobotTcpPort", str(closed_port())]
    env = dict(os.environ, LD_LIBRARY_PATH=str(ARIA_LIB))
    samples: list[tuple[float, Pose, bool]] = []
    stop = threading.Event()

    def sample() -> None:
        t0 = time.monotonic()
        while not stop.is_set():
            s = emu.sim.read()
            samples.append((time.monotonic() - t0, s.true_pose or s.pose, s.stalled))
            stop.wait(0.1)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    exe = aria / "examples" / program if (aria / "examples" / program).exists() else aria / program
    proc = subprocess.Popen([str(exe), *args, *extra], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    try:
        out, _ = proc.communicate(timeout=seconds)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGINT)          # ARIA's own handler: stops and disconnects
        try:
            out, _ = proc.communicate(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, _ = proc.communicate()
    stop.set()
    sampler.join()
    return samples, out


def heading_spread(poses: list[Pose]) -> float:
    """[deg] the range of the unwrapped heading."""
    th = np.unwrap([p.theta for p in poses])
    return math.degrees(float(th.max() - th.min()))


def check_wander(aria: Path, transport: str, seconds: float) -> bool:
    world = closed_box(-1.0, -1.5, CORRIDOR_END, 1.5, "corridor")
    with P3DXEmulator(world, pose=Pose(0.0, 0.0, 0.0), port=0, pty=transport == "pty") as emu:
        emu.start()
        samples, out = run_peer(aria, "wander", emu, transport, seconds, [])
        heads = sum(1 for cmd in emu.commands if cmd.cmd == 12)
        collisions = emu.sim.collisions
    poses = [p for _, p, _ in samples]
    path = sum(a.distance_to(b) for a, b in zip(poses, poses[1:], strict=False))
    spread = heading_spread(poses)
    far = max(p.x for p in poses)
    ok = collisions == 0 and spread > 90 and path > 5.0 and far < CORRIDOR_END - 0.25
    print(f"wander/{transport}: {seconds:g} s, path {path:.2f} m, farthest x {far:.2f} m (wall at {CORRIDOR_END:.2f}), "
          f"heading spread {spread:.0f} deg, HEAD commands {heads}, collisions {collisions}, "
          f"stalled samples {sum(s for _, _, s in samples)}: {'PASS' if ok else 'FAIL'}")
    if not ok:
        print(out[-2000:])
    return ok


def check_goto(aria: Path, transport: str, seconds: float) -> bool:
    world = closed_box(-3.0, -3.0, 3.0, 3.0, "room")
    start = Pose(-2.5, -2.5, 0.0)
    with P3DXEmulator(world, pose=start, port=0, pty=transport == "pty") as emu:
        emu.start()
        samples, out = run_peer(aria, "gotoActionExample", emu, transport, seconds, [])
        collisions = emu.sim.collisions
    corners = [(2.5, 0.0), (2.5, 2.5), (0.0, 2.5), (0.0, 0.0)]
    times: list[float | None] = []
    i = 0
    for t, p, _ in samples:
        if i < len(corners):
            gx, gy = start.x + corners[i][0], start.y + corners[i][1]
            if math.hypot(p.x - gx, p.y - gy) < CORNER_TOL:
                times.append(t)
                i += 1
    reached = len(times)
    poses = [p for _, p, _ in samples]
    path = sum(a.distance_to(b) for a, b in zip(poses, poses[1:], strict=False))
    # the program cancels its goal after 30 s: at 0.4 m/s that is three legs and most of the fourth
    last = poses[-1] if poses else start
    to_home = math.hypot(last.x - start.x, last.y - start.y)
    ok = collisions == 0 and (reached == 4 or (reached == 3 and to_home < 2.5 - 0.5))
    print(f"gotoActionExample/{transport}: {seconds:g} s, corners reached in order {reached}/4 at "
          f"{', '.join(f'{t:.1f}' for t in times if t is not None) or '-'} s, then {to_home:.2f} m from the start "
          f"when it stopped; path {path:.2f} m (square 10.00), collisions {collisions}: {'PASS' if ok else 'FAIL'}")
    if not ok:
        print(out[-2000:])
    return ok


# Our own 25-line ARIA client (compiled against ARIACODA_DIR): robot.move(500), then setDeltaHeading(90),
# each awaited with ARIA's isMoveDone / isHeadingDone; prints ARIA's pose after each.
MOTION_CPP = r"""
#include "Aria/Aria.h"
#include <cstdio>
static void await(ArRobot &robot, bool heading) {
  ArTime t;
  while (t.mSecSince() < 15000) {
    robot.lock();
    bool done = heading ? robot.isHeadingDone() : robot.isMoveDone();
    robot.unlock();
    if (done && t.mSecSince() > 500) break;
    ArUtil::sleep(50);
  }
  ArUtil::sleep(1000);                       // let it settle
  robot.lock();
  printf("pose %.1f %.1f %.1f\n", robot.getX(), robot.getY(), robot.getTh());
  fflush(stdout);
  robot.unlock();
}
int main(int argc, char **argv) {
  Aria::init();
  ArArgumentParser parser(&argc, argv);
  parser.loadDefaultArguments();
  ArRobot robot;
  ArRobotConnector connector(&parser, &robot);
  if (!connector.connectRobot()) { printf("no robot\n"); Aria::exit(1); }
  robot.runAsync(true);
  robot.lock(); robot.enableMotors(); robot.move(500); robot.unlock();
  await(robot, false);
  robot.lock(); robot.setDeltaHeading(90); robot.unlock();
  await(robot, true);
  Aria::exit(0);
}
"""


def check_motion(aria: Path, transport: str, workdir: Path) -> bool:
    exe = workdir / "aria_move_dhead"
    if not exe.exists():
        (workdir / "aria_move_dhead.cpp").write_text(MOTION_CPP)
        build = subprocess.run(["g++", "-std=c++14", "-I", str(aria / "include"), str(workdir / "aria_move_dhead.cpp"),
                                "-L", str(aria / "lib"), "-lAria", "-lpthread", "-ldl", "-lrt", "-o", str(exe)],
                               capture_output=True, text=True)
        if build.returncode:
            print(f"move/dhead/{transport}: cannot build our ARIA client: {build.stderr[-1500:]}: FAIL")
            return False
    world = closed_box(-3.0, -3.0, 3.0, 3.0, "room")
    start = Pose(-1.0, 0.0, 0.0)
    with P3DXEmulator(world, pose=start, port=0, pty=transport == "pty") as emu:
        emu.start()
        samples, out = run_peer(workdir, exe.name, emu, transport, 40.0, [])
        truth = emu.sim.read().true_pose
    aria_poses = [tuple(float(v) for v in line.split()[1:]) for line in out.splitlines() if line.startswith("pose ")]
    moved = math.hypot(truth.x - start.x, truth.y - start.y)
    turned = math.degrees(truth.theta - start.theta)
    ok = (len(aria_poses) == 2 and abs(moved - 0.5) < 0.01 and abs(turned - 90.0) < 2.0
          and abs(aria_poses[0][0] - 500.0) < 10.0 and abs(aria_poses[1][2] - 90.0) < 2.0)
    print(f"move(500) + setDeltaHeading(90)/{transport}: ARIA's poses {aria_poses}; emulator: moved "
          f"{moved * 1000:.1f} mm, turned {turned:.1f} deg: {'PASS' if ok else 'FAIL'}")
    if not ok:
        print(out[-2000:])
    return ok


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("aria", type=Path, help="a built AriaCoda checkout")
    parser.add_argument("--seconds", type=float, default=40.0, help="how long each program runs [s]")
    parser.add_argument("--transport", choices=("tcp", "pty", "both"), default="both")
    parser.add_argument("--only", choices=("wander", "goto", "motion"), default=None, help="run one program only")
    a = parser.parse_args()
    global ARIA_LIB
    ARIA_LIB = a.aria / "lib"
    for prog in ("wander", "gotoActionExample"):
        if not (a.aria / "examples" / prog).is_file() or not (a.aria / "lib" / "libAria.so").is_file():
            print(f"aria_peers: {a.aria}/examples/{prog} or lib/libAria.so missing: build AriaCoda first "
                  f"(make -j2 lib/libAria.so examples/{prog})", file=sys.stderr)
            return 2
    if not a.seconds > 0:
        print(f"aria_peers: --seconds must be > 0, got {a.seconds}", file=sys.stderr)
        return 2
    commit = subprocess.run(["git", "-C", str(a.aria), "log", "-1", "--format=%h %cs"], capture_output=True,
                            text=True).stdout.strip()
    print(f"AriaCoda {commit or '(not a git checkout)'} at {a.aria}")
    ok = True
    with tempfile.TemporaryDirectory(prefix="robotexp-aria-") as tmp:
        for transport in (("tcp", "pty") if a.transport == "both" else (a.transport,)):
            if a.only in (None, "motion"):
                ok &= check_motion(a.aria, transport, Path(tmp))
            if a.only in (None, "wander"):
                ok &= check_wander(a.aria, transport, a.seconds)
            if a.only in (None, "goto"):
                ok &= check_goto(a.aria, transport, 35.0)     # it cancels its goal after 30 s and exits
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
