"""Every filter either returns a finite output or counts a fault, for any input value
(issue 13): NaN, +-Inf and finite values up to the type's maximum, in float32 and float64.

Before the fix one sample of 3e38 (float32) or 1.7e308 (float64) gave the soft-mode real-time
wavelet up to 271 NaN outputs with fault_counts 0, and ar_filter returned Inf near the type's
maximum. The filters now treat a value beyond gyrodrift's filter input limit (max / 2^24,
include/gyrodrift/filters/input_range.hpp) like NaN: skipped, counted, state untouched. So a record
with extreme values must filter exactly like the same record with NaN in their place.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from gyrodrift import _core
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.filters.ar2 import Ar2Model, KalmanFilter, ar_filter, kalman_filter_result
from gyrodrift.filters.wavelet import RealtimeWavelet
from gyrodrift.imu.processor import ImuChannelConfig, ImuConfig, ImuProcessor, WaveletSettings
from hypothesis import given, settings
from hypothesis import strategies as st

N = 300  # > the 256-sample wavelet window, so the filtered (not start-up) path runs
DTYPES = (np.float32, np.float64)
MODEL = Ar2Model(a1=0.6, a2=0.25, sigma2=1e-2, mean=0.05, r=2e-3)


def limit(dtype: type) -> float:
    """max / 2^24, the documented input limit of the C++ filters."""
    return float(np.finfo(dtype).max) / 2.0**24


def base_record(dtype: type, seed: int = 5) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (0.05 + 0.1 * rng.standard_normal(N)).astype(dtype)


def extreme_values(width: int) -> st.SearchStrategy[float]:
    """Any float of the width, weighted towards the top of the range."""
    big = float(np.finfo(np.float32 if width == 32 else np.float64).max)
    return st.one_of(
        st.floats(width=width),  # anything, NaN and +-Inf included
        st.floats(min_value=big / 2**30, max_value=big, width=width),
        st.floats(min_value=-big, max_value=-big / 2**30, width=width),
        st.sampled_from([big, -big, 3e38 if width == 32 else 1.7e308]),
    )


def inject(x: np.ndarray, hits: list[tuple[int, float]]) -> tuple[np.ndarray, np.ndarray, int]:
    """x with the hits written in, the same with NaN where a hit is refused, and how many
    samples the filters must refuse (non-finite or beyond the limit)."""
    bad = x.copy()
    for i, v in hits:
        bad[i] = v
    refused = ~(np.abs(bad.astype(np.float64)) <= limit(x.dtype.type))
    as_nan = bad.copy()
    as_nan[refused] = np.nan
    return bad, as_nan, int(refused.sum())


def hits_strategy(width: int) -> st.SearchStrategy[list[tuple[int, float]]]:
    return st.lists(st.tuples(st.integers(0, N - 1), extreme_values(width)), min_size=1,
                    max_size=4, unique_by=lambda h: h[0])


def check(out: np.ndarray, ref: np.ndarray, faults: int, refused: int) -> None:
    assert np.all(np.isfinite(out)), "non-finite output"
    assert faults == refused
    np.testing.assert_array_equal(out, ref)  # state untouched: same as NaN in their place


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("mode", ["forced", "soft", "hard"])
def test_issue13_wavelet_one_huge_sample(dtype: type, mode: str) -> None:
    """The issue's case: one sample of 3e38 (float32) / 1.7e308 (float64)."""
    x = base_record(dtype)
    x[280] = 3e38 if dtype == np.float32 else 1.7e308
    f = RealtimeWavelet("db8", 256, 5, mode, dtype=dtype)
    out = f.filter(x)
    assert np.all(np.isfinite(out))
    assert int(f.fault_counts.sum()) == 1


@pytest.mark.parametrize("dtype", DTYPES)
def test_issue13_ar_filter_near_max(dtype: type) -> None:
    x = np.full(10, float(np.finfo(dtype).max) * 0.9, dtype=dtype)
    out, faults = _core.ar_filter_batch(
        x, [_core.Ar2KalmanSettings(a1=0.6, a2=0.35, sigma2=1.0, mean=0.0, q=1.0, r=1.0)], None)
    assert np.all(np.isfinite(out))
    assert int(faults[0]) == 10


@pytest.mark.parametrize("width", [32, 64])
@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_property_wavelet_any_value(width: int, data: st.DataObject) -> None:
    dtype = np.float32 if width == 32 else np.float64
    hits = data.draw(hits_strategy(width))
    mode = data.draw(st.sampled_from(["forced", "soft", "hard"]))
    bad, as_nan, refused = inject(base_record(dtype), hits)
    a = RealtimeWavelet("db8", 256, 5, mode, dtype=dtype)
    b = RealtimeWavelet("db8", 256, 5, mode, dtype=dtype)
    out = a.filter(bad)
    check(out, b.filter(as_nan), int(a.fault_counts.sum()), refused)
    if mode != "forced":  # the full-recompute path must agree on what it skips
        c = RealtimeWavelet("db8", 256, 5, mode, dtype=dtype)
        assert np.all(np.isfinite(c.filter(bad, recompute=True)))


@pytest.mark.parametrize("width", [32, 64])
@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_property_ar_filters_any_value(width: int, data: st.DataObject) -> None:
    dtype = np.float32 if width == 32 else np.float64
    hits = data.draw(hits_strategy(width))
    bad, as_nan, refused = inject(base_record(dtype), hits)
    params = [_core.Ar2KalmanSettings(a1=MODEL.a1, a2=MODEL.a2, sigma2=MODEL.sigma2,
                                      mean=MODEL.mean, q=MODEL.sigma2, r=MODEL.r)]
    out, faults = _core.ar_filter_batch(bad, params, None)
    ref, _ = _core.ar_filter_batch(as_nan, params, None)
    check(out, ref, int(faults[0]), refused)
    for steady in (False, True):
        res = kalman_filter_result(bad, MODEL, steady_state=steady)
        ref = kalman_filter_result(as_nan, MODEL, steady_state=steady).y
        check(res.y, ref, int(res.faults[0]), refused)


@pytest.mark.parametrize("width", [32, 64])
@settings(max_examples=25, deadline=None)
@given(data=st.data())
def test_property_processor_any_value(width: int, data: st.DataObject) -> None:
    """ImuProcessor with Kalman, wavelet (soft), bias and pass-through channels: a good
    (finite, unsaturated) value a stage refuses is a filter fault; outputs stay finite."""
    dtype = np.float32 if width == 32 else np.float64
    hits = data.draw(hits_strategy(width))
    chan = data.draw(st.integers(0, 5))
    big = float(np.finfo(dtype).max)
    channels = [
        ImuChannelConfig.ar2_kalman(MODEL),
        ImuChannelConfig(filter="wavelet"),
        ImuChannelConfig(filter="wavelet"),
        ImuChannelConfig(filter="bias_removal", bias=-big / 2),  # x - bias overflows near max
        ImuChannelConfig(),
        ImuChannelConfig(filter="bias_removal", bias=0.01),
    ]
    proc = ImuProcessor(ImuConfig(channels=channels, time_tolerance_us=0), dtype=dtype,
                        wavelet=WaveletSettings(wavelet="db8", threshold="soft"))
    x = np.tile(base_record(dtype)[:, None], (1, 6))
    for i, v in hits:
        x[i, chan] = v
    res = proc.process(np.arange(N) % 65536, np.arange(N) * 2500, x)
    h = res.health
    non_finite = int((~np.isfinite(x[:, chan].astype(np.float64))).sum())
    assert np.all(np.isfinite(res.values))
    assert h["non_finite_values"] == non_finite
    finite_hits = [v for _, v in hits if np.isfinite(v)]
    if chan in (0, 1, 2):  # filter stages: refused iff beyond the limit
        assert h["filter_faults"] == sum(abs(v) > limit(dtype) for v in finite_hits)
    elif chan == 3:  # x - (-max/2) overflows (in the dtype's own rounding) for x > ~max/2
        with np.errstate(over="ignore"):
            over = [np.isinf(dtype(v) - dtype(-big / 2)) for v in finite_hits]
        assert h["filter_faults"] == sum(over)
    else:
        assert h["filter_faults"] == 0


def test_kalman_state_stays_finite_after_a_run_of_huge_values() -> None:
    """Before: a run of values near float32 max drove the Kalman state to Inf (then NaN
    forever). Now they are predict-only steps and the filter carries on."""
    x = base_record(np.float32)
    x[100:110] = 3.0e38
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = kalman_filter_result(x, MODEL)
    assert np.all(np.isfinite(res.y)) and int(res.faults[0]) == 10


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("pattern", ["block", "alternating", "one"])
def test_offline_wavelet_extreme_values_clean_error_or_finite(dtype: type, pattern: str) -> None:
    """Offline wavelet_denoise: a record near the dtype's maximum either filters to finite
    values or is refused with a message about the overflow (before: the inverse transform
    complained about a non-finite 'x' at an index of the coefficient array)."""
    from gyrodrift import wavelet_denoise

    big = float(np.finfo(dtype).max)
    x = np.random.default_rng(1).normal(size=1024).astype(dtype)
    if pattern == "block":
        x[500:540] = big
    elif pattern == "alternating":
        x[500:540:2], x[501:540:2] = big, -big
    else:
        x[500] = big
    for mode in ("soft", "hard", "forced"):
        try:
            out = wavelet_denoise(x, mode=mode, dtype=dtype)
        except ValueError as exc:
            assert "overflow" in str(exc) and "scale the record" in str(exc)
        else:
            assert np.all(np.isfinite(out))


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("shape", [(1024,), (1024, 3)])
def test_offline_float32_wavelet_refuses_values_beyond_float32_without_a_warning(
        shape: tuple[int, ...]) -> None:
    """A finite float64 value beyond float32's largest (about 3.4e38) is refused by the
    whole-record float32 denoiser with its value and index, before it is rounded to Inf
    (before: numpy's "overflow encountered in cast" warning, then a message calling the
    finite value non-finite). Warnings are errors here."""
    from gyrodrift import wavelet_denoise
    from gyrodrift.errors import GyrodriftValueError

    x = np.random.default_rng(2).normal(size=shape)
    x[700] = -1e39
    with pytest.raises(GyrodriftValueError) as exc:
        wavelet_denoise(x, "db4", 4, dtype=np.float32)
    where = "700" if len(shape) == 1 else "(700, 0)"
    assert str(exc.value) == (f"x: value -1e+39 at index {where} is beyond the float32 range "
                              "(largest 3.4e+38); scale the record")
    assert np.all(np.isfinite(wavelet_denoise(x, "db4", 4)))  # float64 holds it


def test_float32_filters_refuse_a_model_float32_cannot_hold() -> None:
    """A model fitted in float64 whose variance float32 cannot hold (1e66 here: a record at
    1e33 in its units) is refused for the float32 core with the parameter named, instead of
    the core's "bad argument" or a run of non-finite outputs; float64 takes it."""
    big = Ar2Model(a1=0.5, a2=0.1, sigma2=1e66, mean=0.0, r=1e66)
    x = np.random.default_rng(0).normal(0.0, 1e33, 64)
    for call in (lambda: ar_filter(x, big, dtype=np.float32),
                 lambda: kalman_filter_result(x, big, dtype=np.float32),
                 lambda: KalmanFilter(big, dtype=np.float32)):
        with pytest.raises(GyrodriftValueError, match=r"sigma2 = 1e\+66 is beyond what the "
                                                      r"float32 core holds"):
            call()
    assert np.all(np.isfinite(ar_filter(x, big, dtype=np.float64)))


@pytest.mark.filterwarnings("error")
def test_float32_realtime_wavelet_counts_a_value_beyond_float32_without_a_warning() -> None:
    """The streaming float32 filter counts a finite float64 value beyond float32 as a fault
    (it becomes Inf, is left out of the window, the previous output repeats) without numpy's
    overflow warning, per sample and per block."""
    x = np.random.default_rng(1).normal(size=600)
    x[300] = 1e39
    f = RealtimeWavelet("db4", 64, 3, dtype=np.float32)
    y = f.filter(x)
    assert int(f.fault_counts.sum()) == 1 and np.all(np.isfinite(y))
    g = RealtimeWavelet("db4", 64, 3, dtype=np.float32)
    for v in x:
        g.step(v)
    assert int(g.fault_counts.sum()) == 1
