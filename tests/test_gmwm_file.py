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
import tempfile
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


# The parametric bootstrap of a file-backed record: each replicate is simulated in pieces
# (every term's generator state carried across them) into a temporary file and its wavelet
# variance streamed from it, as the record's own.

BOOT_TERMS = ("Q", "N", "GM", "K", "R", "GM")
#: per-sample parameters of BOOT_TERMS (Q^2, N^2, GM sigma^2 and T_c, K^2, R^2, ...)
BOOT_P = np.array([0.3, 2.0, 1.5, 40.0, 1e-4, 1e-8, 0.7, 300.0])


def _pieces(piece: int, n: int, seed: int, records: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(records):
        st = gmwm._ModelStream(BOOT_TERMS, BOOT_P, n, rng, piece)
        parts = [st.next_piece() for _ in range(-(-n // piece))]
        assert st.next_piece().size == 0
        out.append(np.concatenate(parts))
    return np.concatenate(out)


def test_bootstrap_records_in_pieces_are_the_whole_record_simulation_bit_for_bit() -> None:
    # the same random numbers and the same arithmetic, however the record is cut: exact
    # (two records in a row: the generator is left where the whole-record simulation
    # leaves it)
    n = 10_007
    rng = np.random.default_rng(3)
    whole = np.concatenate([gmwm._simulate_model(BOOT_TERMS, BOOT_P, n, rng) for _ in range(2)])
    for piece in (1, 333, 4096, n - 1):
        np.testing.assert_array_equal(_pieces(piece, n, 3, 2), whole)
    # the record has the terms' random parts: not a constant or a copy of one piece
    assert np.std(np.diff(whole[:n])) > 1.0


def test_file_backed_bootstrap_equals_the_bootstrap_in_memory(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The replicates are the same records (test above); their wavelet variances come through
    # the streamed Allan variance instead of haar_wv (1e-9, module docstring), and the refits
    # on them agree to the optimiser's tolerance (1e-6 relative, as the fit itself).
    n = 1 << 17
    rng = np.random.default_rng(8)
    y = rng.normal(size=n) * 30.0 + np.cumsum(rng.normal(size=n)) * 0.05
    path = tmp_path / "rec.npy"
    np.save(path, y)
    monkeypatch.setattr(gmwm, "FILE_BACKED_MIN", 1 << 16)
    monkeypatch.setattr(gmwm, "_WV_PIECE", 1 << 14)  # 8 pieces per replicate
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    got = gmwm.identify_gmwm(np.load(path, mmap_mode="r"), 100.0, model="N+K", bootstrap=4,
                             seed=2)
    ref = gmwm.identify_gmwm(y, 100.0, model="N+K", bootstrap=4, seed=2)
    assert got.ci_method == ref.ci_method == "bootstrap"
    for p, q in zip(got.params, ref.params, strict=True):
        assert p.name == q.name
        for attr in ("value", "ci_low", "ci_high"):
            a, b = getattr(p, attr), getattr(q, attr)
            assert math.isclose(a, b, rel_tol=1e-6), (p.name, attr, a, b)
    # another seed gives other intervals: the comparison above is not of fixed numbers
    other = gmwm.identify_gmwm(y, 100.0, model="N+K", bootstrap=4, seed=3)
    assert other.param("K").ci_high != ref.param("K").ci_high
    # the replicate's temporary file is gone
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.npy"]
