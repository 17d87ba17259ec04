"""The drift model fitted to a record memory-mapped from a .npy file reads the file in pieces:
the same fit as the record in memory, without holding the record (no copy of it, no page of
its mapping resident), so `gyrodrift fit`'s memory does not grow with the record.

Tolerances: the file-backed fit sums the mean, the Burg fit's and the autocovariances' lag
products piece by piece (another summation order than the whole-array passes, ~1e-16
relative) and the likelihood through the core's stream (bit-identical to the one pass), so the
optimiser may stop at a point that differs within its own tolerance: log-likelihoods agree
to 1e-6 and parameters to 1 % of their standard errors (the statistical uncertainty), as for
the scaled records in test_extreme_scales.py."""

from __future__ import annotations

import math
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from gyrodrift._native import core
from gyrodrift.filters import drift_model as dm
from mapped_memory import mapped_resident_kib
from scipy.signal import lfilter

N = 1_000_000


@pytest.fixture(scope="module")
def record(tmp_path_factory: pytest.TempPathFactory) -> Path:
    rng = np.random.default_rng(1)
    y = (lfilter([1.0], [1.0, -0.6868, 0.0213], rng.normal(0, 0.5, N))
         + rng.normal(0, 0.3, N) + 2.0)
    path = tmp_path_factory.mktemp("drift") / "rec.npy"
    np.save(path, y)
    return path


def test_file_backed_fit_equals_the_fit_in_memory_without_holding_the_record(
        record: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(dm, "_PIECE", 1 << 15)  # 31 pieces: boundaries everywhere
    mm = np.load(record, mmap_mode="r")
    tracemalloc.start()
    try:
        got = dm.compare_drift_models(mm, 100.0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # a copy of the record would be 8 MB; the pieces and the 2^16-sample prefix are ~2 MB
    assert peak < 0.5 * 8 * N, peak
    assert mapped_resident_kib(record) < 1024
    ref = dm.compare_drift_models(np.load(record), 100.0)
    assert got.chosen == ref.chosen
    for f, f0 in zip(got.fits, ref.fits, strict=True):
        assert abs(f.loglike - f0.loglike) < 1e-6, f.model
        for k in ("a1", "a2", "q", "r", "mean"):
            se = f0.stderr[k]
            if math.isfinite(se):
                assert abs(getattr(f, k) - getattr(f0, k)) < 0.01 * se, (f.model, k)
            else:
                assert getattr(f, k) == getattr(f0, k), (f.model, k)
        assert math.isclose(f.ljung_box.statistic, f0.ljung_box.statistic, rel_tol=1e-6)
        assert (f.identified, f.tuning, f.n) == (f0.identified, f0.tuning, f0.n)


def test_file_backed_block_average_is_the_in_memory_one(record: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(dm, "_PIECE", 1000)
    mm = np.load(record, mmap_mode="r")
    for factor in (1, 7, 1024, 4096):  # blocks smaller and larger than a piece
        assert np.array_equal(dm.block_average(mm, factor), dm.block_average(np.load(record),
                                                                            factor)), factor
    assert mapped_resident_kib(record) < 1024


def test_stream_pieces_equal_one_pass() -> None:
    """The core's stream over pieces gives the one pass's sums and innovations exactly."""
    rng = np.random.default_rng(4)
    y = lfilter([1.0], [1.0, -0.6, -0.2], rng.normal(size=5000)) + rng.normal(size=5000)
    drift = core("drift")
    innov = np.empty(y.size)
    whole = drift.drift_loglike(y, 0.6, 0.2, 1.0, 1.0, 0.1, innov)
    stream = drift.DriftLoglikeStream(a1=0.6, a2=0.2, q=1.0, r=1.0, mean=0.1)
    parts = []
    for lo in range(0, y.size, 333):
        e = np.empty(min(333, y.size - lo))
        stream.update(y[lo:lo + 333], e)
        parts.append(e)
    assert tuple(stream.result()) == tuple(whole)
    assert np.array_equal(np.concatenate(parts), innov)
    bad = y.copy()
    bad[4000] = np.nan
    stream = drift.DriftLoglikeStream(a1=0.6, a2=0.2, q=1.0, r=1.0, mean=0.1)
    stream.update(bad)
    with pytest.raises(ValueError, match="non-finite"):
        stream.result()
    with pytest.raises(ValueError, match="non-stationary"):
        drift.DriftLoglikeStream(a1=0.7, a2=0.3, q=1.0, r=1.0, mean=0.0)
