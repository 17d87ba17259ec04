"""Bulk (whole-record) encoding and decoding of the issue-5 wire formats for the replay harness.

The per-frame codecs live in `gyrodrift.codecs` (owned by the codecs work); the harness needs
to turn a whole record into bytes and back fast enough to drive the loop at >= 200k frames/s,
so it packs with a numpy structured dtype and computes the CRC with `binascii.crc_hqx`
(CRC-16/CCITT-FALSE = crc_hqx with init 0xFFFF). The tests check these against the
per-frame codecs and against hand-checked bytes.

Serial frame (little-endian, 42 bytes): A5 5A | type | len=36 | seq u16 | flags u16 |
t_us u64 | 6 x float32 (gyro x y z rad/s, accel x y z m/s^2) | CRC-16 over bytes 2..39.
CAN (classic, 11-bit): per sample 0x100 GyroXY, 0x101 GyroZ+Seq+Flags, 0x102 AccelXY,
0x103 AccelZ+Seq+Flags (input); 0x180..0x183 the same layout for the filtered output.
"""

from __future__ import annotations

import binascii
from dataclasses import dataclass, field

import numpy as np

SYNC0 = 0xA5
SYNC1 = 0x5A
TYPE_INPUT = 0x01
TYPE_OUTPUT = 0x81
PAYLOAD_LEN = 36
FRAME_LEN = 42
CAN_INPUT_BASE_ID = 0x100
CAN_OUTPUT_BASE_ID = 0x180

FRAME_DTYPE = np.dtype(
    [
        ("sync0", "u1"),
        ("sync1", "u1"),
        ("type", "u1"),
        ("len", "u1"),
        ("seq", "<u2"),
        ("flags", "<u2"),
        ("t_us", "<u8"),
        ("ch", "<f4", (6,)),
        ("crc", "<u2"),
    ]
)
assert FRAME_DTYPE.itemsize == FRAME_LEN

# CAN payloads: two float32, or float32 + seq u16 + flags u16 (little-endian, byte 0 first).
_CAN_PAIR_DTYPE = np.dtype([("a", "<f4"), ("b", "<f4")])
_CAN_TAIL_DTYPE = np.dtype([("a", "<f4"), ("seq", "<u2"), ("flags", "<u2")])


def crc16_ccitt_false(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, xorout 0)."""
    return binascii.crc_hqx(data, 0xFFFF)


@dataclass
class Samples:
    """A record of IMU samples as carried on the wire (float32 channels)."""

    seq: np.ndarray  # (n,) uint16
    flags: np.ndarray  # (n,) uint16
    t_us: np.ndarray  # (n,) uint64
    channels: np.ndarray  # (n, 6) float32: gyro x y z rad/s, accel x y z m/s^2

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
    """Validate a record and give it wire types: seq counts from seq0 and wraps at 65536."""
    t_s = np.asarray(t_s, dtype=np.float64)
    gyro = np.asarray(gyro_rad_s, dtype=np.float64)
    accel = np.asarray(accel_m_s2, dtype=np.float64)
    if t_s.ndim != 1 or t_s.size == 0:
        raise ValueError(f"t_s: expected a non-empty 1-D array, got shape {t_s.shape}")
    n = t_s.shape[0]
    for name, arr in (("gyro_rad_s", gyro), ("accel_m_s2", accel)):
        if arr.shape != (n, 3):
            raise ValueError(f"{name}: expected shape ({n}, 3), got {arr.shape}")
    if not np.all(np.isfinite(t_s)):
        raise ValueError("t_s: non-finite timestamp")
    if t_s[0] < 0 or np.any(np.diff(t_s) < 0):
        raise ValueError("t_s: timestamps must be >= 0 and non-decreasing")
    seq = ((np.arange(n, dtype=np.int64) + seq0) % 65536).astype(np.uint16)
    t_us = np.round(t_s * 1e6).astype(np.uint64)
    channels = np.concatenate([gyro, accel], axis=1).astype(np.float32)
    return Samples(seq, np.zeros(n, np.uint16), t_us, channels)


def encode_frames(samples: Samples, frame_type: int = TYPE_INPUT) -> np.ndarray:
    """All samples as serial frames: an (n, 42) uint8 array (row i = frame i)."""
    n = len(samples)
    rec = np.zeros(n, dtype=FRAME_DTYPE)
    rec["sync0"] = SYNC0
    rec["sync1"] = SYNC1
    rec["type"] = frame_type
    rec["len"] = PAYLOAD_LEN
    rec["seq"] = samples.seq
    rec["flags"] = samples.flags
    rec["t_us"] = samples.t_us
    rec["ch"] = samples.channels
    raw = rec.view(np.uint8).reshape(n, FRAME_LEN)
    body = raw[:, 2:40]
    crc = np.fromiter((binascii.crc_hqx(row.tobytes(), 0xFFFF) for row in body),
                      dtype=np.uint16, count=n)
    rec["crc"] = crc
    return raw


@dataclass
class DecodedStream:
    """Frames found in a byte stream, in arrival order, and what had to be skipped."""

    frame_type: np.ndarray  # (m,) uint8
    samples: Samples
    end_offset: np.ndarray  # (m,) offset in the stream one past each frame's last byte
    crc_errors: int = 0
    garbage_bytes: int = 0
    truncated_bytes: int = 0
    other: dict[str, int] = field(default_factory=dict)


def decode_stream(data: bytes) -> DecodedStream:
    """Find every valid frame in a byte stream (resynchronising on the sync word).

    Fast path: while the stream is frame-aligned, whole runs are checked with numpy; any
    misalignment (garbage, a corrupted length) falls back to a byte-wise sync search.
    """
    buf = memoryview(data)
    n = len(buf)
    starts: list[int] = []
    crc_errors = 0
    garbage = 0
    i = 0
    while i + FRAME_LEN <= n:
        if buf[i] == SYNC0 and buf[i + 1] == SYNC1 and buf[i + 3] == PAYLOAD_LEN:
            crc = buf[40 + i] | (buf[41 + i] << 8)
            if binascii.crc_hqx(buf[i + 2:i + 40], 0xFFFF) == crc:
                starts.append(i)
                i += FRAME_LEN
                continue
            crc_errors += 1
        # Not a frame here: skip to the next candidate sync word.
        nxt = data.find(b"\xa5\x5a", i + 1)
        if nxt < 0 or nxt + FRAME_LEN > n:
            stop = n if nxt < 0 else nxt
            garbage += stop - i
            i = stop
            break
        garbage += nxt - i
        i = nxt
    truncated = n - i
    idx = np.asarray(starts, dtype=np.int64)
    if idx.size:
        raw = np.frombuffer(data, dtype=np.uint8)
        rows = raw[idx[:, None] + np.arange(FRAME_LEN)[None, :]]
        rec = np.ascontiguousarray(rows).view(FRAME_DTYPE).reshape(-1)
    else:
        rec = np.zeros(0, dtype=FRAME_DTYPE)
    samples = Samples(rec["seq"].copy(), rec["flags"].copy(), rec["t_us"].copy(),
                      rec["ch"].astype(np.float32))
    return DecodedStream(rec["type"].copy(), samples, idx + FRAME_LEN, crc_errors, garbage,
                         truncated)


@dataclass
class CanFrame:
    arbitration_id: int
    data: bytes
    timestamp: float = 0.0


def encode_can(samples: Samples, base_id: int = CAN_INPUT_BASE_ID) -> list[tuple[int, bytes]]:
    """Each sample as its 4 classic CAN frames (base+0 .. base+3), in sample order."""
    n = len(samples)
    ch = samples.channels
    pairs_g = np.zeros(n, _CAN_PAIR_DTYPE)
    pairs_g["a"], pairs_g["b"] = ch[:, 0], ch[:, 1]
    tail_g = np.zeros(n, _CAN_TAIL_DTYPE)
    tail_g["a"], tail_g["seq"], tail_g["flags"] = ch[:, 2], samples.seq, samples.flags
    pairs_a = np.zeros(n, _CAN_PAIR_DTYPE)
    pairs_a["a"], pairs_a["b"] = ch[:, 3], ch[:, 4]
    tail_a = np.zeros(n, _CAN_TAIL_DTYPE)
    tail_a["a"], tail_a["seq"], tail_a["flags"] = ch[:, 5], samples.seq, samples.flags
    out: list[tuple[int, bytes]] = []
    for k in range(n):
        out.append((base_id, pairs_g[k].tobytes()))
        out.append((base_id + 1, tail_g[k].tobytes()))
        out.append((base_id + 2, pairs_a[k].tobytes()))
        out.append((base_id + 3, tail_a[k].tobytes()))
    return out


@dataclass
class CanAssembly:
    """Samples assembled from CAN frames, plus what could not be assembled."""

    samples: Samples
    timestamp_s: np.ndarray  # arrival/log time of each sample's last frame
    incomplete: int = 0  # samples with some but not all four frames ("can_incomplete")
    foreign: int = 0  # frames with other IDs or lengths
    orphan_frames: int = 0  # XY frames whose Seq frame never came (sample seq unknown)


def assemble_can(frames: list[CanFrame], base_id: int = CAN_INPUT_BASE_ID) -> CanAssembly:
    """Group frames into samples: XY frame then its Seq frame, gyro half + accel half.

    0x100/0x102 carry no Seq, so each pairs with the Seq frame that follows it; a sample is
    complete when the gyro and the accel half with the same Seq are both present.
    """
    seqs: list[int] = []
    flags: list[int] = []
    chans: list[list[float]] = []
    stamps: list[float] = []
    broken: set[int] = set()  # seqs known to be incomplete (counted once each)
    orphans = 0
    foreign = 0
    pending_xy: list[bytes | None] = [None, None]  # gyro XY, accel XY
    half: dict[int, tuple[int, int, list[float]]] = {}  # seq -> (which half, flags, values)
    for f in frames:
        off = f.arbitration_id - base_id
        if off not in (0, 1, 2, 3) or len(f.data) != 8:
            foreign += 1
            continue
        if off in (0, 2):
            if pending_xy[off // 2] is not None:
                orphans += 1  # an XY frame whose Seq frame never came
            pending_xy[off // 2] = bytes(f.data)
            continue
        which = off // 2
        xy = pending_xy[which]
        pending_xy[which] = None
        tail = np.frombuffer(bytes(f.data), _CAN_TAIL_DTYPE)[0]
        seq = int(tail["seq"])
        if xy is None:
            half.pop(seq, None)
            broken.add(seq)
            continue
        if seq in broken:
            continue
        pair = np.frombuffer(xy, _CAN_PAIR_DTYPE)[0]
        values = [float(pair["a"]), float(pair["b"]), float(tail["a"])]
        other = half.pop(seq, None)
        if other is None or other[0] == which:
            if other is not None:
                broken.add(seq)  # the same half twice: cannot tell which is right
                continue
            half[seq] = (which, int(tail["flags"]), values)
            continue
        gyro, accel = (other[2], values) if other[0] == 0 else (values, other[2])
        seqs.append(seq)
        flags.append(int(tail["flags"]) | other[1])
        chans.append(gyro + accel)
        stamps.append(float(f.timestamp))
    incomplete = len(broken | set(half))
    orphans += sum(x is not None for x in pending_xy)
    ts = np.asarray(stamps, dtype=np.float64)
    samples = Samples(np.asarray(seqs, np.uint16), np.asarray(flags, np.uint16),
                      np.round(ts * 1e6).astype(np.uint64) if ts.size else np.zeros(0, np.uint64),
                      np.asarray(chans, np.float32).reshape(-1, 6))
    return CanAssembly(samples, ts, incomplete, foreign, orphans)
