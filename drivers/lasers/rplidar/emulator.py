"""A Slamtec RPLidar A1/A2 emulator: the RPLidar protocol served from a `ScanSource`, on a
pseudo-terminal (as the USB serial adapter) or TCP.

It answers GET_INFO, GET_HEALTH and GET_SAMPLERATE, starts streaming on SCAN / FORCE_SCAN (the
7-byte descriptor, then 5-byte nodes) or EXPRESS_SCAN (84-byte capsules of 32 samples at the
express sample time: an A1 turn of 720 samples, two capsules every 16 ms), stops on STOP and
RESET, and takes SET_MOTOR_PWM. A turn
is `samples` nodes (360 by default: one per degree) at the model's sample time (A1M8: 508 us, so a
turn of 360 takes 0.183 s, 5.5 Hz), sent in pieces of `samples / 18` nodes as they are measured:
each piece is measured by the source when it is sent, at the angles of its nodes.

Emulation choices (documented, not the firmware's): node angles fall exactly on the driver's beams
(a real turn drifts by a fraction of a degree); no echo within 12 m is distance 0 with quality 0,
an echo quality 47; RESET stops the stream without the boot banner a real device prints; DTR (the
A1 adapter's motor line) does not exist on a pseudo-terminal and is not modelled; express samples
carry no angle compensation (dθ = 0) and the working mode of EXPRESS_SCAN is not read. Serving,
transports and fault injection are `robotexp_drivers.emulation.StreamEmulator`'s.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np

from robotexp import ConfigError, ScanSource
from robotexp_drivers.lasers.base import LaserEmulatorBase
from robotexp_drivers.lasers.rplidar import constants as C
from robotexp_drivers.lasers.rplidar.codec import (
    DeviceInfo,
    Health,
    Request,
    RequestDecoder,
    beam_index,
    descriptor,
    encode_capsule,
    encode_scan,
    geometry,
    node_angles_cw,
)

__all__ = ["RPLidarEmulator", "RPLidarModel", "MODELS"]

PIECES_PER_TURN = 18
CAPSULES_PER_STEP = 2       # express: 64 samples a step (16 ms on an A1)


@dataclass(frozen=True)
class RPLidarModel:
    """What an emulated model reports and how it samples."""

    model: int
    firmware: tuple[int, int]
    hardware: int
    sample_us: int          # SCAN mode
    express_us: int
    range_max: float        # [m]


MODELS: dict[str, RPLidarModel] = {
    "A1M8": RPLidarModel(C.A1M8_MODEL, C.A1M8_FIRMWARE, C.A1M8_HARDWARE, C.A1M8_SAMPLE_US, C.A1M8_EXPRESS_US,
                         C.A1_RANGE_MAX_MM / 1000.0),
    "A2M8": RPLidarModel(C.A2M8_MODEL, C.A2M8_FIRMWARE, C.A2M8_HARDWARE, C.A2M8_SAMPLE_US, C.A2M8_EXPRESS_US,
                         C.A1_RANGE_MAX_MM / 1000.0),
}


class RPLidarEmulator(LaserEmulatorBase):
    """Serve an RPLidar measuring with `source` (call `start()`, or use `with`).

    Args:
        source: what the laser sees.
        pty: serve on a pseudo-terminal instead of TCP.
        port: TCP port on `host` (None or 0: any free one; read `address`). Ignored with `pty`.
        host: interface to listen on.
        model: "A1M8" (508 us per sample) or "A2M8" (250 us).
        samples: nodes per turn (a multiple of 18; 360 gives 1 deg).
        speedup: device seconds per wall second.
        serial: the 16-byte serial number GET_INFO reports (default: derived from the model).
        health: what GET_HEALTH reports (default good; a test can set a warning or an error).

    Raises:
        ConfigError: an unknown model, a bad `samples` or speedup.
        OSError: the port cannot be bound.
    """

    label = "rplidar emulator"

    def __init__(self, source: ScanSource, *, pty: bool = False, port: int | None = None, host: str = "127.0.0.1",
                 model: str = "A1M8", samples: int = 360, speedup: float = 1.0, serial: bytes | None = None,
                 health: Health | None = None) -> None:
        if model not in MODELS:
            raise ConfigError(f"rplidar emulator: model must be one of {', '.join(MODELS)}, got {model!r}")
        if samples < PIECES_PER_TURN or samples % PIECES_PER_TURN:
            raise ConfigError(f"rplidar emulator: samples must be a positive multiple of {PIECES_PER_TURN}, "
                              f"got {samples}")
        if not (speedup > 0 and math.isfinite(speedup)):
            raise ConfigError(f"rplidar emulator: speedup must be > 0, got {speedup}")
        self._init_laser(source, speedup)
        self.model = MODELS[model]
        self.samples = samples
        self.serial = serial if serial is not None else bytes(range(self.model.model, self.model.model + 16))
        if len(self.serial) != C.SERIAL_LEN:
            raise ConfigError(f"rplidar emulator: serial must be {C.SERIAL_LEN} bytes, got {len(self.serial)}")
        self.health = health if health is not None else Health(C.HEALTH_GOOD)
        self.requests: list[Request] = []
        self.motor_pwm: int | None = None
        self.turns_sent = 0
        self._decoder = RequestDecoder()
        self._scanning = False
        self._express = False
        self._piece = 0
        self._sample = 0            # express: samples sent since the request
        # express: as many samples a turn as the sample times allow (A1: 720 at 254 us)
        self.express_samples = round(samples * self.model.sample_us / self.model.express_us)
        # the laser-frame angle of each node of a turn, in sweep order
        g = geometry(samples, 0.0, self.model.range_max, 1.0)
        self._angles = g.angles()[beam_index(node_angles_cw(samples), samples)]
        self._open_transport(pty, port, host)

    @property
    def period(self) -> float:
        """One turn [s of device time]."""
        return self.samples * self.model.sample_us * 1e-6

    @property
    def _period(self) -> float:
        if self._express:
            return CAPSULES_PER_STEP * C.EXPRESS_SAMPLES * self.model.express_us * 1e-6 / self.speedup
        return self.period / PIECES_PER_TURN / self.speedup

    @property
    def scanning(self) -> bool:
        """A SCAN stream is running."""
        return self._scanning

    def _on_connect(self) -> None:
        self._scanning = False
        self._decoder = RequestDecoder()

    def _halt(self) -> None:
        self._scanning = False

    def _step(self) -> bytes:
        if not self._scanning:
            return b""
        if self._express:
            return self._capsules()
        per = self.samples // PIECES_PER_TURN
        first = self._piece * per
        measured = self.source(self._angles[first:first + per], self.model.range_max)
        # encode_scan wants a whole turn of ranges by beam: fill only this piece's beams
        ranges = np.full(self.samples, math.inf)
        ranges[beam_index(node_angles_cw(self.samples)[first:first + per], self.samples)] = measured
        self._piece = (self._piece + 1) % PIECES_PER_TURN
        if self._piece == 0:
            self.turns_sent += 1
        return encode_scan(ranges, first=first, count=per)

    def _capsules(self) -> bytes:
        """The next `CAPSULES_PER_STEP` express capsules, measured now; angle compensation 0."""
        n = self.express_samples
        out = bytearray()
        for _ in range(CAPSULES_PER_STEP):
            cw_q6 = np.rint((self._sample + np.arange(C.EXPRESS_SAMPLES)) % n * (C.ANGLE_Q6_TURN / n))
            r = self.source(-np.radians(cw_q6 / C.ANGLE_Q6_PER_DEG), self.model.range_max)
            ok = np.isfinite(r) & (r > 0)
            mm = np.where(ok, np.clip(np.rint(np.where(ok, r, 0.0) * 1000.0), 1, C.EXPRESS_DISTANCE_MAX_MM), 0)
            out += encode_capsule(int(cw_q6[0]), self._sample == 0, mm.astype(np.int64))
            self._sample += C.EXPRESS_SAMPLES
        return bytes(out)

    def _on_bytes(self, data: bytes) -> None:
        for req in self._decoder.feed(data):
            self.requests.append(req)
            self._transmit(self._answer(req))

    def _answer(self, req: Request) -> bytes:
        m = self.model
        if req.cmd == C.CMD_GET_INFO:
            info = DeviceInfo(m.model, m.firmware, m.hardware, self.serial)
            return descriptor(C.DEVINFO_LEN, C.SEND_MODE_SINGLE, C.ANS_TYPE_DEVINFO) + info.encode()
        if req.cmd == C.CMD_GET_HEALTH:
            return descriptor(C.HEALTH_LEN, C.SEND_MODE_SINGLE, C.ANS_TYPE_DEVHEALTH) + self.health.encode()
        if req.cmd == C.CMD_GET_SAMPLERATE:
            return (descriptor(C.SAMPLE_RATE_LEN, C.SEND_MODE_SINGLE, C.ANS_TYPE_SAMPLE_RATE)
                    + struct.pack("<HH", m.sample_us, m.express_us))
        if req.cmd in (C.CMD_SCAN, C.CMD_FORCE_SCAN, C.CMD_EXPRESS_SCAN):
            if self.health.status == C.HEALTH_ERROR:
                return b""                          # a protection stop: no scan until RESET
            self._scanning = True
            self._express = req.cmd == C.CMD_EXPRESS_SCAN
            self._piece = self._sample = 0
            if self._express:
                return descriptor(C.EXPRESS_CAPSULE_LEN, C.SEND_MODE_MULTI, C.ANS_TYPE_MEASUREMENT_CAPSULED)
            return descriptor(C.NODE_LEN, C.SEND_MODE_MULTI, C.ANS_TYPE_MEASUREMENT)
        if req.cmd == C.CMD_STOP:
            self._scanning = False
        elif req.cmd == C.CMD_RESET:
            self._scanning = False
            self.health = Health(C.HEALTH_GOOD)
        elif req.cmd == C.CMD_SET_MOTOR_PWM and len(req.payload) == 2:
            self.motor_pwm = struct.unpack("<H", req.payload)[0]
        return b""
