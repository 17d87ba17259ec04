"""Golden-output check (as PX4 ECL does): a stored small input record with every fault kind,
a shipped configuration (every stage kind: wavelet db4/db8 forced/soft/hard, AR(2)-Kalman
steady-state and full, bias removal, pass-through) and the processor's stored outputs
(tests/golden/). Any change of an output fails here and is shown channel by channel; after an
INTENDED change, regenerate with scripts/update-golden --write and say why in the commit.

The outputs are the float32 C++ processor's (which the loop equals bit for bit,
tests/test_config_file.py); they are compared exactly: the same code on the same input must
give the same bits (determinism is part of the processor's contract)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from gyrodrift.imu.config import load_config
from gyrodrift.imu.contract import describe_flags
from gyrodrift.imu.processor import ImuConfig, ImuProcessor

GOLDEN = Path(__file__).resolve().parent / "golden"
CHANNELS = ("gx", "gy", "gz", "ax", "ay", "az")


def describe_changes(old: dict[str, np.ndarray], new: dict[str, np.ndarray]) -> str:
    """One line per changed channel (count, largest change, first sample) and for the flags."""
    lines = []
    ov, nv = old["values"], new["values"]
    if ov.shape != nv.shape:
        return f"output shape changed: {ov.shape} -> {nv.shape}"
    for c, name in enumerate(CHANNELS):
        a, b = ov[:, c].astype(np.float64), nv[:, c].astype(np.float64)
        same = (a == b) | (np.isnan(a) & np.isnan(b))
        if not same.all():
            idx = np.flatnonzero(~same)
            d = np.abs(a[idx] - b[idx])
            lines.append(f"{name}: {idx.size} samples changed, max |change| {np.nanmax(d):.3g} "
                         f"(relative {np.nanmax(d) / max(np.nanmax(np.abs(a)), 1e-30):.3g}), "
                         f"first at sample {idx[0]}: {a[idx[0]]!r} -> {b[idx[0]]!r}")
    fchg = np.flatnonzero(old["flags"] != new["flags"])
    if fchg.size:
        k = fchg[0]
        lines.append(f"flags: {fchg.size} samples changed, first at sample {k}: "
                     f"{describe_flags(int(old['flags'][k]))} -> "
                     f"{describe_flags(int(new['flags'][k]))}")
    return "\n".join(lines)


def test_golden_outputs_unchanged() -> None:
    inp = np.load(GOLDEN / "input.npz")
    old = dict(np.load(GOLDEN / "output.npz"))
    cfg = ImuConfig.from_processor_config(GOLDEN / "processor.toml", float32=True)
    res = ImuProcessor(cfg, dtype=np.float32).process(inp["seq"], inp["t_us"], inp["values"])
    new = {"values": res.values.astype(np.float32), "flags": res.flags}
    report = describe_changes(old, new)
    assert not report, "processor outputs changed (scripts/update-golden):\n" + report


def test_golden_set_covers_every_stage_and_fault() -> None:
    cfg = load_config(GOLDEN / "processor.toml")
    kinds = {(s.type, getattr(s, "threshold", getattr(s, "steady_state", None)))
             for c in cfg.channels for s in c.stages}
    assert {k for k, _ in kinds} == {"wavelet", "ar2_kalman", "bias_removal", "pass_through"}
    assert {("wavelet", "forced"), ("wavelet", "soft"), ("wavelet", "hard"),
            ("ar2_kalman", True), ("ar2_kalman", False)} <= kinds
    out = np.load(GOLDEN / "output.npz")
    names = {n for f in np.unique(out["flags"]) for n in describe_flags(int(f))}
    assert {"non_finite", "saturated", "stuck", "seq_gap", "duplicate", "time_jump",
            "rejected"} <= names


def test_describe_changes_shows_a_change_by_channel() -> None:
    """The report names the channel, the count and the first sample (a one-ulp change)."""
    old = dict(np.load(GOLDEN / "output.npz"))
    new = {k: v.copy() for k, v in old.items()}
    new["values"][700, 4] = np.nextafter(new["values"][700, 4], np.float32(np.inf))
    text = describe_changes(old, new)
    assert text.startswith("ay: 1 samples changed") and "first at sample 700" in text
