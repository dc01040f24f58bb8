"""ARCOS motion commands (MOVE, HEAD, DHEAD, SETV/SETRV, SETA/SETRA) and p3dx.p's sonar poses.

Byte vectors are framed by hand with aria-sip.md §2.1 (checksum = sum of the big-endian words of
ID + DATA) and §2.2 (0x3B positive int, 0x1B negative int, uint16 LE magnitude); the profiles
are checked against the trapezoid computed by hand.
"""

from __future__ import annotations

import math
import socket
import time
from typing import Any

import numpy as np
import pytest

from robotexp.robot import Pose
from robotexp.sim import LaserConfig
from robotexp.sim.presets import P3DX_SONAR_ARIA
from robotexp.world.model import World, segment_box
from robotexp_drivers.p3dx import codec as k
from robotexp_drivers.p3dx import constants as c
from robotexp_drivers.p3dx.emulator import P3DXEmulator
from robotexp_drivers.p3dx.motion import ArcosMotion, RotMode, TransMode, approach

# (command, argument) -> the bytes on the wire (§2.1 / §2.2 by hand)
MOVE_500 = bytes.fromhex("FAFB06083BF401FC3C")       # 0x083B + 0xF401 = 0xFC3C
MOVE_M300 = bytes.fromhex("FAFB06081B2C01341C")      # 0x081B + 0x2C01 = 0x341C
HEAD_M45 = bytes.fromhex("FAFB060C1B2D00391B")       # aria-sip.md §2.1 worked example
DHEAD_90 = bytes.fromhex("FAFB060D3B5A00673B")       # 0x0D3B + 0x5A00 = 0x673B
SETA_500 = bytes.fromhex("FAFB06053BF401F93C")       # 0x053B + 0xF401 = 0xF93C
SETA_M200 = bytes.fromhex("FAFB06051BC800CD1B")      # 0x051B + 0xC800 = 0xCD1B
SETV_200 = bytes.fromhex("FAFB06063BC800CE3B")       # 0x063B + 0xC800 = 0xCE3B
SETRA_50 = bytes.fromhex("FAFB06173B3200493B")       # 0x173B + 0x3200 = 0x493B
SETRV_30 = bytes.fromhex("FAFB060A3B1E00283B")       # 0x0A3B + 0x1E00 = 0x283B
VEL_300 = bytes.fromhex("FAFB060B3B2C01373C")        # §2.1 worked example
RVEL_20 = bytes.fromhex("FAFB06153B1400293B")        # §2.1 worked example
OPEN_CONFIG = bytes.fromhex("FAFB06013B0100023B") + bytes.fromhex("FAFB06123B0100133B")
SPEEDUP = 20.0
HALF = 2.0            # [m] inner half-size of the test room


def test_byte_vectors_are_what_the_codec_frames() -> None:
    assert k.cmd_move(500) == MOVE_500 and k.cmd_move(-300) == MOVE_M300
    assert k.cmd_head(-45) == HEAD_M45 and k.cmd_dhead(90) == DHEAD_90
    assert k.cmd_seta(500) == SETA_500 and k.cmd_seta(-200) == SETA_M200
    assert k.cmd_setv(200) == SETV_200 and k.cmd_setra(50) == SETRA_50 and k.cmd_setrv(30) == SETRV_30
    cmds = k.CommandDecoder().feed(MOVE_M300 + SETA_M200 + HEAD_M45)
    assert [(x.cmd, x.arg) for x in cmds] == [(c.CMD_MOVE, -300), (c.CMD_SETA, -200), (c.CMD_HEAD, -45)]


def _run(m: ArcosMotion, seconds: float, head: float = 0.0,
         dt: float = 0.1) -> tuple[list[float], list[float], float, float]:
    """Integrate the controller alone (a perfect robot) from `head` [deg]; returns speeds, rates,
    distance and the final heading."""
    v = w = dist = 0.0
    vs, ws = [], []
    for _ in range(round(seconds / dt)):
        v, w = m.step(v, w, head, dt)
        dist += v * dt
        head += w * dt
        m.travelled(v * dt)
        vs.append(v)
        ws.append(w)
    return vs, ws, dist, head


def test_move_is_a_trapezoid_under_the_accelerations() -> None:
    # MOVE 500 at 300 mm/s^2 both ways, 1200 mm/s max: a triangle with its peak at sqrt(a d) = 387 mm/s,
    # done in 2 sqrt(d / a) = 2.58 s (plus the 0.1 s steps)
    m = ArcosMotion(1200, 300, 300, 300, 100, 100)
    m.move(500)
    vs, _, dist, _ = _run(m, 4.0)
    assert dist == pytest.approx(500.0, abs=c.DIST_CONV_FACTOR)
    assert max(vs) <= math.sqrt(300 * 500) + 1e-9 and max(vs) > 0.9 * math.sqrt(300 * 500)
    assert all(abs(b - a) <= 300 * 0.1 + 1e-9 for a, b in zip(vs, vs[1:], strict=False))
    t_done = next(i for i, v in enumerate(vs) if i > 5 and v == 0.0) * 0.1
    assert 2.5 <= t_done <= 3.0
    assert m.move_left == 0.0 and vs[-1] == 0.0            # stops and holds
    # SETV caps the move: 200 mm/s cruise, SETA -600 a harder stop
    m = ArcosMotion(1200, 300, 300, 300, 100, 100)
    m.set_trans_max(200)
    m.set_trans_accel(-600)
    assert (m.trans_accel, m.trans_decel) == (300, 600)
    m.move(-1000)
    vs, _, dist, _ = _run(m, 8.0)
    assert dist == pytest.approx(-1000.0, abs=0.5) and min(vs) == pytest.approx(-200.0)


def test_head_and_dhead_turn_to_the_heading_under_setra() -> None:
    m = ArcosMotion(1200, 300, 300, 300, 100, 100)
    m.head(90)
    _, ws, _, head = _run(m, 4.0)
    assert head == pytest.approx(90.0, abs=0.5)
    assert max(ws) <= math.sqrt(100 * 90) + 1e-9               # triangle peak 94.9 deg/s
    m.delta_head(-120, head)                                   # to -30 deg
    m.set_rot_max(30)
    _, ws, _, head = _run(m, 8.0, head)
    assert head == pytest.approx(-30.0, abs=0.5) and min(ws) == pytest.approx(-30.0)
    # a later RVEL cancels the heading goal; VEL cancels a MOVE
    m.set_rot_vel(10)
    m.move(100)
    m.set_vel(50)
    assert (m.rot_mode, m.trans_mode) == (RotMode.VEL, TransMode.VEL)
    assert m.targets(0.0, 0.1) == (50.0, 10.0)
    m.set_rot_max_dir(-5)                                      # SETRVDIR: clockwise rates capped at 5 deg/s
    m.set_rot_vel(-40)
    assert m.targets(0.0, 0.1) == (50.0, -5.0)


def test_approach_uses_accel_up_and_decel_down() -> None:
    assert approach(0.0, 100.0, 300.0, 600.0, 0.1) == pytest.approx(30.0)
    assert approach(100.0, 0.0, 300.0, 600.0, 0.1) == pytest.approx(40.0)
    assert approach(100.0, -100.0, 300.0, 600.0, 0.1) == pytest.approx(40.0)   # through zero: decelerating
    assert approach(-10.0, -12.0, 300.0, 600.0, 0.1) == -12.0


def _room() -> World:
    t, h = 0.1, HALF + 0.05
    return World("room", np.array([segment_box(-h, -h, h, -h, t), segment_box(-h, h, h, h, t),
                                   segment_box(-h, -h, -h, h, t), segment_box(h, -h, h, h, t)]))


def _session(emu: P3DXEmulator) -> socket.socket:
    host, port = emu.address.split(":")
    sock = socket.create_connection((host, int(port)))
    for seq in ("FAFB03000000", "FAFB03010001", "FAFB03020002"):
        sock.sendall(bytes.fromhex(seq))
        time.sleep(0.02)
    sock.sendall(OPEN_CONFIG)
    return sock


def _sips(sock: socket.socket, dec: k.PacketDecoder, until: object, timeout: float = 10.0) -> k.StandardSip:
    """Read SIPs until `until(sip)` holds; returns that SIP."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        sock.settimeout(max(end - time.monotonic(), 0.01))
        for p in dec.feed(sock.recv(65536)):
            if isinstance(p, k.StandardSip) and until(p):  # type: ignore[operator]
                return p
    raise AssertionError("no such SIP in time")


def _pose(sip: k.StandardSip, start: tuple[int, int]) -> tuple[float, float, float]:
    """(x mm, y mm, th deg) of a SIP relative to the raw position `start` (§5.1's 15-bit unwrapping)."""
    return (k.unwrap_position_delta(start[0], sip.xpos) * c.DIST_CONV_FACTOR,
            k.unwrap_position_delta(start[1], sip.ypos) * c.DIST_CONV_FACTOR,
            math.degrees(sip.thpos * c.ANGLE_CONV_FACTOR))


def test_aria_motion_commands_drive_the_emulator() -> None:
    # ARIA's move(500), setHeading(-45), setDeltaHeading(90) used to leave the pose unchanged
    with P3DXEmulator(_room(), pose=Pose(0.0, 0.0, 0.0), port=0, speedup=SPEEDUP, laser=LaserConfig()) as emu:
        sock = _session(emu)
        dec = k.PacketDecoder(max_count=255)
        first = _sips(sock, dec, lambda s: True)
        origin = (first.xpos, first.ypos)
        sock.sendall(SETA_500 + MOVE_500)
        sip = _sips(sock, dec, lambda s: s.left_vel == 0 and s.right_vel == 0 and _pose(s, origin)[0] > 400)
        x, y, th = _pose(sip, origin)
        assert x == pytest.approx(500.0, abs=2 * c.DIST_CONV_FACTOR) and abs(y) < 1 and th == 0.0
        assert emu.sim.read().true_pose.x == pytest.approx(0.5, abs=1e-3)
        sock.sendall(HEAD_M45)
        sip = _sips(sock, dec, lambda s: s.rot_vel_x10 == 0 and _pose(s, origin)[2] < -40)
        assert _pose(sip, origin)[2] == pytest.approx(-45.0, abs=1.0)
        sock.sendall(SETRV_30 + DHEAD_90)                      # to +45 at no more than 30 deg/s
        rates: list[int] = []
        sip = _sips(sock, dec, lambda s: rates.append(s.rot_vel_x10) or (s.rot_vel_x10 == 0
                                                                         and _pose(s, origin)[2] > 40))
        assert _pose(sip, origin)[2] == pytest.approx(45.0, abs=1.0)
        assert max(rates) == 300                               # ROTVEL x10: capped by SETRV 30
        # a VEL cancels a MOVE in progress
        here = (sip.xpos, sip.ypos)
        sock.sendall(MOVE_M300)
        _sips(sock, dec, lambda s: s.left_vel < -50)
        sock.sendall(bytes.fromhex("FAFB060B3B00000B3B"))     # VEL 0 (0x0B3B + 0x0000)
        sip = _sips(sock, dec, lambda s: s.left_vel == 0 and s.right_vel == 0)
        x, y, _ = _pose(sip, here)
        assert 10 < math.hypot(x, y) < 250 and x < 0 and y < 0   # backwards along 45 deg, stopped short
        sock.sendall(k.cmd_close())
        sock.close()


def test_sonar_from_p3dx_p_poses_reads_a_known_wall() -> None:
    # robot at the centre of a 4 m room facing +x: side sonar 0 sits at y = 136 mm (p3dx.p), so it
    # reads 2000 - 136 = 1864 mm (its nearest ray 0.5 deg off axis: /cos(0.5 deg), still 1864); the
    # old 0.2 m ring read 1800 (64 mm short). Sonar 3 at (166, 27) facing 10 deg: (2000 - 166) /
    # cos(2.5 deg) = 1835.7 mm.
    assert tuple((round(x * 1000), round(y * 1000)) for x, y in P3DX_SONAR_ARIA.origins().tolist()) == tuple(
        p[:2] for p in c.SONAR_POSES)
    assert P3DX_SONAR_ARIA.angles_deg == tuple(p[2] for p in c.SONAR_POSES)
    with P3DXEmulator(_room(), pose=Pose(0.0, 0.0, 0.0), port=0, speedup=SPEEDUP, laser=LaserConfig()) as emu:
        sock = _session(emu)
        sip = _sips(sock, k.PacketDecoder(max_count=255), lambda s: len(s.sonar) == 16)
        sock.sendall(k.cmd_close())
        sock.close()
    sonar = dict(sip.sonar)
    assert sonar[0] == 1864 and sonar[7] == 1864 and sonar[8] == 1864 and sonar[15] == 1864
    assert sonar[3] == round((2000 - 166) / math.cos(math.radians(2.5)))
    assert sonar[12] == round((2000 - 255) / math.cos(math.radians(2.5)))


def test_laser_reaches_as_mobilesims_lms200() -> None:
    # a 13 m corridor end read 32767 (nothing) when the emulated laser stopped at 3 m
    corridor = World("corridor", np.array([segment_box(-1.0, -1.0, 14.0, -1.0, 0.1),
                                           segment_box(-1.0, 1.0, 14.0, 1.0, 0.1),
                                           segment_box(13.05, -1.0, 13.05, 1.0, 0.1),
                                           segment_box(-1.0, -1.0, -1.0, 1.0, 0.1)]))
    with P3DXEmulator(corridor, pose=Pose(0.0, 0.0, 0.0), port=0, speedup=SPEEDUP) as emu:
        assert emu.sim.laser_config.range_max == pytest.approx(32.767)
        ahead = emu.sim.scan().ranges[90]
    assert ahead == pytest.approx(13.0 - 0.018, abs=0.006)       # +-5 mm noise, from LaserX 18 mm


def test_first_session_is_as_quick_as_the_next(cpu_wait: Any) -> None:
    with P3DXEmulator("ufmg-static", port=0, speedup=1.0) as emu:
        waits = []
        for _ in range(2):
            t0, mark = time.monotonic(), cpu_wait.total()
            sock = _session(emu)
            dec = k.PacketDecoder(max_count=255)
            got: list[k.Packet] = []
            while not any(isinstance(p, k.StandardSip) for p in got):
                got += dec.feed(sock.recv(65536))
            waits.append(time.monotonic() - t0 - cpu_wait.since(mark))     # a loaded machine's CPU waits aside
            assert any(isinstance(p, k.ConfigPacket) for p in got)
            sock.sendall(k.cmd_close())
            sock.close()
            time.sleep(0.1)
    assert waits[0] < 0.35 and waits[1] < 0.35, waits


def test_identifies_as_a_real_robot_when_asked() -> None:
    # ARIA uses its simulated laser when SYNC2 says "MobileSim" or CONFIG's serial is "SIM"; a laser
    # emulator on its own port needs the robot to look real
    with P3DXEmulator(_room(), pose=Pose(0.0, 0.0, 0.0), port=0, speedup=SPEEDUP, laser=LaserConfig(),
                      simulator=False) as emu:
        host, port = emu.address.split(":")
        with socket.create_connection((host, int(port))) as sock:
            dec = k.PacketDecoder(max_count=255)
            got: list[k.Packet] = []
            for seq in ("FAFB03000000", "FAFB03010001", "FAFB03020002"):
                sock.sendall(bytes.fromhex(seq))
                got += dec.feed(sock.recv(256))
            sock.sendall(OPEN_CONFIG)
            while not any(isinstance(p, k.ConfigPacket) for p in got):
                got += dec.feed(sock.recv(65536))
            sock.sendall(k.cmd_close())
    sync2 = next(p for p in got if isinstance(p, k.SyncReply) and p.seq == 2)
    cfg = next(p for p in got if isinstance(p, k.ConfigPacket))
    assert sync2.name != "MobileSim" and cfg.serial_number not in ("SIM", "") and cfg.name == sync2.name
