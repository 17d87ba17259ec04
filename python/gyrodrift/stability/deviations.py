"""The deviation family with confidence intervals: overlapping Allan (oadev), modified
Allan (mdev), time (tdev), Hadamard (hdev), overlapping Hadamard (ohdev) and total (totdev)
deviation (NIST SP 1065 sec. 5.2), on the C++ kernels include/gyrodrift/stability/deviation_*.hpp.

API: one function per deviation with allantools' names (`mdev`, `tdev`, `hdev`, `ohdev`,
`totdev`; `oadev` is gyrodrift.stability.allan.oadev) and the dispatcher
`deviation(data, rate_hz, name, ...)`; all return the frozen `gyrodrift.stability.allan.AllanResult`
(its `adev` field holds the deviation named in `.deviation`). Units: the rate unit of the
input (deg/h in, deg/h out); tdev = tau mdev / sqrt(3) is in rate unit x s (deg/h x s =
arcsec for deg/h input; for phase input in the phase unit, as SP 1065's time deviation).

- Input: rate samples (kind="rate") or phase / cumulative angle samples (kind="phase",
  differenced to rates first). In memory, one fused pass serves all taus (double prefix
  sums over blocks, long double carries; within 1e-12 of the long double per-tau kernels
  that the chunked path runs).
- Records too large for memory: pass a numpy.memmap (np.load(path, mmap_mode="r")) or
  chunk_samples; the record is then streamed in chunks read from its file (four streams of
  at most chunk_samples float64 each plus the re-chunking carry: ~8 chunk_samples x 8 bytes,
  64 MiB at the default 2**20), never loaded whole.
- Confidence intervals: edf per tau (gyrodrift.stability.edf: Greenhall & Riley for
  mdev/tdev/hdev/ohdev, SP 1065 Table 7 for totdev, Table 5 for oadev) for the noise type
  alpha of each tau (gyrodrift.stability.noise_type: lag-1 ACF where >= 30 averages exist,
  slope fallback; the method used is in `.noise_id`), and the chi-squared interval of
  SP 1065 eq. 45.

Examples
--------
>>> import numpy as np, gyrodrift
>>> y = np.random.default_rng(0).standard_normal(10_000)
>>> r = gyrodrift.deviation(y, 100.0, "mdev")
>>> r.deviation, float(r.tau_s[0]), str(r.noise_id[0])
('mdev', 0.01, 'acf')
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from typing import Any

import numpy as np

from gyrodrift._native import core
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.stability import noise_type
from gyrodrift.stability.allan import (
    ONE_SIGMA_CI,
    AllanResult,
    checked_record,
    chi2_interval,
    factors_for_taus,
    oadev,
    record_scale,
    scaled_back,
)
from gyrodrift.stability.edf import edf_for
from gyrodrift.stability.record_source import RecordSource

__all__ = ["DEVIATIONS", "deviation", "hdev", "mdev", "ohdev", "tdev", "totdev"]

#: Names accepted by deviation() (allantools' function names).
DEVIATIONS = ("oadev", "mdev", "tdev", "hdev", "ohdev", "totdev")

DEFAULT_CHUNK_SAMPLES = 1 << 20



def _kernel(name: str) -> str:
    return "mdev" if name == "tdev" else name


def max_factor(name: str, n_rate: int) -> int:
    """Largest averaging factor with at least 2 terms (allantools' cut) for n_rate samples."""
    return int(core("allan").deviation_max_m(_kernel(name), int(n_rate)))


def _factors(name: str, n_rate: int, taus: Any, rate_hz: float, per_decade: int) -> np.ndarray:
    max_m = max_factor(name, n_rate)
    if max_m < 1:
        raise GyrodriftValueError(f"record too short for {name}: {n_rate} rate samples")
    return factors_for_taus(taus, max_m, rate_hz, per_decade,
                            f"record too short for {name} at tau = {{tau:g}} s: {n_rate} "
                            f"samples at {rate_hz:g} Hz support tau <= {max_m / rate_hz:g} s")


def _streamed(src: RecordSource, name: str, m_all: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Chunked sums per factor (bounded memory): the streaming kernels fed with aligned
    chunks of the record at the offsets each estimator reads."""
    lib = core("allan")
    p = src.pieces
    n = src.n
    sigma2 = np.empty(m_all.size)
    terms = np.empty(m_all.size, dtype=np.int64)
    for j, m in enumerate(int(v) for v in m_all):
        if name == "mdev":
            st = lib.ModAllanStream(m)
            for lo, hi in zip(p(0, m), p(m, 2 * m), strict=True):
                st.seed_diff(lo, hi)
            for y0, y1, y2 in zip(p(0, m), p(m, 2 * m), p(2 * m, 3 * m), strict=True):
                st.seed_inner(y0, y1, y2)
            n_adv = n - 3 * m  # n_terms - 2
            for y0, y1, y2, y3 in zip(p(0, n_adv), p(m, m + n_adv), p(2 * m, 2 * m + n_adv),
                                      p(3 * m, 3 * m + n_adv), strict=True):
                st.advance(y0, y1, y2, y3)
            st.finish()
        elif name == "ohdev":
            st = lib.OhdevStream(m)
            for y0, y1, y2 in zip(p(0, m), p(m, 2 * m), p(2 * m, 3 * m), strict=True):
                st.seed(y0, y1, y2)
            n_adv = n - 3 * m  # n_terms - 1
            for y0, y1, y2, y3 in zip(p(0, n_adv), p(m, m + n_adv), p(2 * m, 2 * m + n_adv),
                                      p(3 * m, 3 * m + n_adv), strict=True):
                st.advance(y0, y1, y2, y3)
            st.finish()
        elif name == "hdev":
            st = lib.HdevStream(m)
            for y in p(0, n):
                st.push(y)
        elif name == "totdev":
            st = lib.OadevStream(m, "rate")  # the Allan sums on the reflected record
            b0 = 1 - m
            for lo, hi in zip(p(b0, b0 + m), p(b0 + m, b0 + 2 * m), strict=True):
                st.seed(lo, hi)
            n_adv = n - 2  # n_terms - 1
            for y0, y1, y2 in zip(p(b0, b0 + n_adv), p(b0 + m, b0 + m + n_adv),
                                  p(b0 + 2 * m, b0 + 2 * m + n_adv), strict=True):
                st.advance(y0, y1, y2)
            st.finish()
        else:  # pragma: no cover - guarded by deviation()
            raise GyrodriftValueError(name)
        sigma2[j] = st.sigma2()
        terms[j] = st.terms
    return sigma2, terms


def deviation(
    data: np.ndarray,
    rate_hz: float,
    name: str = "oadev",
    *,
    kind: str = "rate",
    taus: str | np.ndarray | list[float] = "octave",
    per_decade: int = 10,
    ci: float = ONE_SIGMA_CI,
    alpha: int | np.ndarray | str | None = None,
    chunk_samples: int | None = None,
    threads: int | None = None,
    progress: bool | str = "auto",
) -> AllanResult:
    """Deviation `name` (one of DEVIATIONS) with chi-squared confidence intervals.

    Parameters
    ----------
    data
        1-D rate samples (kind="rate") or phase / cumulative angle samples
        (kind="phase"). A numpy.memmap is streamed from its file (bounded memory).
    rate_hz
        sample rate, Hz.
    name
        "oadev", "mdev", "tdev", "hdev", "ohdev" or "totdev".
    taus
        "octave", "decade" (per_decade points per decade), "all", or taus in s. The
        longest tau leaves at least 2 terms (allantools' cut): N/3 rate samples for
        mdev/tdev, (N-1)/3 for ohdev, N/4 for hdev, N for totdev.
    ci
        two-sided probability of the interval (default 1 sigma, 0.683).
    alpha
        noise exponent for the edf: None (default) the lag-1 ACF method where at
        least 30 averages exist, the slope method beyond (gyrodrift.stability.noise_type);
        "slope": the slope method everywhere; or integers (one, or one per tau).
    chunk_samples
        chunk of the streamed path (default 2**20); forces it when given.
    threads
        worker threads for the in-memory kernels (each takes one half of the term
        range of a group of taus; None: all cores; the result is the same for any count).
    progress
        passed to gyrodrift.stability.allan.oadev for name="oadev" (ignored otherwise).

    Raises
    ------
    ValueError
        unknown name, not 1-D, too short, NaN/Inf, bad rate or taus.

    Examples
    --------
    >>> x = np.random.default_rng(0).standard_normal(4096)  # white rate noise, 100 Hz
    >>> r = deviation(x, 100.0, "mdev")
    >>> r.deviation, r.tau_s[:3].tolist(), str(r.noise_id[0])
    ('mdev', [0.01, 0.02, 0.04], 'acf')
    """
    if name not in DEVIATIONS:
        raise GyrodriftValueError(f"name must be one of {', '.join(DEVIATIONS)}, got {name!r}")
    if name == "oadev":
        return oadev(data, rate_hz, kind=kind, taus=taus, per_decade=per_decade, ci=ci,
                     alpha=alpha, chunk_samples=chunk_samples, progress=progress,
                     threads=threads)
    is_memmap = isinstance(data, np.memmap)
    arr = checked_record(data, rate_hz, kind, "data")
    c = record_scale(arr, int(chunk_samples or DEFAULT_CHUNK_SAMPLES))
    if c != 1.0:  # extreme magnitude: as oadev, analysed scaled by a power of two
        return scaled_back(deviation(np.asarray(arr, dtype=np.float64) / c, rate_hz, name,
                                     kind=kind, taus=taus, per_decade=per_decade, ci=ci,
                                     alpha=alpha, chunk_samples=chunk_samples,
                                     progress=progress, threads=threads), c)
    n_rate = int(arr.shape[0]) - (1 if kind == "phase" else 0)
    m = _factors(name, n_rate, taus, float(rate_hz), per_decade)
    n_threads = (os.cpu_count() or 1) if threads is None else int(threads)
    if n_threads < 1:
        raise GyrodriftValueError(f"threads must be >= 1, got {threads!r}")
    kernel = _kernel(name)
    chunked = is_memmap or chunk_samples is not None
    src: RecordSource | None = None
    y: np.ndarray | None = None
    if chunked:
        chunk = int(chunk_samples or DEFAULT_CHUNK_SAMPLES)
        if chunk < 1:
            raise GyrodriftValueError(f"chunk_samples must be >= 1, got {chunk}")
        src = RecordSource(arr, kind, float(rate_hz), chunk)
        sigma2, terms = _streamed(src, kernel, m)
    else:
        if kind == "phase":
            y = np.diff(np.asarray(arr, dtype=np.float64)) * float(rate_hz)
        else:
            y = arr if arr.dtype in (np.float64, np.float32) else arr.astype(np.float64)
            y = np.ascontiguousarray(y)
        try:
            sigma2, terms = core("allan").deviation_sigma2(y, m, kernel, n_threads)
        except ValueError as exc:
            bad = int(np.count_nonzero(~np.isfinite(y)))
            if bad:
                raise GyrodriftValueError(
                    f"data: {bad} NaN/Inf samples; drop or repair them first "
                    "(gyrodrift.io.records.load_record has an explicit nan_policy)") from exc
            raise
    if not np.any(sigma2 > 0):
        raise GyrodriftValueError(
            f"data: the record is constant ({name} is zero at all {m.size} taus)")
    tau_s = m / float(rate_hz)
    dev = np.sqrt(sigma2)
    if name == "tdev":
        dev = tau_s * dev / math.sqrt(3.0)  # SP 1065 eq. 15
    alpha_arr, method = _alpha(name, alpha, m, tau_s, dev, n_rate, y, src, arr, kind,
                               float(rate_hz))
    n_phase = n_rate + 1
    edf = np.maximum(edf_for(name, n_phase, m, alpha_arr), 1.0)
    lo, hi = chi2_interval(dev, edf, ci)
    return AllanResult(tau_s, m, dev, terms, edf, alpha_arr, lo, hi, float(ci), int(arr.shape[0]),
                       float(rate_hz), kind, deviation=name, noise_id=method)


def _alpha(name: str, alpha: Any, m: np.ndarray, tau_s: np.ndarray, dev: np.ndarray,
           n_rate: int, y: np.ndarray | None, src: RecordSource | None, arr: np.ndarray, kind: str,
           rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Noise type per tau and how it was found ("acf", "slope", "given")."""
    modified = name in ("mdev", "tdev")
    slope_dev = dev / tau_s if name == "tdev" else dev
    if alpha is None or (isinstance(alpha, str) and alpha in ("acf", "auto")):
        slope = noise_type.slope_alpha(tau_s, slope_dev, modified=modified)
        if y is not None:
            averages = noise_type.averages_in_memory(y)
        else:
            if src is None:  # pragma: no cover
                src = RecordSource(arr, kind, rate_hz, DEFAULT_CHUNK_SAMPLES)
            averages = noise_type.averages_from_pieces(src.raw_pieces)
        return noise_type.alpha_per_tau(averages, m, n_rate, slope)
    if isinstance(alpha, str):
        if alpha != "slope":
            raise GyrodriftValueError(
                f"alpha must be None, 'acf', 'slope' or integers, got {alpha!r}")
        a = noise_type.slope_alpha(tau_s, slope_dev, modified=modified)
        return a, np.full(m.size, "slope")
    a = np.broadcast_to(np.asarray(alpha, dtype=np.int64), m.shape).copy()
    return a, np.full(m.size, "given")


def _named(name: str) -> Callable[..., AllanResult]:
    def fn(data: np.ndarray, rate_hz: float, **kwargs: Any) -> AllanResult:
        return deviation(data, rate_hz, name, **kwargs)

    fn.__name__ = name
    fn.__qualname__ = name
    fn.__doc__ = (f"{name} with confidence intervals: deviation(data, rate_hz, {name!r}, ...) "
                  "(see gyrodrift.stability.deviations.deviation for the arguments).\n\n"
                  "Examples\n--------\n"
                  ">>> x = np.random.default_rng(0).standard_normal(4096)\n"
                  f">>> r = {name}(x, 100.0)\n"
                  ">>> r.deviation, r.tau_s[:2].tolist()\n"
                  f"({name!r}, [0.01, 0.02])\n")
    return fn


mdev = _named("mdev")
tdev = _named("tdev")
hdev = _named("hdev")
ohdev = _named("ohdev")
totdev = _named("totdev")
