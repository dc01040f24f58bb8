"""Fuzz and time the ARIA / P3-DX stream decoders (robotexp_drivers.p3dx.codec).

Each stream holds 1..8 valid packets (SIPs, laser, CONFIG, sync replies, SIMSTAT, unknown types,
or client commands) separated by random noise; most streams then get random byte flips, insertions
and deletions, and all are fed in random chunks, then flushed. Reports packets recovered, bytes
dropped, bad checksums/lengths, any exception (there must be none), and, for streams left intact
with header-free noise, any packet lost (there must be none). Then times clean decoding.

Run: python benchmarks/fuzz/fuzz_p3dx.py [--streams 100000] [--seed 0]
Exit status 1 when an exception or a lost packet was found.
"""

from __future__ import annotations

import argparse
import random
import time

from robotexp_drivers.p3dx import codec as k
from robotexp_drivers.p3dx import constants as c
from fuzz_streams import Tally, mutate


def _sip(rng: random.Random) -> k.StandardSip:
    return k.StandardSip(
        moving=rng.random() < 0.5, xpos=rng.randrange(65536), ypos=rng.randrange(65536),
        thpos=rng.randrange(-2048, 2048), left_vel=rng.randrange(-700, 700),
        right_vel=rng.randrange(-700, 700), battery_dv=130, stall_bumpers=rng.randrange(65536),
        flags=rng.randrange(64), compass=rng.randrange(180),
        sonar=tuple((i, rng.randrange(5001)) for i in range(rng.randrange(17))),
        grip_state=0, analog_port=0, analog=0, digin=0xFF, digout=0xFF, battery_x10=130, charge_state=0,
        rot_vel_x10=rng.randrange(-3000, 3000), fault_flags=0, lat_vel=0, temperature=-127, state_of_charge=0)


def _packet_frames(rng: random.Random) -> list[bytes]:
    """A pool of valid robot-to-client packets."""
    pool = [k.encode_packet(_sip(rng)) for _ in range(200)]
    pool += k.encode_laser_scan([rng.randrange(32768) for _ in range(181)])
    pool += k.encode_laser_scan([rng.randrange(32768) for _ in range(181)], extended=False, pose=(1, 2, 3))
    pool += [k.encode_packet(k.mobilesim_config()),
             k.encode_packet(k.SyncReply(2, "MobileSim", "Pioneer", "p3dx")),
             k.encode_packet(k.SyncReply(0)), k.encode_packet(k.SyncReply(1)),
             k.encode_packet(k.SimStat(true_x_mm=1000, true_y_mm=-5, true_th_deg=90)),
             k.encode_packet(k.EncoderPacket(123456, -654321)),
             k.encode_packet(k.UnknownPacket(0xF0, bytes(rng.randrange(256) for _ in range(20))))]
    return pool


def _command_frames(rng: random.Random) -> list[bytes]:
    """A pool of valid client commands."""
    pool = [k.cmd_sync0(), k.cmd_sync1(), k.cmd_sync2(), k.cmd_open(), k.cmd_close(), k.cmd_config(),
            k.cmd_enable(True), k.cmd_sim_laser(), k.cmd_sim_set_pose(1000, -2000, 90), k.cmd_estop(),
            k.encode_command(c.CMD_SIM_MESSAGE, "hello"), k.cmd_sim_lrf(c.CMD_SIM_LRF_ENABLE, 2, 0)]
    pool += [k.cmd_vel(rng.randrange(-2000, 2000)) for _ in range(20)]
    pool += [k.cmd_rvel(rng.randrange(-300, 300)) for _ in range(20)]
    pool += [k.cmd_vel2(rng.randrange(-2000, 2000), rng.randrange(-2000, 2000)) for _ in range(20)]
    return pool


def _noise(rng: random.Random, header_free: bool) -> bytes:
    out = bytearray(rng.randrange(256) for _ in range(rng.randrange(24)))
    if rng.random() < 0.2:
        out += c.HEADER + bytes((rng.randrange(256),))  # a false header
    if header_free:
        for i in range(1, len(out)):
            if out[i - 1] == c.HEADER_0 and out[i] == c.HEADER_1:
                out[i] = 0
    return bytes(out)


def fuzz(streams: int, seed: int) -> int:
    """Run the fuzz loop; print the counts; return the number of problems found."""
    rng = random.Random(seed)
    pools = {"packets": _packet_frames(rng), "commands": _command_frames(rng)}
    reference: dict[str, dict[bytes, list[object]]] = {   # what each pool entry decodes to
        "packets": {f: list(k.PacketDecoder().feed(f)) for f in pools["packets"]},
        "commands": {f: list(k.CommandDecoder().feed(f)) for f in pools["commands"]}}
    tally = Tally(("recovered", "dropped_bytes", "bad_checksums", "bad_lengths", "truncated"))
    t0 = time.perf_counter()
    for n in range(streams):
        kind = "packets" if n % 2 == 0 else "commands"
        mutated = rng.random() < 0.8
        frames = [rng.choice(pools[kind]) for _ in range(rng.randrange(1, 9))]
        stream = bytearray()
        for f in frames:
            stream += _noise(rng, header_free=not mutated) + f
        stream += _noise(rng, header_free=not mutated)
        if mutated:
            mutate(rng, stream)
        dec: k.PacketDecoder | k.CommandDecoder = (k.PacketDecoder() if kind == "packets"
                                                   else k.CommandDecoder())
        out: list[object] = []
        try:
            pos = 0
            while pos < len(stream):
                step = rng.randrange(1, 64)
                out += dec.feed(bytes(stream[pos:pos + step]))
                pos += step
            out += dec.flush()
        except Exception:  # noqa: BLE001 - the fuzzer's job is to report any exception at all
            tally.exception(f"stream {n}", stream)
            continue
        if not mutated:
            # header-free noise around intact packets: every packet must come out, in order
            tally.compare(out, [obj for f in frames for obj in reference[kind][f]])
        tally.totals["recovered"] += len(out)
        tally.add(dec, ("dropped_bytes", "bad_checksums", "bad_lengths", "truncated"))
    elapsed = time.perf_counter() - t0
    return tally.report(f"streams: {streams} in {elapsed:.1f} s (seed {seed})", "packets lost from intact streams")


def throughput(count: int, seed: int) -> None:
    """Time clean decoding of SIP + laser traffic and of a command stream, in 4 KiB reads."""
    rng = random.Random(seed)
    cycle = [k.encode_packet(_sip(rng))] + k.encode_laser_scan([rng.randrange(32768) for _ in range(181)])
    for label, frames, dec in (
            ("robot->client (SIP + 0x61 laser)", cycle, k.PacketDecoder()),
            ("robot->client (SIP only)", cycle[:1], k.PacketDecoder()),
            ("client->robot (commands)", _command_frames(rng), k.CommandDecoder())):
        chunks = [frames[i % len(frames)] for i in range(count)]
        expected = sum(len(type(dec)().feed(f)) for f in chunks)
        data = b"".join(chunks)
        t0 = time.perf_counter()
        got = 0
        for pos in range(0, len(data), 4096):
            got += len(dec.feed(data[pos:pos + 4096]))
        elapsed = time.perf_counter() - t0
        if got != expected:
            raise SystemExit(f"throughput run {label}: decoded {got} packets, expected {expected}")
        print(f"throughput {label}: {got / elapsed:,.0f} packets/s ({len(data) / elapsed / 1e6:.1f} MB/s)")


def main() -> int:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--streams", type=int, default=100_000, help="number of fuzz streams")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--packets", type=int, default=100_000, help="packets per throughput run")
    args = parser.parse_args()
    problems = fuzz(args.streams, args.seed)
    throughput(args.packets, args.seed)
    return 1 if problems else 0


if __name__ == "__main__":
    raise SystemExit(main())
