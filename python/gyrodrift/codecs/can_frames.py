"""CAN encoding of IMU samples through cantools and the project DBC (python-can messages).

Twin of include/gyrodrift/codecs/can_frames.hpp. One sample = 4 classic CAN frames (base+0 GyroXY,
base+1 GyroZ+Seq+Flags, base+2 AccelXY, base+3 AccelZ+Seq+Flags); base 0x100 input,
0x180 filtered output. An XY frame binds to the next Z frame of its pair; halves are joined
by Seq. Accounting invariant: frames_in == foreign_frames + frames_used + frames_dropped
+ pending_frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from typing import Any

import can
import cantools
import numpy as np
import numpy.typing as npt

from gyrodrift.errors import GyrodriftValueError

__all__ = [
    "FRAMES_PER_SAMPLE",
    "INPUT_BASE_ID",
    "OUTPUT_BASE_ID",
    "CanRxStats",
    "CanSample",
    "SampleAssembler",
    "encode_sample",
    "load_dbc",
]

INPUT_BASE_ID = 0x100
OUTPUT_BASE_ID = 0x180
FRAMES_PER_SAMPLE = 4
_ROLE_NAMES = ("GyroXY", "GyroZ", "AccelXY", "AccelZ")


@cache
def load_dbc() -> cantools.database.can.Database:
    """The IMU database shipped in the package (gyrodrift/data/gyrodrift_imu.dbc).

    Examples
    --------
    >>> db = load_dbc()
    >>> [m.name for m in db.messages][:4]
    ['IMU_GyroXY', 'IMU_GyroZ', 'IMU_AccelXY', 'IMU_AccelZ']
    >>> hex(db.get_message_by_name("OUT_GyroXY").frame_id)
    '0x180'
    """
    path = resources.files("gyrodrift") / "data" / "gyrodrift_imu.dbc"
    with resources.as_file(path) as p:
        db = cantools.database.load_file(str(p))
    assert isinstance(db, cantools.database.can.Database)  # a .dbc file is a CAN database
    return db


def _prefix(base_id: int) -> str:
    if base_id == INPUT_BASE_ID:
        return "IMU"
    if base_id == OUTPUT_BASE_ID:
        return "OUT"
    raise GyrodriftValueError(f"base_id: expected 0x100 or 0x180, got {base_id:#x}")


def encode_sample(
    seq: int, values: npt.ArrayLike, *, flags: int = 0, base_id: int = INPUT_BASE_ID
) -> list[can.Message]:
    """The four frames of one sample, in transmit order (values stored as float32).

    Examples
    --------
    >>> frames = encode_sample(5, [0.1, 0.2, 0.3, 0.0, 0.0, 9.8])
    >>> [hex(m.arbitration_id) for m in frames], frames[0].dlc
    (['0x100', '0x101', '0x102', '0x103'], 8)
    """
    v = np.asarray(values, dtype=np.float32).reshape(-1)
    if v.size != 6:
        raise GyrodriftValueError(f"values: expected 6 channels, got {v.size}")
    db = load_dbc()
    prefix = _prefix(base_id)
    g = [float(x) for x in v]
    signals = (
        {"GyroX": g[0], "GyroY": g[1]},
        {"GyroZ": g[2], "Seq": seq & 0xFFFF, "Flags": flags & 0xFFFF},
        {"AccelX": g[3], "AccelY": g[4]},
        {"AccelZ": g[5], "Seq": seq & 0xFFFF, "Flags": flags & 0xFFFF},
    )
    out = []
    for role, sig in zip(_ROLE_NAMES, signals, strict=True):
        msg = db.get_message_by_name(f"{prefix}_{role}")
        out.append(
            can.Message(arbitration_id=msg.frame_id, data=msg.encode(sig), is_extended_id=False)
        )
    return out


@dataclass
class CanSample:
    """One reassembled sample: sequence number, flags, and the six channel values.

    Examples
    --------
    >>> CanSample(seq=5, flags=0, values=(0.0,) * 6).seq
    5
    """
    seq: int
    flags: int
    values: tuple[float, ...]  # gyro x y z (rad/s), accel x y z (m/s^2)


@dataclass
class CanRxStats:
    """The receive counters of a :class:`SampleAssembler` (frames in, used, dropped and why).

    Examples
    --------
    >>> asm = SampleAssembler()
    >>> for m in encode_sample(1, [0.0] * 6)[:3]:  # the AccelZ frame never arrives
    ...     _ = asm.push(m)
    >>> asm.finish()
    >>> asm.stats.frames_in, asm.stats.frames_dropped, asm.stats.incomplete_samples
    (3, 3, 1)
    """
    frames_in: int = 0
    frames_used: int = 0
    frames_dropped: int = 0
    foreign_frames: int = 0
    bad_dlc: int = 0
    orphan_frames: int = 0
    duplicate_frames: int = 0
    complete_samples: int = 0
    incomplete_samples: int = 0  # reason "can_incomplete"


@dataclass
class _Slot:
    seq: int
    order: int
    state: list[str] = field(default_factory=lambda: ["", ""])  # "", "ok", "broken"
    held: int = 0
    flags: int = 0
    values: list[float] = field(default_factory=lambda: [0.0] * 6)


@dataclass
class SampleAssembler:
    """Reassembles samples from frames (decoded with cantools); same rules as the C++ one.

    Examples
    --------
    >>> asm = SampleAssembler()
    >>> out = [asm.push(m) for m in encode_sample(5, [0.5, 0.25, 0.125, 0.0, 0.0, 9.75])]
    >>> out[:3], out[3]
    ([None, None, None], CanSample(seq=5, flags=0, values=(0.5, 0.25, 0.125, 0.0, 0.0, 9.75)))
    >>> asm.stats.complete_samples, asm.stats.frames_used
    (1, 4)
    """

    base_id: int = INPUT_BASE_ID
    slots: int = 4
    stats: CanRxStats = field(default_factory=CanRxStats)
    _pending: list[tuple[float, float] | None] = field(default_factory=lambda: [None, None])
    _table: dict[int, _Slot] = field(default_factory=dict)
    _order: int = 0

    def __post_init__(self) -> None:
        _prefix(self.base_id)
        if self.slots < 1:
            raise GyrodriftValueError("slots must be >= 1")

    @property
    def pending_frames(self) -> int:
        return sum(s.held for s in self._table.values()) + sum(p is not None for p in self._pending)

    def push(self, msg: can.Message) -> CanSample | None:
        st = self.stats
        st.frames_in += 1
        fid = msg.arbitration_id
        if msg.is_extended_id or msg.is_remote_frame or not 0 <= fid - self.base_id < 4:
            st.foreign_frames += 1
            return None
        if msg.dlc != 8 or len(msg.data) != 8:
            st.bad_dlc += 1
            st.frames_dropped += 1
            return None
        sig: dict[str, Any] = load_dbc().decode_message(  # type: ignore[assignment]
            fid, bytes(msg.data), decode_choices=False)
        role = fid - self.base_id
        half = role // 2
        axes = ("Gyro", "Accel")[half]
        if role % 2 == 0:
            if self._pending[half] is not None:
                st.orphan_frames += 1
                st.frames_dropped += 1
            self._pending[half] = (float(sig[f"{axes}X"]), float(sig[f"{axes}Y"]))
            return None
        seq = int(sig["Seq"])
        pend = self._pending[half]
        slot = self._table.get(seq)
        if slot is not None and slot.state[half]:
            n = 2 if pend is not None else 1
            st.duplicate_frames += n
            st.frames_dropped += n
            self._pending[half] = None
            return None
        if slot is None:
            if len(self._table) >= self.slots:
                oldest = min(self._table.values(), key=lambda s: s.order)
                self._drop(oldest)
            slot = _Slot(seq=seq, order=self._order)
            self._order += 1
            self._table[seq] = slot
        if pend is not None:
            slot.state[half] = "ok"
            slot.held += 2
            slot.values[3 * half : 3 * half + 3] = [pend[0], pend[1], float(sig[f"{axes}Z"])]
            slot.flags |= int(sig["Flags"])
        else:
            slot.state[half] = "broken"
            slot.held += 1
            st.orphan_frames += 1
        self._pending[half] = None
        if "" in slot.state:
            return None
        if slot.state == ["ok", "ok"]:
            del self._table[seq]
            st.frames_used += FRAMES_PER_SAMPLE
            st.complete_samples += 1
            return CanSample(seq=seq, flags=slot.flags, values=tuple(slot.values))
        self._drop(slot)
        return None

    def finish(self) -> None:
        """End of stream: partial samples and held XY frames are counted as dropped."""
        for slot in list(self._table.values()):
            self._drop(slot)
        for half in (0, 1):
            if self._pending[half] is not None:
                self.stats.orphan_frames += 1
                self.stats.frames_dropped += 1
                self._pending[half] = None

    def _drop(self, slot: _Slot) -> None:
        self.stats.incomplete_samples += 1
        self.stats.frames_dropped += slot.held
        del self._table[slot.seq]
