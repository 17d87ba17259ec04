"""Fault planning: rates, determinism, what each kind does to the send order, corruption."""

from __future__ import annotations

import binascii

import numpy as np
import pytest
from gyrodrift.codecs.wire import encode_frames, make_samples
from gyrodrift.replay.faults import (
    FaultSpec,
    corrupt_serial_frame,
    corrupt_slcan_line,
    plan_transmission,
)

T_S = np.arange(10000) / 400.0


def test_no_faults_sends_everything_in_order() -> None:
    plan = plan_transmission(T_S, FaultSpec())
    assert [u.index for u in plan.units] == list(range(T_S.size))
    assert not any(plan.counts.values())


@pytest.mark.parametrize("bad", [{"drop": -0.1}, {"corrupt": 1.5}, {"drop": 0.6, "delay": 0.6},
                                 {"delay_s": -1.0}, {"reorder": float("nan")}])
def test_invalid_specs_raise(bad: dict) -> None:
    with pytest.raises(ValueError):
        FaultSpec(**bad)


def test_rates_and_determinism() -> None:
    spec = FaultSpec(drop=0.02, corrupt=0.02, duplicate=0.02, reorder=0.02, delay=0.02, seed=9)
    a = plan_transmission(T_S, spec)
    b = plan_transmission(T_S, spec)
    assert a.units == b.units  # same seed, same plan
    for kind, count in a.counts.items():
        # Binomial(10000, 0.02): mean 200, sd 14; 6 sd bounds (reorder consumes 2 draws).
        assert 110 <= count <= 290, (kind, count)
    n = T_S.size
    assert a.sent_units == n - a.counts["drop"] + a.counts["duplicate"]
    assert sum(u.corrupt for u in a.units) == a.counts["corrupt"]
    assert plan_transmission(T_S, FaultSpec(drop=0.02, seed=10)).units != \
        plan_transmission(T_S, FaultSpec(drop=0.02, seed=11)).units


def test_each_kind_shapes_the_send_order() -> None:
    order = [u.index for u in plan_transmission(T_S[:2000], FaultSpec(reorder=0.05, seed=1)).units]
    swaps = [k for k in range(len(order) - 1) if order[k] == order[k + 1] + 1]
    assert swaps and sorted(order) == list(range(2000))
    dup = plan_transmission(T_S[:2000], FaultSpec(duplicate=0.05, seed=1))
    idx = [u.index for u in dup.units]
    assert len(idx) - len(set(idx)) == dup.counts["duplicate"]
    delayed = plan_transmission(T_S[:2000], FaultSpec(delay=0.05, delay_s=0.02, seed=1))
    where = {(u.index, u.fault): p for p, u in enumerate(delayed.units)}
    for pos, u in enumerate(delayed.units):
        if u.fault == "delay":
            # 20 ms at 400 Hz = 8 periods: every on-time sample among the next 7 goes first.
            for j in range(u.index + 1, min(u.index + 8, 2000)):
                if (j, "") in where:
                    assert where[(j, "")] < pos


def test_corruption_breaks_exactly_the_crc_or_the_line() -> None:
    rng = np.random.default_rng(3)
    s = make_samples(np.zeros(50), np.ones((50, 3)), np.ones((50, 3)))
    for frame in encode_frames(s):
        bad = corrupt_serial_frame(frame.tobytes(), rng)
        assert bad[:4] == frame.tobytes()[:4]  # header intact: the receiver drops one frame
        assert binascii.crc_hqx(bad[2:40], 0xFFFF) != int.from_bytes(bad[40:42], "little")
    line = b"t1018" + b"0011223344556677" + b"\r"
    for _ in range(50):
        bad = corrupt_slcan_line(line, rng)
        assert bad[:5] == line[:5] and bad.endswith(b"\r") and b"G" in bad
