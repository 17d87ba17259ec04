"""Fault injection for replays: which samples are dropped, corrupted, duplicated, reordered
or delayed, decided up front from a seeded generator so a run is reproducible and the
expected effect on the loop can be computed before anything is sent.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from gyrodrift.errors import GyrodriftValueError

__all__ = [
    "FAULT_KINDS",
    "FaultSpec",
    "TransmissionPlan",
    "Unit",
    "corrupt_serial_frame",
    "corrupt_slcan_line",
    "plan_transmission",
]

FAULT_KINDS: tuple[str, ...] = ("drop", "corrupt", "duplicate", "reorder", "delay")


@dataclass(frozen=True)
class FaultSpec:
    """Per-sample fault probabilities (each in [0, 1], their sum <= 1) and parameters.

    Attributes
    ----------
    drop
        the sample is never sent (the loop sees a sequence gap).
    corrupt
        one bit of the sample is flipped on the wire (serial: a payload byte, so the
        CRC fails; SLCAN: a hex digit of the GyroZ line becomes non-hex, as a line error).
    duplicate
        the sample is sent twice in a row.
    reorder
        the sample is swapped with the next one.
    delay
        the sample is sent `delay_s` later than its timestamp says (after later samples).

    Examples
    --------
    >>> spec = FaultSpec(drop=0.1, corrupt=0.05, seed=3)
    >>> spec.any, spec.to_dict()["drop"]
    (True, 0.1)
    >>> FaultSpec(drop=0.7, corrupt=0.7)
    Traceback (most recent call last):
    ...
    gyrodrift.errors.GyrodriftValueError: fault rates sum to 1.400 > 1
    """

    drop: float = 0.0
    corrupt: float = 0.0
    duplicate: float = 0.0
    reorder: float = 0.0
    delay: float = 0.0
    delay_s: float = 0.02
    seed: int = 0

    def __post_init__(self) -> None:
        rates = [getattr(self, k) for k in FAULT_KINDS]
        for k, r in zip(FAULT_KINDS, rates, strict=True):
            if not (0.0 <= r <= 1.0) or not np.isfinite(r):
                raise GyrodriftValueError(f"fault rate {k}={r} must be within [0, 1]")
        if sum(rates) > 1.0 + 1e-12:
            raise GyrodriftValueError(f"fault rates sum to {sum(rates):.3f} > 1")
        if not (self.delay_s >= 0.0 and np.isfinite(self.delay_s)):
            raise GyrodriftValueError(f"delay_s={self.delay_s} must be finite and >= 0")

    @property
    def any(self) -> bool:
        return any(getattr(self, k) > 0 for k in FAULT_KINDS)

    def to_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True)
class Unit:
    """One transmission: sample `index` at record time `t_s` (already shifted if delayed).

    Examples
    --------
    >>> Unit(index=4, t_s=0.01, fault="delay")
    Unit(index=4, t_s=0.01, corrupt=False, fault='delay')
    """

    index: int
    t_s: float
    corrupt: bool = False
    fault: str = ""  # "", or the fault kind that produced/moved this unit


@dataclass
class TransmissionPlan:
    """The units to send, in send order, and how many samples each fault kind touched.

    Examples
    --------
    >>> plan = plan_transmission(np.arange(4) / 400.0, FaultSpec())
    >>> plan.sent_units, [u.index for u in plan.units], plan.counts["drop"]
    (4, [0, 1, 2, 3], 0)
    """
    units: list[Unit]  # in send order
    counts: dict[str, int]  # samples affected per fault kind

    @property
    def sent_units(self) -> int:
        return len(self.units)


def plan_transmission(t_s: np.ndarray, spec: FaultSpec) -> TransmissionPlan:
    """Send order of n samples with faults applied. At most one fault per sample; a sample
    swapped by `reorder` takes its partner out of the draw (the partner is counted in
    the swap).

    Examples
    --------
    >>> plan = plan_transmission(np.arange(8) / 400.0, FaultSpec(reorder=1.0))
    >>> [u.index for u in plan.units], plan.counts["reorder"]  # every pair swapped
    ([1, 0, 3, 2, 5, 4, 7, 6], 4)
    >>> plan = plan_transmission(np.arange(4) / 400.0, FaultSpec(duplicate=1.0))
    >>> [u.index for u in plan.units]
    [0, 0, 1, 1, 2, 2, 3, 3]
    """
    n = int(t_s.shape[0])
    counts = dict.fromkeys(FAULT_KINDS, 0)
    if not spec.any:
        return TransmissionPlan([Unit(i, float(t_s[i])) for i in range(n)], counts)
    rng = np.random.default_rng(spec.seed)
    u = rng.random(n)
    edges = np.cumsum([getattr(spec, k) for k in FAULT_KINDS])
    kind_idx = np.searchsorted(edges, u, side="right")  # len(FAULT_KINDS) = no fault
    units: list[Unit] = []
    i = 0
    while i < n:
        k = int(kind_idx[i])
        kind = FAULT_KINDS[k] if k < len(FAULT_KINDS) else ""
        t = float(t_s[i])
        if kind == "drop":
            counts["drop"] += 1
        elif kind == "corrupt":
            counts["corrupt"] += 1
            units.append(Unit(i, t, corrupt=True, fault="corrupt"))
        elif kind == "duplicate":
            counts["duplicate"] += 1
            units.append(Unit(i, t))
            units.append(Unit(i, t, fault="duplicate"))
        elif kind == "reorder" and i + 1 < n:
            counts["reorder"] += 1
            t_next = float(t_s[i + 1])
            units.append(Unit(i + 1, t_next, fault="reorder"))
            units.append(Unit(i, t_next, fault="reorder"))
            i += 2
            continue
        elif kind == "delay":
            counts["delay"] += 1
            units.append(Unit(i, t + spec.delay_s, fault="delay"))
        else:
            units.append(Unit(i, t))
        i += 1
    # Delayed samples move behind everything due earlier (stable: ties keep plan order).
    order = sorted(range(len(units)), key=lambda j: (units[j].t_s, j))
    return TransmissionPlan([units[j] for j in order], counts)


def corrupt_serial_frame(frame: bytes, rng: np.random.Generator) -> bytes:
    """Flip one bit in bytes 4..39 (seq .. channels): the CRC must fail; the header stays
    intact so the receiver discards exactly this frame (reason "crc").

    Examples
    --------
    >>> from gyrodrift.codecs import FrameError, decode_frame, encode_frame
    >>> bad = corrupt_serial_frame(encode_frame(1, 0, [0.0] * 6), np.random.default_rng(0))
    >>> try:
    ...     decode_frame(bad)
    ... except FrameError as exc:
    ...     print(exc)
    CRC mismatch
    """
    b = bytearray(frame)
    pos = int(rng.integers(4, 40))
    b[pos] ^= 1 << int(rng.integers(0, 8))
    return bytes(b)


def corrupt_slcan_line(line: bytes, rng: np.random.Generator) -> bytes:
    """Replace one data hex digit of an SLCAN frame line with a non-hex character (a serial
    line error the adapter's parser must reject as malformed).

    Examples
    --------
    >>> line = b"t10080000000000000000\\r"
    >>> bad = corrupt_slcan_line(line, np.random.default_rng(0))
    >>> len(bad) == len(line), sum(a != b for a, b in zip(bad, line))
    (True, 1)
    """
    b = bytearray(line)
    # "tIIIL" + 16 hex digits + CR: data digits are at 5..20.
    pos = int(rng.integers(5, len(b) - 1))
    b[pos] = ord("G")
    return bytes(b)
