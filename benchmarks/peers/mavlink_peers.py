"""MAVProxy and a pymavlink ground station against the MAVLink rover emulator, as against ArduPilot Rover.

Usage:
    python benchmarks/peers/mavlink_peers.py VENV [--speedup 1]

VENV is a virtual environment with MAVProxy and pymavlink installed (outside this repository, e.g.
`python3 -m venv VENV && VENV/bin/pip install mavproxy pymavlink`).
The emulator runs here, on UDP; the peers run as VENV's programs:

1. a pymavlink (mavutil) ground station: heartbeat, PARAM_REQUEST_LIST once (every parameter must
   come back on the first request, param_count and indexes consistent), DO_SET_MODE with base mode 0
   (DENIED, as ArduPilot) then GUIDED (ACCEPTED, COMMAND_ACK target ids = ours), arming, GET_HOME_POSITION
   before and after SET_GPS_GLOBAL_ORIGIN (FAILED, then HOME_POSITION), SYS_STATUS bits;
2. MAVProxy (`mavproxy.py --master udpout:...`, commands on its standard input): parameters fetched
   with one PARAM_REQUEST_LIST, `mode GUIDED`, `arm throttle`, `param set`, and `velocity 0 0.4 0`
   (BODY_NED, mask 4039: 0.4 m/s to the right): the rover turns right to face it, then drives that way.

Prints what each peer saw and PASS/FAIL; exits 1 when a check fails, 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from robotexp.world.poses import resolve_pose
from robotexp.robot import Pose
from robotexp.world.builtin import builtin_world
from robotexp_drivers.mavlink import constants as C
from robotexp_drivers.mavlink.emulator import ROVER_PARAMS, MavlinkEmulator

# The ground station, run with VENV's python (its own pymavlink): prints one JSON line.
GCS_SCRIPT = r'''
import json, sys, time
from pymavlink import mavutil
import pymavlink
out = {"pymavlink": getattr(pymavlink, "__version__", "?")}
m = mavutil.mavlink_connection(sys.argv[1], source_system=255, source_component=190)
m.mav.heartbeat_send(6, 8, 0, 0, 0)
hb = m.wait_heartbeat(timeout=5)
out["heartbeat"] = [hb.type, hb.autopilot] if hb else None
def ack(cmd, timeout=3):
    end = time.time() + timeout
    while time.time() < end:
        a = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.5)
        if a is not None and a.command == cmd:
            return [a.result, a.target_system, a.target_component]
    return None
m.mav.param_request_list_send(m.target_system, m.target_component)
params, count, end = {}, None, time.time() + 5
while time.time() < end and (count is None or len(params) < count):
    p = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=0.5)
    if p is not None:
        params[p.param_index] = (p.param_id, p.param_value, p.param_type)
        count = p.param_count
out["param_count"], out["params_received"] = count, len(params)
out["param_indexes_ok"] = sorted(params) == list(range(count or 0))
m.mav.command_long_send(m.target_system, m.target_component, 176, 0, 0, 15, 0, 0, 0, 0, 0)
out["set_mode_base0"] = ack(176)
m.mav.command_long_send(m.target_system, m.target_component, 176, 0, 1, 15, 0, 0, 0, 0, 0)
out["set_mode_guided"] = ack(176)
m.mav.command_long_send(m.target_system, m.target_component, 400, 0, 1, 0, 0, 0, 0, 0, 0)
out["arm"] = ack(400)
m.mav.command_long_send(m.target_system, m.target_component, 410, 0, 0, 0, 0, 0, 0, 0, 0)
out["home_before_origin"] = ack(410)
m.mav.set_gps_global_origin_send(m.target_system, -198697000, -439637000, 800000)
o = m.recv_match(type="GPS_GLOBAL_ORIGIN", blocking=True, timeout=3)
out["origin"] = [o.latitude, o.longitude, o.altitude] if o else None
m.mav.command_long_send(m.target_system, m.target_component, 410, 0, 0, 0, 0, 0, 0, 0, 0)
out["home_after_origin"] = ack(410)
h = m.recv_match(type="HOME_POSITION", blocking=True, timeout=3)
out["home"] = [h.latitude, h.longitude] if h else None
m.mav.request_data_stream_send(m.target_system, m.target_component, 2, 5, 1)
s = m.recv_match(type="SYS_STATUS", blocking=True, timeout=3)
out["sys_status"] = [s.onboard_control_sensors_present, s.onboard_control_sensors_enabled,
                     s.onboard_control_sensors_health] if s else None
print(json.dumps(out))
'''


def check_pymavlink(python: Path, emu: MavlinkEmulator) -> bool:
    port = emu.address.rsplit(":", 1)[1]
    run = subprocess.run([str(python), "-c", GCS_SCRIPT, f"udpout:127.0.0.1:{port}"], capture_output=True, text=True,
                         timeout=60)
    try:
        got = json.loads(run.stdout.strip().splitlines()[-1])
    except (IndexError, json.JSONDecodeError):
        print(f"pymavlink ground station failed:\n{run.stdout[-2000:]}\n{run.stderr[-2000:]}")
        return False
    n = len(ROVER_PARAMS)
    checks = {
        "vehicle heartbeat (GROUND_ROVER, ARDUPILOTMEGA)": got["heartbeat"] == [10, 3],
        f"{n} parameters on the first PARAM_REQUEST_LIST": got["param_count"] == n and got["params_received"] == n
        and got["param_indexes_ok"] and emu.received["PARAM_REQUEST_LIST"] == 1,
        "DO_SET_MODE base mode 0 DENIED, ids filled": got["set_mode_base0"] == [C.MAV_RESULT_DENIED, 255, 190],
        "DO_SET_MODE GUIDED ACCEPTED": got["set_mode_guided"] == [C.MAV_RESULT_ACCEPTED, 255, 190],
        "arm FAILED in GUIDED without a position estimate": got["arm"] == [C.MAV_RESULT_FAILED, 255, 190],
        "GET_HOME_POSITION FAILED without an origin": got["home_before_origin"] == [C.MAV_RESULT_FAILED, 255, 190],
        "SET_GPS_GLOBAL_ORIGIN answered": got["origin"] == [-198697000, -439637000, 800000],
        "HOME_POSITION after the origin": got["home_after_origin"] == [C.MAV_RESULT_ACCEPTED, 255, 190]
        and got["home"] is not None,
        "SYS_STATUS: every sensor present is healthy, geofence healthy (no breach)": got["sys_status"] is not None
        and got["sys_status"][0] & got["sys_status"][2] == got["sys_status"][0] != 0
        and got["sys_status"][2] & C.MAV_SYS_STATUS_GEOFENCE,
    }
    for what, ok in checks.items():
        print(f"  pymavlink {got['pymavlink']}: {what}: {'PASS' if ok else 'FAIL'}")
    return all(checks.values())


def check_mavproxy(mavproxy: Path, emu: MavlinkEmulator, workdir: Path) -> bool:
    port = emu.address.rsplit(":", 1)[1]
    version = subprocess.run([str(mavproxy.parent / "pip"), "show", "MAVProxy"], capture_output=True,
                             text=True).stdout
    version = next((line.split()[-1] for line in version.splitlines() if line.startswith("Version")), "?")
    proc = subprocess.Popen([str(mavproxy), f"--master=udpout:127.0.0.1:{port}", "--default-modules=",
                             "--load-module=param,mode,arm,cmdlong", f"--state-basedir={workdir}",
                             f"--logfile={workdir / 'mav.tlog'}"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, cwd=workdir)
    assert proc.stdin is not None

    def say(cmd: str) -> None:
        assert proc.stdin is not None
        proc.stdin.write(cmd + "\n")
        proc.stdin.flush()

    def wait(cond: object, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if cond():  # type: ignore[operator]
                return True
            time.sleep(0.05)
        return False

    checks: dict[str, bool] = {}
    try:
        checks["MAVProxy connects and fetches parameters with one PARAM_REQUEST_LIST"] = wait(
            lambda: emu.received["PARAM_REQUEST_LIST"] >= 1, 15) and not wait(
            lambda: emu.received["PARAM_REQUEST_LIST"] > 1, 4)
        say("mode GUIDED")
        checks["mode GUIDED"] = wait(lambda: emu.mode == C.ROVER_MODE_GUIDED, 5)
        say("arm throttle")
        checks["arm throttle"] = wait(lambda: emu.armed, 5)
        say("param set WP_PIVOT_ANGLE 50")
        checks["param set"] = wait(lambda: emu.param("WP_PIVOT_ANGLE") == 50.0, 5)
        before = emu.sim.read().pose
        say("velocity 0 0.4 0")                  # BODY_NED: 0.4 m/s to the right
        time.sleep(3.0 / emu.speedup)            # GUID_TIMEOUT: the rover stops 3 s after the target
        wait(lambda: emu.sim.read().velocity.v == 0.0 and emu.sim.read().velocity.w == 0.0, 5)
        after = emu.sim.read().pose
    finally:
        proc.terminate()
        out = proc.communicate(timeout=10)[0]
    turn = math.degrees(math.remainder(after.theta - before.theta, 2 * math.pi))
    moved = math.atan2(after.y - before.y, after.x - before.x)
    off = math.degrees(abs(math.remainder(moved - (before.theta - math.pi / 2), 2 * math.pi)))
    dist = math.hypot(after.x - before.x, after.y - before.y)
    checks[f"velocity 0 0.4 0: turned {turn:.0f} deg (right 90), then drove {dist:.2f} m, {off:.0f} deg off "
           "the target direction"] = -100 < turn < -80 and dist > 0.2 and off < 20
    checks["MAVProxy saw the parameters"] = f"Received {len(ROVER_PARAMS)} parameters" in out
    for what, ok in checks.items():
        print(f"  MAVProxy {version}: {what}: {'PASS' if ok else 'FAIL'}")
    if not all(checks.values()):
        print(out[-3000:])
    return all(checks.values())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("venv", type=Path, help="virtual environment with MAVProxy and pymavlink")
    parser.add_argument("--speedup", type=float, default=1.0, help="emulator speed-up (MAVProxy is real time)")
    a = parser.parse_args()
    python, mavproxy = a.venv / "bin" / "python", a.venv / "bin" / "mavproxy.py"
    if not python.is_file() or not mavproxy.is_file():
        print(f"mavlink_peers: {a.venv} has no bin/python or bin/mavproxy.py: pip install mavproxy pymavlink there",
              file=sys.stderr)
        return 2
    if not (a.speedup > 0 and math.isfinite(a.speedup)):
        print(f"mavlink_peers: --speedup must be > 0, got {a.speedup}", file=sys.stderr)
        return 2
    world = builtin_world("ufmg-static")
    start = resolve_pose(world, "path1", 0.25)[0]
    ok = True
    print("pymavlink ground station (indoor rover: no EKF origin):")
    with MavlinkEmulator(world, pose=start, speedup=a.speedup) as emu:
        ok &= check_pymavlink(python, emu)
    print("MAVProxy (EKF origin set, as outdoors):")
    with tempfile.TemporaryDirectory(prefix="robotexp-mavproxy-") as workdir, MavlinkEmulator(
            world, pose=Pose(start.x, start.y, math.pi / 2), speedup=a.speedup, origin=C.DEFAULT_ORIGIN) as emu:
        ok &= check_mavproxy(mavproxy, emu, Path(workdir))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
