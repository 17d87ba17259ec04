"""GMWM on a record memory-mapped from a .npy file reads the file in chunks: its wavelet
variance is half the streamed overlapping Allan variance at m = 2^(j-1), the same as the
Haar MODWT wavelet variance of the record in memory, without a copy of the record or a
resident page of its mapping (so `identify --identifier gmwm` has bounded memory).

Tolerances: the two wavelet variances are the same sums in another order and through
another kernel (the Allan kernel's fused block sums against one cumulative sum): 1e-9
relative (rounding of sums of 1e6 squared differences is ~1e-12; a wrong level or count
would be off by a factor of 2 or more). The fit on them then agrees to 1e-6 relative (the
optimiser's own tolerance on nearly equal data)."""

from __future__ import annotations

import math
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.stability import gmwm
from mapped_memory import mapped_resident_kib

N = 1 << 20


def test_file_backed_gmwm_equals_the_fit_in_memory_without_holding_the_record(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(5)
    y = rng.normal(size=N) * 30.0 + np.cumsum(rng.normal(size=N)) * 0.05 + 7.0
    path = tmp_path / "rec.npy"
    np.save(path, y)
    monkeypatch.setattr(gmwm, "FILE_BACKED_MIN", 1 << 16)
    monkeypatch.setattr(gmwm, "_WV_PIECE", 1 << 15)  # 32 chunks
    mm = np.load(path, mmap_mode="r")
    tracemalloc.start()
    try:
        got = gmwm.identify_gmwm(mm, 100.0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 0.5 * 8 * N, peak  # a copy of the record would be 8.4 MB
    assert mapped_resident_kib(path) < 1024
    ref = gmwm.identify_gmwm(y, 100.0)
    assert got.n_samples == ref.n_samples == N
    np.testing.assert_allclose(got.wv, ref.wv, rtol=1e-9)
    np.testing.assert_allclose(got.tau_s, ref.tau_s, rtol=0)
    assert got.model == ref.model
    for p, q in zip(got.params, ref.params, strict=True):
        assert p.name == q.name
        for attr in ("value", "ci_low", "ci_high"):
            a, b = getattr(p, attr), getattr(q, attr)
            assert a == b or math.isclose(a, b, rel_tol=1e-6), (p.name, attr, a, b)


def test_file_backed_gmwm_refuses_nan_with_its_count(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    y = np.random.default_rng(6).normal(size=1 << 17)
    y[[5, 70000]] = np.nan
    path = tmp_path / "nan.npy"
    np.save(path, y)
    monkeypatch.setattr(gmwm, "FILE_BACKED_MIN", 1 << 16)
    with pytest.raises(ValueError, match="x: 2 NaN/Inf samples"):
        gmwm.identify_gmwm(np.load(path, mmap_mode="r"), 100.0)
