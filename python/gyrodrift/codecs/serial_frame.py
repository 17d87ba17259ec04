"""Serial IMU frame (42 bytes, little-endian): encoder and resynchronising stream parser.

Twin of include/gyrodrift/codecs/serial_frame.hpp (same layout, same resync rules, same counters).
Layout (offset size field): 0 1 sync0=0xA5 | 1 1 sync1=0x5A | 2 1 type (0x01 input,
0x81 output, 0x02 health request, 0x82 health report) | 3 1 len=36 | 4 2 seq u16 |
6 2 flags u16 | 8 8 t_us u64 | 16 24 6 x float32
(gyro x y z rad/s, accel x y z m/s^2) | 40 2 CRC-16/CCITT-FALSE over bytes 2..39.
A health report is one frame per counter: seq = index, flags = group, t_us = value, the 24
value bytes = the counter's name (NUL-padded ASCII); group 0xFF ends it (t_us = the number of
counter frames before it).
The CRC comes from the standard library (binascii.crc_hqx: poly 0x1021, no reflection;
init 0xFFFF gives CCITT-FALSE), independent of the C++ table implementation.
"""

from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from gyrodrift.errors import GyrodriftValueError

__all__ = [
    "CRC_OFFSET",
    "FRAME_DTYPE",
    "FRAME_SIZE",
    "FRAME_TYPES",
    "PAYLOAD_LEN",
    "SYNC0",
    "SYNC1",
    "TYPE_HEALTH_REPORT",
    "TYPE_HEALTH_REQUEST",
    "TYPE_INPUT",
    "TYPE_OUTPUT",
    "FrameError",
    "FrameParser",
    "ImuFrame",
    "ParserStats",
    "crc16_ccitt_false",
    "decode_frame",
    "encode_frame",
    "encode_frames",
]

SYNC0 = 0xA5
SYNC1 = 0x5A
TYPE_INPUT = 0x01
TYPE_OUTPUT = 0x81
TYPE_HEALTH_REQUEST = 0x02  # asks a target for its health counters
TYPE_HEALTH_REPORT = 0x82  # one counter of the target's answer
FRAME_TYPES = (TYPE_INPUT, TYPE_OUTPUT, TYPE_HEALTH_REQUEST, TYPE_HEALTH_REPORT)
PAYLOAD_LEN = 36
FRAME_SIZE = 42
CRC_OFFSET = 40

_BODY = struct.Struct("<BBBBHHQ6f")  # bytes 0..39
_CRC = struct.Struct("<H")
# numpy view of a frame, for vectorised encoding of whole recordings
FRAME_DTYPE = np.dtype(
    [
        ("sync0", "u1"),
        ("sync1", "u1"),
        ("type", "u1"),
        ("len", "u1"),
        ("seq", "<u2"),
        ("flags", "<u2"),
        ("t_us", "<u8"),
        ("values", "<f4", (6,)),
        ("crc", "<u2"),
    ]
)
assert FRAME_DTYPE.itemsize == FRAME_SIZE


def crc16_ccitt_false(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, xorout 0); check value 0x29B1.

    Examples
    --------
    >>> hex(crc16_ccitt_false(b"123456789"))  # the CRC catalogue's check value
    '0x29b1'
    """
    return binascii.crc_hqx(bytes(data), 0xFFFF)


@dataclass
class ImuFrame:
    """One decoded serial frame: sequence, timestamp (us), six float32 values, type, flags.

    Examples
    --------
    >>> decode_frame(encode_frame(3, 2500, [0.5] * 6))
    ImuFrame(seq=3, t_us=2500, values=(0.5, 0.5, 0.5, 0.5, 0.5, 0.5), frame_type=1, flags=0)
    """
    seq: int
    t_us: int
    values: tuple[float, ...]  # gyro x y z (rad/s), accel x y z (m/s^2), as float32 values
    frame_type: int = TYPE_INPUT
    flags: int = 0


def encode_frame(
    seq: int,
    t_us: int,
    values: npt.ArrayLike,
    *,
    frame_type: int = TYPE_INPUT,
    flags: int = 0,
) -> bytes:
    """One 42-byte frame. values: 6 numbers, stored as float32.

    Examples
    --------
    >>> len(encode_frame(1, 2500, [0.1] * 6))
    42
    """
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    if v.size != 6:
        raise GyrodriftValueError(f"values: expected 6 channels, got {v.size}")
    if frame_type not in FRAME_TYPES:
        raise GyrodriftValueError(f"type: expected 0x01, 0x81, 0x02 or 0x82, got "
                                  f"{frame_type:#x}")
    body = _BODY.pack(
        SYNC0, SYNC1, frame_type, PAYLOAD_LEN, seq & 0xFFFF, flags & 0xFFFF, int(t_us), *v.tolist()
    )
    return body + _CRC.pack(crc16_ccitt_false(body[2:]))


def encode_frames(
    seq: npt.ArrayLike,
    t_us: npt.ArrayLike,
    values: npt.ArrayLike,
    *,
    frame_type: int = TYPE_INPUT,
    flags: npt.ArrayLike = 0,
) -> bytes:
    """n frames back to back (vectorised layout; CRC per frame).

    Examples
    --------
    >>> data = encode_frames([1, 2], [0, 2500], np.zeros((2, 6)))
    >>> len(data), decode_frame(data[FRAME_SIZE:]).t_us
    (84, 2500)
    """
    vals = np.asarray(values, dtype=np.float32)
    if vals.ndim != 2 or vals.shape[1] != 6:
        raise GyrodriftValueError(f"values: expected shape (n, 6), got {vals.shape}")
    n = vals.shape[0]
    rec = np.zeros(n, dtype=FRAME_DTYPE)
    rec["sync0"] = SYNC0
    rec["sync1"] = SYNC1
    rec["type"] = frame_type
    rec["len"] = PAYLOAD_LEN
    rec["seq"] = np.asarray(seq, dtype=np.int64) & 0xFFFF
    rec["flags"] = np.asarray(flags, dtype=np.int64) & 0xFFFF
    rec["t_us"] = np.asarray(t_us, dtype=np.uint64)
    rec["values"] = vals
    raw = rec.view(np.uint8).reshape(n, FRAME_SIZE)
    rec["crc"] = [crc16_ccitt_false(raw[i, 2:CRC_OFFSET].tobytes()) for i in range(n)]
    return rec.tobytes()


class FrameError(GyrodriftValueError):
    """A byte string that is not exactly one valid frame.

    Examples
    --------
    >>> try:
    ...     decode_frame(b"\\x00" * FRAME_SIZE)
    ... except FrameError as exc:
    ...     print(exc, isinstance(exc, ValueError))
    bad sync 0x00 0x00 True
    """


def decode_frame(frame: bytes | bytearray | memoryview) -> ImuFrame:
    """Decodes exactly one frame; raises FrameError with the reason otherwise.

    Examples
    --------
    >>> f = decode_frame(encode_frame(7, 2500, [1.0, 2, 3, 4, 5, 6]))
    >>> f.seq, f.t_us, f.values[:2]
    (7, 2500, (1.0, 2.0))
    """
    b = bytes(frame)
    if len(b) != FRAME_SIZE:
        raise FrameError(f"expected {FRAME_SIZE} bytes, got {len(b)}")
    s0, s1, typ, ln, seq, flags, t_us, *vals = _BODY.unpack_from(b)
    if (s0, s1) != (SYNC0, SYNC1):
        raise FrameError(f"bad sync {s0:#04x} {s1:#04x}")
    if typ not in FRAME_TYPES or ln != PAYLOAD_LEN:
        raise FrameError(f"bad header type={typ:#04x} len={ln}")
    (crc,) = _CRC.unpack_from(b, CRC_OFFSET)
    if crc != crc16_ccitt_false(b[2:CRC_OFFSET]):
        raise FrameError("CRC mismatch")
    return ImuFrame(seq=seq, t_us=t_us, values=tuple(vals), frame_type=typ, flags=flags)


def _valid_header(typ: int, ln: int) -> bool:
    return typ in FRAME_TYPES and ln == PAYLOAD_LEN


def _header_inside(b: bytes | bytearray, avail: int) -> int:
    """Offset (2..41) of the first whole valid header inside the frame at b[0], using no
    byte at or past avail; FRAME_SIZE if none (offset 1 holds sync1, never a sync0)."""
    for k in range(2, min(FRAME_SIZE, avail - 3)):
        if b[k] == SYNC0 and b[k + 1] == SYNC1 and _valid_header(b[k + 2], b[k + 3]):
            return k
    return FRAME_SIZE


@dataclass
class ParserStats:
    """The counters of a :class:`FrameParser`: bytes in, frames decoded, bytes discarded and why.

    Examples
    --------
    >>> p = FrameParser()
    >>> _ = p.feed(b"\\x00" + encode_frame(1, 0, [0.0] * 6))  # one stray byte before the frame
    >>> p.stats.frames_ok, p.stats.garbage_bytes, p.stats.bytes_in
    (1, 1, 43)
    """
    bytes_in: int = 0
    frames_ok: int = 0
    discarded_bytes: int = 0
    garbage_bytes: int = 0
    bad_header: int = 0
    crc_errors: int = 0
    truncated: int = 0


@dataclass
class FrameParser:
    """Stream parser with the C++ parser's rules and counters (unbounded buffer here).

    Invariant: bytes_in == FRAME_SIZE * frames_ok + discarded_bytes + buffered.

    Examples
    --------
    >>> p = FrameParser()
    >>> data = encode_frames([7, 8], [0, 2500], np.ones((2, 6)))
    >>> [f.seq for f in p.feed(data[:50])], [f.seq for f in p.feed(data[50:])]
    ([7], [8])
    """

    stats: ParserStats = field(default_factory=ParserStats)
    _buf: bytearray = field(default_factory=bytearray)

    @property
    def buffered(self) -> int:
        return len(self._buf)

    def feed(self, data: bytes | bytearray | memoryview) -> list[ImuFrame]:
        """Adds bytes and returns every frame completed by them."""
        self._buf += data
        self.stats.bytes_in += len(data)
        out: list[ImuFrame] = []
        while True:
            frame = self._next()
            if frame is None:
                return out
            out.append(frame)

    def finish(self) -> None:
        """End of stream: buffered bytes can no longer complete a frame. A complete frame
        still here failed its CRC while the parser waited for the 3 bytes after it; it is
        settled as _next would settle it (cut short if a whole header lies inside)."""
        if len(self._buf) >= FRAME_SIZE:
            k = _header_inside(self._buf, len(self._buf))
            if k < FRAME_SIZE:
                self.stats.truncated += 1
                self._discard(k)
            else:
                self.stats.crc_errors += 1
                self._discard(FRAME_SIZE)
        if not self._buf:
            return
        if self._buf[0] == SYNC0:
            self.stats.truncated += 1
        else:
            self.stats.garbage_bytes += len(self._buf)
        self._discard(len(self._buf))

    def _discard(self, n: int) -> None:
        del self._buf[:n]
        self.stats.discarded_bytes += n

    def _hunt(self) -> bool:
        b = self._buf
        if len(b) == 1:
            if b[0] == SYNC0:
                return False
            k = 1
        else:
            k = 1
            while k < len(b):
                if b[k] == SYNC0 and (k + 1 == len(b) or b[k + 1] == SYNC1):
                    break
                k += 1
        self.stats.garbage_bytes += k
        self._discard(k)
        return len(self._buf) >= 2

    def _next(self) -> ImuFrame | None:
        while True:
            b = self._buf
            if not b:
                return None
            if len(b) < 2 or b[0] != SYNC0 or b[1] != SYNC1:
                if not self._hunt():
                    return None
                continue
            if len(b) < 4:
                return None
            if not _valid_header(b[2], b[3]):
                self.stats.bad_header += 1
                self._discard(2)
                continue
            if len(b) < FRAME_SIZE:
                return None
            try:
                frame = decode_frame(b[:FRAME_SIZE])
            except FrameError:
                # CRC failed: a whole header anywhere inside (offsets 2..41) means this frame
                # was cut short; resume there. A header at 39..41 ends up to 3 bytes past
                # the frame, so wait for them (counters must not depend on chunking).
                if len(b) < FRAME_SIZE + 3:
                    return None
                k = _header_inside(b, FRAME_SIZE + 3)
                if k < FRAME_SIZE:
                    self.stats.truncated += 1
                    self._discard(k)
                else:
                    self.stats.crc_errors += 1
                    self._discard(FRAME_SIZE)
                continue
            del b[:FRAME_SIZE]
            self.stats.frames_ok += 1
            return frame
