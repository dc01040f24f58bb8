"""A robot link is alive only while valid packets come: bytes that are never a packet
lose the robot within its silence time, and a reader thread starved of the interpreter's lock by
our own main thread does not (the data waits in the link). Against the real P3-DX emulator on TCP,
through a proxy that can turn its stream into garbage."""

from __future__ import annotations

import re
import socket
import sys
import threading
import time
from collections.abc import Iterator

import pytest
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.errors import ProtocolError
from robotexp.output.results import read_records
from robotexp.registry import make_emulator
from robotexp_drivers.p3dx.robot import P3DXRobot


VEL_HEADER = b"\xfa\xfb\x06\x0b"      # an ARCOS VEL command: header, byte count 6, command 11


class GarbageProxy:
    """TCP proxy to `target`; once `garbage` is set, the robot's bytes are replaced by bytes that
    never form a valid packet (all byte values but `no_byte`, ARCOS's 0xFA header by default; MAVLink
    frames that start in them fail their CRC) at about 20 kB/s; `garbage_after_vel`: set once the client has
    sent that many ARCOS VEL commands (a run under way: 10 a second of robot time)."""

    def __init__(self, target: tuple[str, int], garbage_after: float | None = None, no_byte: int = 0xFA,
                 garbage_after_vel: int | None = None) -> None:
        self.target = target
        self.no_byte = no_byte
        self.garbage_after = garbage_after
        self.garbage_after_vel = garbage_after_vel
        self.vel_commands = 0
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.garbage = threading.Event()
        self.done = threading.Event()
        self.sent_garbage = 0
        threading.Thread(target=self._run, daemon=True).start()

    def _run(self) -> None:
        client, _ = self.server.accept()
        robot = socket.create_connection(self.target)
        if self.garbage_after is not None:
            threading.Timer(self.garbage_after, self.garbage.set).start()
        threading.Thread(target=self._pump_commands, args=(client, robot), daemon=True).start()
        robot.settimeout(0.01)
        filler = bytes(b for b in range(256) if b != self.no_byte) * 4
        try:
            while not self.done.is_set():
                try:
                    data = robot.recv(4096)
                    if not data:
                        break
                except TimeoutError:
                    data = b""
                if self.garbage.is_set():
                    client.sendall(filler[:200])
                    self.sent_garbage += 200
                elif data:
                    client.sendall(data)
        except OSError:
            pass
        finally:
            client.close()
            robot.close()

    def _pump_commands(self, src: socket.socket, dst: socket.socket) -> None:
        try:
            while data := src.recv(4096):
                self.vel_commands += data.count(VEL_HEADER)
                if self.garbage_after_vel is not None and self.vel_commands >= self.garbage_after_vel:
                    self.garbage.set()
                dst.sendall(data)
        except OSError:
            pass

    def close(self) -> None:
        self.done.set()
        self.server.close()


@pytest.fixture
def emulator() -> Iterator[object]:
    emu = make_emulator("p3dx", "dense", port=0)
    emu.start()
    yield emu
    emu.close()


def _port(emu: object) -> int:
    return int(str(emu.address).rsplit(":", 1)[1])  # type: ignore[attr-defined]


def test_garbage_after_the_handshake_loses_the_robot(emulator):
    proxy = GarbageProxy(("127.0.0.1", _port(emulator)))
    robot = P3DXRobot(f"127.0.0.1:{proxy.port}", silence=0.5)
    try:
        t = robot.wait_until(0.3)          # the stream is alive: robot time advances
        proxy.garbage.set()
        t0 = time.monotonic()
        outcome: list[BaseException | float] = []

        def wait() -> None:
            try:
                outcome.append(robot.wait_until(t + 3600.0))   # forever if any byte counted as life
            except BaseException as exc:   # noqa: BLE001 (handed to the test thread)
                outcome.append(exc)

        waiter = threading.Thread(target=wait, daemon=True)
        waiter.start()
        waiter.join(timeout=5.0)
        assert outcome, "wait_until still waiting 5 s into a garbage stream"
        assert isinstance(outcome[0], ProtocolError), outcome
        assert "no valid SIP" in str(outcome[0]) and "bytes came" in str(outcome[0])
        assert time.monotonic() - t0 < 0.5 + 0.5 and proxy.sent_garbage > 0
        with pytest.raises(ProtocolError):
            robot.read()
    finally:
        robot.close()
        proxy.close()


def test_a_reader_starved_by_the_main_thread_keeps_its_robot(emulator):
    robot = P3DXRobot(emulator.address, silence=0.5)    # type: ignore[attr-defined]
    old = sys.getswitchinterval()
    try:
        t = robot.wait_until(0.2)
        sys.setswitchinterval(5.0)     # the main thread keeps the lock as a long numba kernel would
        t0 = time.perf_counter()
        stalled = robot._last_rx       # noqa: SLF001 (what the reader saw last)
        n = 0
        while time.perf_counter() - t0 < 1.5:
            n += 1
        hogged = time.perf_counter() - t0
        starved = robot._last_rx == stalled
        sys.setswitchinterval(old)
        state = robot.read()           # 3 times the silence limit later: still connected
        after = robot.wait_until(state.time + 0.5)
    finally:
        sys.setswitchinterval(old)
        robot.close()
    assert hogged >= 1.5 and starved, "the reader ran during the hog: the test did not starve it"
    assert after >= t + 0.5


def _lost(robot, error, match=None, timeout=30.0):
    """`robot.read()` raises `error` once garbage alone has come for its silence limit (0.5 s): polled, since a
    loaded machine may run the reader late (it judges silence on its own reads), never longer than `timeout`."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            robot.read()
        except error as exc:
            assert match is None or re.search(match, str(exc)), exc
            return
        assert time.monotonic() < deadline, f"still connected {timeout} s after the garbage began"
        time.sleep(0.05)


def test_a_reader_starved_for_longer_than_silence_then_fed_nothing_is_still_lost(emulator):
    # the other side of the rule: once the reader runs again and nothing comes, the robot is lost
    proxy = GarbageProxy(("127.0.0.1", _port(emulator)))
    robot = P3DXRobot(f"127.0.0.1:{proxy.port}", silence=0.5)
    try:
        robot.wait_until(0.2)
        proxy.garbage.set()
        _lost(robot, ProtocolError)
    finally:
        robot.close()
        proxy.close()


def test_a_run_ended_by_a_robot_error_exits_1_with_its_record(emulator, tmp_path):
    # the garbage begins 2 s into the run (20 VEL commands), not 2 s after connecting: on a loaded machine the
    # kernels' warm-up before the robot moves may take longer, and a link lost before the run has no record
    proxy = GarbageProxy(("127.0.0.1", _port(emulator)), garbage_after_vel=20)
    try:
        result = CliRunner().invoke(main, ["explore", "--address", f"127.0.0.1:{proxy.port}", "--world", "dense",
                                           "--max-time", "600", "--out", str(tmp_path)])
    finally:
        proxy.close()
    assert result.exit_code == 1, result.output
    assert "robotexp: error: " in result.output and "no valid SIP" in result.output
    (rec,) = read_records(tmp_path / "results.jsonl")
    assert rec.reason.startswith("robot error") and "no valid SIP" in rec.reason


def test_mavlink_garbage_after_the_handshake_loses_the_vehicle():
    from robotexp.world.builtin import builtin_world
    from robotexp.world.poses import resolve_pose
    from robotexp_drivers.mavlink.emulator import MavlinkEmulator
    from robotexp_drivers.mavlink.robot import ROVER_RADIUS, MavlinkRobot

    world = builtin_world("ufmg-static")
    with MavlinkEmulator(world, pose=resolve_pose(world, "path1", ROVER_RADIUS)[0], speedup=10.0, tcp=True) as emu:
        proxy = GarbageProxy(("127.0.0.1", int(emu.address.rsplit(":", 1)[1])), no_byte=-1)
        robot = MavlinkRobot(f"tcp:127.0.0.1:{proxy.port}", timeout=0.5)
        try:
            robot.read()
            proxy.garbage.set()
            _lost(robot, ProtocolError, match="no valid message from the vehicle")
        finally:
            robot.close()
            proxy.close()


def test_a_handshake_read_starved_past_its_deadline_still_reads_once():
    # the handshakes (lms2xx, hokuyo, rplidar, p3dx) read for their replies in `reads_until` turns: a thread that
    # only runs again after the deadline (the loop `while time.monotonic() < deadline` then read nothing and
    # failed with the reply waiting: the LMS2xx test under load) reads once more
    from robotexp_drivers.backend import reads_until

    now = [10.0]
    starts = []
    for _ in reads_until(1.0, clock=lambda: now[0]):
        starts.append(now[0])
    assert starts == [10.0]                      # woke up 9 s late: one read, started after the deadline
    now[0] = 0.0
    starts.clear()
    for _ in reads_until(1.0, clock=lambda: now[0]):
        starts.append(now[0])
        now[0] += 0.4
    assert starts == pytest.approx([0.0, 0.4, 0.8, 1.2])   # while before the deadline, then one after it
