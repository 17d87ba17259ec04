"""Argument handling of the AR(2) bindings: dtypes, shapes, layouts, clear errors."""

from __future__ import annotations

import gyrodrift
import numpy as np
import pytest
from gyrodrift import Ar2Model, KalmanFilter, _core
from gyrodrift.filters.ar2 import kalman_filter_result

MODEL = Ar2Model(a1=0.45, a2=0.12, sigma2=0.8, mean=3.0, r=1.1)
S = _core.Ar2KalmanSettings
PARAMS = [_core.Ar2KalmanSettings(a1=MODEL.a1, a2=MODEL.a2, sigma2=MODEL.sigma2, mean=MODEL.mean,
                                   q=MODEL.sigma2, r=MODEL.r)]


@pytest.fixture()
def x(rng) -> np.ndarray:
    return 3.0 + rng.normal(0.0, 1.0, (600, 3))


@pytest.mark.parametrize("fn", [gyrodrift.kalman_filter, gyrodrift.ar_filter])
def test_dtypes_and_shapes(fn, x) -> None:
    for dtype in (np.float64, np.float32):
        a = x.astype(dtype)
        assert fn(a, MODEL).dtype == dtype
        assert fn(a[:, 0].copy(), MODEL).dtype == dtype
        assert fn(a, MODEL).shape == (600, 3)
    # Integers (e.g. raw gyro counts) are filtered in float64.
    counts = np.round(x * 10).astype(np.int32)
    np.testing.assert_array_equal(fn(counts, MODEL), fn(counts.astype(np.float64), MODEL))
    # Explicit computation dtype.
    assert fn(x, MODEL, dtype=np.float32).dtype == np.float32
    with pytest.raises(TypeError, match="float32 or float64"):
        fn(x, MODEL, dtype=np.int16)
    for bad in (x.astype(np.complex128), x.astype(np.float16), np.array(["1.0"] * 10), x > 0):
        with pytest.raises(TypeError, match="dtype"):
            fn(bad, MODEL)
    for shape in [(600, 2), (600, 4), (10, 3, 1), ()]:
        with pytest.raises(ValueError, match="shape"):
            fn(np.zeros(shape), MODEL)
    with pytest.raises(ValueError, match="empty"):
        fn(np.zeros(0), MODEL)


@pytest.mark.parametrize("fn", [gyrodrift.kalman_filter, gyrodrift.ar_filter])
def test_non_contiguous_input_gives_same_result(fn, x) -> None:
    col = x[:, 1]  # strided view
    assert not col.flags.c_contiguous
    np.testing.assert_array_equal(fn(col, MODEL), fn(col.copy(), MODEL))
    fortran = np.asfortranarray(x)
    np.testing.assert_array_equal(fn(fortran, MODEL), fn(x, MODEL))
    rev = x[::-1]
    np.testing.assert_array_equal(fn(rev, MODEL), fn(rev.copy(), MODEL))
    swapped = x.astype(x.dtype.newbyteorder())  # non-native byte order: converted
    np.testing.assert_array_equal(fn(swapped, MODEL), fn(x, MODEL))
    readonly = x.copy()
    readonly.flags.writeable = False
    np.testing.assert_array_equal(fn(readonly, MODEL), fn(x, MODEL))


def test_input_is_not_modified(x) -> None:
    before = x.copy()
    x[5, 1] = np.nan
    before[5, 1] = np.nan
    with pytest.warns(RuntimeWarning):
        gyrodrift.kalman_filter(x, MODEL)
    np.testing.assert_array_equal(x, before)


def test_core_is_strict_zero_copy(x) -> None:
    # The low-level functions take only C-contiguous float32/float64 (no silent copies).
    _core.ar2_kalman_batch(x, PARAMS)
    _core.ar2_kalman_batch(x.astype(np.float32), PARAMS)
    with pytest.raises(TypeError):
        _core.ar2_kalman_batch(x[:, 0], PARAMS)  # strided
    with pytest.raises(TypeError):
        _core.ar2_kalman_batch(np.asfortranarray(x), PARAMS)
    with pytest.raises(TypeError):
        _core.ar2_kalman_batch(x.astype(np.int64), PARAMS)
    with pytest.raises(ValueError, match="expected 1 or 3 parameter sets"):
        _core.ar2_kalman_batch(x, PARAMS * 2)
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        _core.ar2_kalman_batch(np.zeros((5, 2)), PARAMS)
    with pytest.raises(ValueError, match="non-stationary"):
        _core.ar2_kalman_batch(x, [S(a1=1.5, a2=0.0, sigma2=1.0, q=1.0, r=1.0)])
    with pytest.raises(ValueError, match="bad argument"):
        _core.ar2_kalman_batch(x, [S(a1=0.1, a2=0.0, sigma2=1.0, q=1.0, r=0.0)])  # r = 0
    with pytest.raises(ValueError, match="non-finite"):
        _core.Ar2Kalman(S(a1=0.1, a2=0.0, sigma2=1.0, mean=float("inf"), q=1.0, r=1.0))
    with pytest.raises(TypeError):  # a bound configuration, not 13 positional numbers
        _core.ar2_kalman_batch(x, [(0.1, 0.0, 1.0, 0.0, 1.0, 1.0)])
    with pytest.raises(TypeError):  # keyword-only fields
        S(0.1, 0.0, 1.0, 0.0, 1.0, 1.0)


def test_stateful_filter_arguments(x) -> None:
    kf = KalmanFilter(MODEL, dtype=np.float32)
    assert kf.process(x[:, 0]).dtype == np.float32
    with pytest.raises(ValueError, match="1-D"):
        kf.process(x)
    with pytest.raises(TypeError, match="float32 or float64"):
        KalmanFilter(MODEL, dtype=np.int32)
    assert KalmanFilter(MODEL).gain is None
    k0, k1 = KalmanFilter(MODEL, steady_state=True).gain
    assert 0.0 < k0 < 1.0 and np.isfinite(k1)


def test_large_batch_three_axes_float32(rng) -> None:
    # 2e5 x 3 samples through the GIL-free batch path, float32 in and out, finite.
    a = rng.normal(0.0, 1.0, (200_000, 3)).astype(np.float32)
    res = kalman_filter_result(a, MODEL)
    out, faults = res.y, res.faults
    assert out.dtype == np.float32 and faults.tolist() == [0, 0, 0]
    assert np.all(np.isfinite(out))


@pytest.mark.parametrize("fn", [gyrodrift.kalman_filter, gyrodrift.ar_filter])
def test_out_argument(fn, x) -> None:
    for dtype in (np.float64, np.float32):
        a = x.astype(dtype)
        want = fn(a, MODEL)
        out = np.empty_like(a)
        got = fn(a, MODEL, out=out)
        assert got is out
        np.testing.assert_array_equal(out, want)
        inplace = a.copy()
        fn(inplace, MODEL, out=inplace)  # each sample is read before it is overwritten
        np.testing.assert_array_equal(inplace, want)
    with pytest.raises(TypeError, match="out must be"):
        fn(x, MODEL, out=np.empty(x.shape, np.float32))  # dtype differs from the computation
    with pytest.raises(TypeError, match="out must be"):
        fn(x, MODEL, out=np.empty((3, 600)).T)  # not C-contiguous
    with pytest.raises(ValueError, match="shape of x"):
        fn(x, MODEL, out=np.empty((599, 3)))
    ro = np.empty_like(x)
    ro.flags.writeable = False
    with pytest.raises(ValueError, match="read-only"):
        fn(x, MODEL, out=ro)


# --- issue 13: out= partly overlapping x --------------------------------------------------


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("shift", [1, 2, -1, -3])
@pytest.mark.parametrize("axes", [1, 3])
def test_out_partly_overlapping_x_gives_the_result_of_a_copy(
    dtype: type, shift: int, axes: int
) -> None:
    """out= a view that partly overlaps x (not x itself) must not change the result: it
    did (error 0.54 in the issue), because samples were overwritten before being read."""
    from gyrodrift.filters.ar2 import ar_filter, kalman_filter

    model = Ar2Model(a1=0.6, a2=0.25, sigma2=1e-2, mean=0.05, r=2e-3)
    n = 500
    rng = np.random.default_rng(3)
    step = shift * axes  # elements between the two views
    buf = rng.normal(0.05, 0.1, n * axes + abs(step)).astype(dtype)
    shape = (n,) if axes == 1 else (n, 3)
    lo = buf[: n * axes].reshape(shape)
    hi = buf[abs(step):].reshape(shape)
    x, out = (lo, hi) if shift > 0 else (hi, lo)
    assert np.shares_memory(x, out) and x.ctypes.data != out.ctypes.data
    for run in (
        lambda a, o: kalman_filter(a, model, out=o),
        lambda a, o: kalman_filter(a, model, steady_state=True, out=o),
        lambda a, o: ar_filter(a, model, out=o),
    ):
        want = run(x.copy(), None)
        saved = buf.copy()
        got = run(x, out)
        assert got is out or np.shares_memory(got, out)
        np.testing.assert_array_equal(out, want)
        buf[:] = saved  # restore the input for the next filter
