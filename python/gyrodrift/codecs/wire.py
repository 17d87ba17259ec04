"""Whole-record serial frames for the replay harness: wire-typed samples, encoding (through
gyrodrift.codecs.encode_frames) and a stream decoder that also reports where each frame ended
in the stream (the harness needs that to time each output's arrival).

The frame layout, constants, numpy dtype and CRC all come from gyrodrift.codecs.serial_frame
(the single source of truth for the wire format); only the vectorised whole-stream decoder
with end offsets lives here. The tests check it against gyrodrift.codecs.FrameParser and
hand-checked bytes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from gyrodrift.codecs import serial_frame
from gyrodrift.codecs.serial_frame import (
    CRC_OFFSET,
    FRAME_DTYPE,
    FRAME_SIZE,
    PAYLOAD_LEN,
    SYNC0,
    SYNC1,
    TYPE_INPUT,
    crc16_ccitt_false,
)
from gyrodrift.errors import GyrodriftValueError

if TYPE_CHECKING:
    from gyrodrift.io.imu_log import CanLogReport

__all__ = [
    "DecodedStream",
    "Samples",
    "StreamDecoder",
    "decode_stream",
    "encode_frames",
    "make_samples",
]

_SYNC_WORD = bytes((SYNC0, SYNC1))


@dataclass
class Samples:
    """A record of IMU samples as carried on the wire (float32 channels).

    Examples
    --------
    >>> s = make_samples(np.array([0.0, 0.0025]), np.zeros((2, 3)), np.zeros((2, 3)))
    >>> len(s), s.t_s, s.channels.dtype
    (2, array([0.    , 0.0025]), dtype('float32'))
    >>> s.take(np.array([1])).seq
    array([1], dtype=uint16)
    """

    seq: np.ndarray  # (n,) uint16
    flags: np.ndarray  # (n,) uint16
    t_us: np.ndarray  # (n,) uint64
    channels: np.ndarray  # (n, 6) float32: gyro x y z rad/s, accel x y z m/s^2
    # How a CAN log was read (every frame accounted for); None for other sources.
    log_report: CanLogReport | None = None

    def __len__(self) -> int:
        return int(self.seq.shape[0])

    @property
    def t_s(self) -> np.ndarray:
        return self.t_us.astype(np.float64) * 1e-6

    def take(self, index: np.ndarray) -> Samples:
        return Samples(self.seq[index], self.flags[index], self.t_us[index],
                       self.channels[index])


def make_samples(t_s: np.ndarray, gyro_rad_s: np.ndarray, accel_m_s2: np.ndarray,
                 seq0: int = 0) -> Samples:
    """Validate a record and give it wire types: seq counts from seq0 and wraps at 65536.

    Examples
    --------
    >>> s = make_samples(np.arange(3) / 400.0, np.zeros((3, 3)), np.tile([0.0, 0.0, 9.8], (3, 1)),
    ...                  seq0=65535)
    >>> s.seq.tolist(), s.t_us.tolist(), s.seq.dtype, s.t_us.dtype, s.channels.dtype
    ([65535, 0, 1], [0, 2500, 5000], dtype('uint16'), dtype('uint64'), dtype('float32'))
    >>> round(float(s.channels[0, 5]), 6)  # 9.8 rounded to float32
    9.8
    """
    t_s = np.asarray(t_s, dtype=np.float64)
    gyro = np.asarray(gyro_rad_s, dtype=np.float64)
    accel = np.asarray(accel_m_s2, dtype=np.float64)
    if t_s.ndim != 1 or t_s.size == 0:
        raise GyrodriftValueError(f"t_s: expected a non-empty 1-D array, got shape {t_s.shape}")
    n = t_s.shape[0]
    for name, arr in (("gyro_rad_s", gyro), ("accel_m_s2", accel)):
        if arr.shape != (n, 3):
            raise GyrodriftValueError(f"{name}: expected shape ({n}, 3), got {arr.shape}")
    if not np.all(np.isfinite(t_s)):
        raise GyrodriftValueError("t_s: non-finite timestamp")
    if t_s[0] < 0 or np.any(np.diff(t_s) < 0):
        raise GyrodriftValueError("t_s: timestamps must be >= 0 and non-decreasing")
    seq = ((np.arange(n, dtype=np.int64) + seq0) % 65536).astype(np.uint16)
    t_us = np.round(t_s * 1e6).astype(np.uint64)
    channels = np.concatenate([gyro, accel], axis=1).astype(np.float32)
    return Samples(seq, np.zeros(n, np.uint16), t_us, channels)


def encode_frames(samples: Samples, frame_type: int = TYPE_INPUT) -> np.ndarray:
    """All samples as serial frames: an (n, 42) uint8 array (row i = frame i).

    Examples
    --------
    >>> s = make_samples(np.arange(3) / 400.0, np.zeros((3, 3)), np.zeros((3, 3)))
    >>> encode_frames(s).shape
    (3, 42)
    """
    raw = serial_frame.encode_frames(samples.seq, samples.t_us, samples.channels,
                               frame_type=frame_type, flags=samples.flags)
    return np.frombuffer(raw, dtype=np.uint8).reshape(len(samples), FRAME_SIZE)


@dataclass
class DecodedStream:
    """Frames found in a byte stream, in arrival order, and what had to be skipped.

    Examples
    --------
    >>> s = make_samples(np.arange(3) / 400.0, np.zeros((3, 3)), np.zeros((3, 3)))
    >>> dec = decode_stream(b"junk" + encode_frames(s).tobytes())
    >>> dec.samples.seq, dec.garbage_bytes, dec.end_offset
    (array([0, 1, 2], dtype=uint16), 4, array([ 46,  88, 130]))
    """

    frame_type: np.ndarray  # (m,) uint8
    samples: Samples
    end_offset: np.ndarray  # (m,) offset in the stream one past each frame's last byte
    crc_errors: int = 0
    garbage_bytes: int = 0
    truncated_bytes: int = 0


def decode_stream(data: bytes) -> DecodedStream:
    """Find every valid frame in a byte stream (resynchronising on the sync word): a frame
    is accepted where sync, length and CRC check; elsewhere the search moves to the next
    sync word. The accepted frames are then decoded together with numpy. (One
    :class:`StreamDecoder` fed the whole stream.)

    Examples
    --------
    >>> s = make_samples(np.arange(3) / 400.0, np.zeros((3, 3)), np.zeros((3, 3)))
    >>> raw = bytearray(encode_frames(s).tobytes())
    >>> raw[42 + 10] ^= 0xFF  # the second frame's CRC fails
    >>> dec = decode_stream(bytes(raw[:-5]))  # and the third is cut short
    >>> dec.samples.seq, dec.crc_errors, dec.truncated_bytes
    (array([0], dtype=uint16), 1, 37)
    """
    return StreamDecoder().feed(data, final=True)


class StreamDecoder:
    """:func:`decode_stream` of a stream given in pieces: every piece's call returns the
    frames completed by it, and the counters (CRC errors, garbage, truncated tail) end
    equal to those of one call on the whole stream, however it is cut. Besides the frames
    it returns, the decoder holds fewer than ``FRAME_SIZE`` bytes between calls.

    Examples
    --------
    >>> s = make_samples(np.arange(3) / 400.0, np.zeros((3, 3)), np.zeros((3, 3)))
    >>> raw = b"junk" + encode_frames(s).tobytes()
    >>> dec = StreamDecoder()
    >>> [dec.feed(raw[k:k + 50]).samples.seq.tolist() for k in range(0, 100, 50)]
    [[0], [1]]
    >>> last = dec.feed(raw[100:], final=True)
    >>> last.samples.seq, last.end_offset, last.garbage_bytes
    (array([2], dtype=uint16), array([130]), 4)
    """

    def __init__(self) -> None:
        self._carry = b""  # the bytes from the resume position on
        self._base = 0  # stream offset of _carry[0]
        # True when the resume position was reached by skipping bytes that hold no sync word
        # (a sync word may start at the last byte of a piece), not yet checked as a frame
        self._unchecked = False
        self._done = False
        self.crc_errors = 0
        self.garbage_bytes = 0
        self.truncated_bytes = 0

    def feed(self, data: bytes | bytearray | memoryview, final: bool = False) -> DecodedStream:
        """The frames completed by `data` (end offsets counted from the stream's start),
        with the counters so far; `final`: `data` ends the stream (the truncated tail is
        counted then)."""
        if self._done:
            raise GyrodriftValueError("StreamDecoder: the stream has ended (final=True)")
        buf = self._carry + bytes(data) if self._carry else bytes(data)
        n = len(buf)
        starts: list[int] = []
        i = 0
        while i + FRAME_SIZE <= n:
            self._unchecked = False
            if buf[i] == SYNC0 and buf[i + 1] == SYNC1 and buf[i + 3] == PAYLOAD_LEN:
                crc = buf[i + CRC_OFFSET] | (buf[i + CRC_OFFSET + 1] << 8)
                if crc16_ccitt_false(buf[i + 2:i + CRC_OFFSET]) == crc:
                    starts.append(i)
                    i += FRAME_SIZE
                    continue
                self.crc_errors += 1
            # Not a frame here: skip to the next candidate sync word.
            nxt = buf.find(_SYNC_WORD, i + 1)
            if nxt < 0 and not final:
                # none in this piece; one may start at its last byte
                self.garbage_bytes += n - 1 - i
                i = n - 1
                self._unchecked = True
                break
            if nxt < 0 or nxt + FRAME_SIZE > n:
                stop = n if nxt < 0 else nxt
                self.garbage_bytes += stop - i
                i = stop
                break
            self.garbage_bytes += nxt - i
            i = nxt
        if final:
            if self._unchecked:  # the resume position was never checked: search from it
                nxt = buf.find(_SYNC_WORD, i)
                stop = n if nxt < 0 else nxt
                self.garbage_bytes += stop - i
                i = stop
            self.truncated_bytes = n - i
            self._done = True
        idx = np.asarray(starts, dtype=np.int64)
        if idx.size:
            raw = np.frombuffer(buf, dtype=np.uint8)
            rows = raw[idx[:, None] + np.arange(FRAME_SIZE)[None, :]]
            rec = np.ascontiguousarray(rows).view(FRAME_DTYPE).reshape(-1)
        else:
            rec = np.zeros(0, dtype=FRAME_DTYPE)
        samples = Samples(rec["seq"].copy(), rec["flags"].copy(), rec["t_us"].copy(),
                          rec["values"].astype(np.float32))
        end = self._base + idx + FRAME_SIZE
        self._carry = buf[i:] if not final else b""
        self._base += i
        return DecodedStream(rec["type"].copy(), samples, end, self.crc_errors,
                             self.garbage_bytes, self.truncated_bytes)
