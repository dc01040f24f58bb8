"""A pure MAVLink codec over pymavlink's generated `ardupilotmega` dialect (MAVLink 2): no I/O.

`MavlinkCodec.feed(bytes)` returns the typed pymavlink messages (`MAVLink_heartbeat_message`, ...)
that the bytes complete; `encode(message)` returns a frame. Framing, CRC_EXTRA checks and field
decoding are pymavlink's (`MAVLink.parse_char` with `robust_parsing`); this layer adds two things:

- nothing escapes: noise becomes counts (`bad_frames`: frames with a bad checksum or header,
  `dropped_bytes`: bytes skipped, `unknown`: frames of ids the dialect lacks, whose checksum
  cannot be checked without their CRC_EXTRA: their bytes are parsed again like a bad frame's);
- resynchronisation: pymavlink consumes a whole frame's worth of bytes when a frame is bad, so a
  start byte in noise (0xFD with a large length) could swallow good frames behind it. After a bad
  frame the codec drops only its first byte and parses the rest again (as pymavlink's own
  `mavutil` does not), so every valid frame embedded in noise is recovered.

MAVLink 1 frames (0xFE) are decoded too; extension fields then read as zero.
"""

from __future__ import annotations

from typing import TypeAlias

from pymavlink.dialects.v20 import ardupilotmega as mavlink

__all__ = ["MavlinkCodec", "Message", "mavlink"]

Message: TypeAlias = mavlink.MAVLink_message
_RESYNC_LENGTH = mavlink.HEADER_LEN_V1 + 2     # pymavlink's idle `expected_length`


class MavlinkCodec:
    """Bytes <-> MAVLink messages for one side of a link (pure; not thread-safe).

    Args:
        system: our MAVLink system id (255: a ground station).
        component: our component id.

    Attributes:
        mav: the pymavlink `MAVLink` object; its `*_encode` methods build messages to `encode()`.
    """

    def __init__(self, system: int, component: int) -> None:
        self.mav = mavlink.MAVLink(None, srcSystem=system, srcComponent=component)
        self.mav.robust_parsing = True
        self.frames = 0          # valid frames decoded
        self.bad_frames = 0      # frames with a bad checksum, length or header
        self.dropped_bytes = 0   # bytes skipped: noise and the first byte of each bad frame
        self.unknown = 0         # valid frames whose id the dialect does not know

    def feed(self, data: bytes) -> list[Message]:
        """Parse `data` (appended to what is buffered) and return the messages it completes.

        Never raises on bad input: see the counters.
        """
        out: list[Message] = []
        m = self.mav.parse_char(data)
        while m is not None:
            if isinstance(m, mavlink.MAVLink_bad_data):
                self._bad(m)
            elif isinstance(m, mavlink.MAVLink_unknown):
                # no CRC_EXTRA to check it with: most such "frames" are noise, so re-parse its bytes
                self.unknown += 1
                self._resync(m.get_msgbuf())
            else:
                self.frames += 1
                out.append(m)
            m = self.mav.parse_char(b"")
        return out

    def _bad(self, m: mavlink.MAVLink_bad_data) -> None:
        data = bytes(m.data)
        if m.reason == "Bad prefix":     # noise up to the next start byte: already skipped
            self.dropped_bytes += len(data)
            return
        self.bad_frames += 1
        self._resync(data)

    def _resync(self, frame: bytes | bytearray) -> None:
        """Skip the start byte of `frame` only and re-parse the rest (a good frame may start inside)."""
        self.dropped_bytes += 1
        rest = bytes(frame[1:]) + bytes(self.mav.buf[self.mav.buf_index:])
        self.mav.buf = bytearray(rest)
        self.mav.buf_index = 0
        self.mav.expected_length = _RESYNC_LENGTH

    def encode(self, message: Message) -> bytes:
        """One MAVLink 2 frame of `message` from our ids, with the next sequence number."""
        frame = bytes(message.pack(self.mav))
        self.mav.seq = (self.mav.seq + 1) % 256
        return frame

    @property
    def buffered(self) -> int:
        """Bytes held for an incomplete frame."""
        return int(self.mav.buf_len())
