"""Streaming octave Allan variance (C++ core through gyrodrift.stability.streaming) against the
numpy reference from the definition (gyrodrift.reference.adev_rate / adev_octaves), against
allantools.adev (non-overlapped) at the octave taus, float against double after 10 h at
400 Hz, chunking, edf and intervals, one object shared by threads, and bad input."""

from __future__ import annotations

import threading

import allantools
import numpy as np
import pytest
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.reference.allan import adev_octaves, adev_rate
from gyrodrift.stability import edf
from gyrodrift.stability.streaming import StreamingAllan

# Streaming vs the reference: both are double with pairwise-style rounding of the cluster
# means (~log2(m) eps) and sums of 1e5 squares (numpy pairwise, the core compensated), so they
# agree at ~1e-15; 1e-12 is the bar for double and leaves room for summation order.
REF_RTOL = 1e-12
# allantools.adev forms the phase with a float64 cumulative sum (rounding ~N eps relative on
# the phase, see test_allan_oracle.py) and second-differences it: on these 1e5 samples that
# stays below ~1e-13 (docs/validation/streaming-allan.md measures <= 5e-14), so the double
# bar of 1e-12 holds against the external oracle too.
ORACLE_RTOL = 1e-12
# float vs double on the same float32 samples after 10 h at 400 Hz: ~16 float eps, the bound
# docs/validation/streaming-allan.md states (measured < 1e-7).
FLOAT_RTOL = 1e-6


def gyro_like(rng: np.random.Generator, n: int) -> np.ndarray:
    """White rate + random walk + Earth rate-like offset, deg/h."""
    return 15.0 + rng.normal(0.0, 0.05, n) + np.cumsum(rng.normal(0.0, 2e-4, n))


def test_equals_reference_definition_at_every_octave() -> None:
    y = gyro_like(np.random.default_rng(1), 100_003)
    sa = StreamingAllan(400.0, 15)
    assert sa.push(y) == y.size
    for k in range(15):
        dev, terms = adev_rate(y, 1 << k)
        assert sa.counts[k] == terms == y.size // (1 << k) - 1
        np.testing.assert_allclose(sa.adev[k], dev, rtol=REF_RTOL, atol=0)
    ref_avar, ref_terms = adev_octaves(y, 15)
    np.testing.assert_allclose(sa.avar, ref_avar, rtol=REF_RTOL, atol=0)
    np.testing.assert_array_equal(sa.counts, ref_terms)
    np.testing.assert_allclose(sa.tau_s, (1 << np.arange(15)) / 400.0, rtol=1e-15)


def test_equals_allantools_adev_at_octave_taus() -> None:
    y = gyro_like(np.random.default_rng(2), 100_000)
    rate_hz = 400.0
    sa = StreamingAllan(rate_hz, 15)
    sa.push(y)
    taus, dev, _, ns = allantools.adev(y, rate=rate_hz, data_type="freq", taus=sa.tau_s)
    np.testing.assert_allclose(taus, sa.tau_s, rtol=1e-15)
    np.testing.assert_allclose(sa.adev, dev, rtol=ORACLE_RTOL, atol=0)
    np.testing.assert_array_equal(sa.counts, ns)


def test_chunking_does_not_change_the_result() -> None:
    y = gyro_like(np.random.default_rng(3), 50_000)
    whole = StreamingAllan(100.0, 12)
    whole.push(y)
    pieces = StreamingAllan(100.0, 12)
    for part in np.array_split(y, [1, 2, 3, 777, 4096, 4097, 30_000]):
        pieces.push(part)
    # the same samples in the same order give the same operations: bit-identical
    np.testing.assert_array_equal(pieces.avar, whole.avar)
    np.testing.assert_array_equal(pieces.counts, whole.counts)


def test_float_state_after_ten_hours_at_400_hz() -> None:
    rate_hz, n = 400.0, 14_400_000  # 10 h
    rng = np.random.default_rng(4)
    # gyro-like in deg/h: bias 10, ARW-like white noise, slow rate random walk
    y32 = (10.0 + rng.standard_normal(n) + np.cumsum(rng.normal(0.0, 1e-4, n))).astype(np.float32)
    single = StreamingAllan(rate_hz, 20, dtype=np.float32)
    double = StreamingAllan(rate_hz, 20)
    assert single.push(y32) == n
    double.push(y32.astype(np.float64))  # the same values: the difference is arithmetic only
    np.testing.assert_array_equal(single.counts, double.counts)
    assert double.counts[-1] == n // (1 << 19) - 1 == 26
    rel = np.abs(single.avar - double.avar) / double.avar
    assert float(rel.max()) < FLOAT_RTOL, rel


def test_octave_without_two_clusters_is_nan_and_edf_follows_greenhall() -> None:
    y = np.random.default_rng(5).standard_normal(1000)
    sa = StreamingAllan(10.0, 11)  # octave 9 has 1 difference (512 + 488), octave 10 none
    sa.push(y)
    assert sa.counts[9] == 0 and sa.counts[8] == 2
    assert np.isnan(sa.avar[9]) and np.isnan(sa.avar[10])
    got = sa.edf(-1)
    for k in (0, 4, 8):
        assert got[k] == edf.edf_greenhall(-1, 2, 1 << k, 1001, overlapping=False,
                                           modified=False)
    assert np.isnan(got[9])
    lo, hi = sa.interval(0, 0.95)
    ok = ~np.isnan(sa.adev)
    assert np.all(lo[ok] < sa.adev[ok]) and np.all(sa.adev[ok] < hi[ok])


def test_non_finite_samples_are_counted_and_skipped() -> None:
    sa = StreamingAllan(100.0, 2)
    assert sa.push(np.array([1.0, np.nan, -1.0, np.inf, 1.0])) == 3
    assert sa.rejected == 2 and sa.samples == 3
    ref = StreamingAllan(100.0, 2)
    ref.push(np.array([1.0, -1.0, 1.0]))
    np.testing.assert_array_equal(sa.avar, ref.avar)
    sa.reset()
    assert sa.samples == 0 and sa.rejected == 0 and np.isnan(sa.avar).all()


@pytest.mark.parametrize(("args", "kwargs", "match"), [
    ((0.0, 4), {}, "rate_hz"),
    ((float("nan"), 4), {}, "rate_hz"),
    ((100.0, 0), {}, "n_octaves"),
    ((100.0, 41), {}, "n_octaves"),
    ((100.0, 2.5), {}, "n_octaves"),
    ((100.0, 4), {"dtype": np.int32}, "dtype"),
])
def test_bad_configuration_is_a_clear_error(args: tuple, kwargs: dict, match: str) -> None:
    with pytest.raises(GyrodriftValueError, match=match):
        StreamingAllan(*args, **kwargs)


def test_bad_push_and_alpha_are_clear_errors() -> None:
    sa = StreamingAllan(100.0, 3)
    with pytest.raises(GyrodriftValueError, match="1-D"):
        sa.push(np.zeros((4, 2)))
    with pytest.raises(GyrodriftValueError, match="alpha"):
        sa.edf(3)


def test_reader_never_sees_half_a_push() -> None:
    # push runs without the GIL and counts sample by sample; a reader polling `samples` from
    # another thread meanwhile must wait for the object's lock, so it only ever sees whole
    # pushes (multiples of n), never a push in progress.
    n, calls = 200_000, 8
    sa = StreamingAllan(400.0, 20)
    y = np.random.default_rng(6).standard_normal(n)
    done = threading.Event()

    def writer() -> None:
        for _ in range(calls):
            sa.push(y)
        done.set()

    t = threading.Thread(target=writer)
    seen = {sa.samples}
    t.start()
    while not done.is_set():
        seen.add(sa.samples)
    t.join()
    seen.add(sa.samples)
    assert all(v % n == 0 for v in seen), sorted(seen)
    assert sa.samples == calls * n


def test_shared_object_counts_every_sample() -> None:
    n, threads, calls = 100_000, 4, 4
    sa = StreamingAllan(400.0, 10, dtype=np.float32)
    y = np.ones(n, dtype=np.float32)
    start = threading.Barrier(threads)

    def body() -> None:
        start.wait()
        for _ in range(calls):
            sa.push(y)

    pool = [threading.Thread(target=body) for _ in range(threads)]
    for t in pool:
        t.start()
    for t in pool:
        t.join()
    assert sa.samples == threads * calls * n
    assert sa.counts[0] == threads * calls * n - 1
