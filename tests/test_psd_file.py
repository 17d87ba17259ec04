"""Welch's PSD of a record memory-mapped from a .npy file reads the file in pieces of whole
segments: the same PSD as the record in memory (each piece's mean periodogram weighted by
its number of segments is the mean over all segments), without a copy of the record or a
resident page of its mapping, so `gyrodrift psd` has bounded memory (before: 1120 MB at 2e7
samples, docs/validation/memory.md).

Tolerance: the same periodograms averaged in another order, 1e-12 relative (~1e-15 seen)."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.stability import psd as psd_mod
from mapped_memory import mapped_resident_kib

N = 1 << 22


@pytest.mark.parametrize("nperseg", [None, 1001])
def test_file_backed_psd_equals_the_psd_in_memory_without_holding_the_record(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, nperseg: int | None) -> None:
    rng = np.random.default_rng(3)
    y = rng.normal(size=N + 77) * 30.0 + np.cumsum(rng.normal(size=N + 77)) * 0.05
    path = tmp_path / "rec.npy"
    np.save(path, y)
    monkeypatch.setattr(psd_mod, "PSD_PIECE", 1 << 15)
    mm = np.load(path, mmap_mode="r")
    import scipy.signal  # noqa: F401  (its import, tens of MB, is not the PSD's memory)

    tracemalloc.start()
    try:
        got = psd_mod.welch_psd(mm, 400.0, nperseg)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # a copy of the record would be 33.6 MB; a piece of 2^16-sample segments ~6 MB
    assert peak < 0.25 * 8 * N, peak
    assert mapped_resident_kib(path) < 1024
    ref = psd_mod.welch_psd(y, 400.0, nperseg)
    assert got.nperseg == ref.nperseg
    np.testing.assert_array_equal(got.f_hz, ref.f_hz)
    np.testing.assert_allclose(got.psd, ref.psd, rtol=1e-12)


def test_psd_command_on_a_memory_mapped_record(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """The command's constant check and range scaling read the record in pieces too: a
    constant record is still one line, a normal one the PSD of the record in memory."""
    import json

    from gyrodrift.cli import main

    const = tmp_path / "const.npy"
    np.save(const, np.full(5000, 3.0))
    assert main(["psd", str(const), "--rate-hz", "100", "--gyro-units", "deg/h", "--png",
                 str(tmp_path / "c.png")]) == 2
    assert "the record is constant (5000 samples of 3 deg/h)" in capsys.readouterr().err
    rec = tmp_path / "rec.npy"
    y = np.random.default_rng(4).normal(size=20000) * 2.0**-200  # scaled for the transform
    np.save(rec, y)
    assert main(["psd", str(rec), "--rate-hz", "100", "--gyro-units", "deg/h", "--png",
                 str(tmp_path / "r.png"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    ref = psd_mod.welch_psd(y * 2.0**200, 100.0)
    level = float(np.median(ref.psd[ref.f_hz > ref.f_hz[-1] / 2])) * 2.0**-400
    assert out["white_level_deg_h_sq_hz"] == pytest.approx(level, rel=1e-12)
