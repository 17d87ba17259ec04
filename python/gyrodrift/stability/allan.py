"""Overlapping Allan deviation with confidence intervals (IEEE Std 952-1997 Annex C,
NIST SP 1065 sec. 5.2.4 and 5.3), on the C++ kernel include/gyrodrift/stability/allan.hpp.

- `oadev(x, rate_hz, ...)`: rate samples (deg/h, or any unit: the deviation has the same
  unit) or phase samples (cumulative angle, kind="phase"), tau grid "octave", "decade" (M per
  decade), "all" or explicit averaging factors. O(N) per tau, long double sums.
- Records too large for memory: pass a `numpy.memmap` (e.g. `np.load(path, mmap_mode="r")`).
  It is then read from its file with plain file reads (never mapped into the process), so the
  memory in use stays bounded whatever the record length: rate input runs the fused kernel
  over term ranges with one window per segment, windows of about 3 * chunk_samples * 8
  bytes in all plus the segments' spans (a few blocks each); measured peak (tracemalloc)
  about 4 * chunk_samples * 8 bytes, 32 MiB at the default chunk_samples = 2**20; phase
  input runs the per-tau kernel on three chunk buffers (y_i, y_{i+m}, y_{i+2m}),
  3 * chunk_samples * 8 bytes. In-memory arrays go to the kernel zero-copy
  (float64/float32, C-contiguous); the fused kernel runs two factor groups (on up to
  `threads` cores, same result for any count), each with a workspace of (segments x block)
  doubles: 2.6 + 4.7 MB for octave taus at 1e8 samples.
- Confidence intervals: equivalent degrees of freedom from the simple approximations of
  NIST SP 1065 Table 5 (Stein 1985) for the noise type alpha of each tau, and the chi-squared
  interval of SP 1065 eq. 45:
  sigma^2 edf / chi2_{1-p/2} <= sigma_true^2 <= sigma^2 edf / chi2_{p/2}.
"""

from __future__ import annotations

import math
import mmap
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.special
from tqdm import tqdm

from gyrodrift._native import core
from gyrodrift._scale import normalising_scale, scale_for_peak
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.io.records import is_file_backed, iter_chunks
from gyrodrift.stability import noise_type
from gyrodrift.stability.edf import edf_simple
from gyrodrift.stability.record_source import RecordSource

__all__ = [
    "ONE_SIGMA_CI",
    "AllanResult",
    "averaging_factors",
    "checked_record",
    "chi2_interval",
    "factors_for_taus",
    "lag1_noise_id",
    "oadev",
    "record_scale",
    "scaled_back",
]


#: Probability of the 1-sigma two-sided interval, erf(1/sqrt(2)).
ONE_SIGMA_CI = math.erf(1.0 / math.sqrt(2.0))

#: Default chunk of a memory-mapped record, samples (8 MiB per float64 buffer).
DEFAULT_CHUNK_SAMPLES = 1 << 20

#: Block of the fused kernel (term indices per block). 65536 measured ~15 % faster than 4096
#: at 1e6..1e8 samples (fewer far segments); its workspace is (segments x block) doubles
#: per factor group, 2.6 + 4.7 MB for octave taus at 1e8 samples.
FUSED_BLOCK = 1 << 16
#: Smaller block for memory-mapped records read with small chunks (bounded windows).
SMALL_BLOCK = 1 << 12

#: Work (squared differences over all taus) above which progress="auto" shows a bar.
AUTO_PROGRESS_TERMS = 300_000_000


@dataclass(frozen=True)
class AllanResult:
    """Overlapping Allan deviation per tau, with its confidence interval.

    Attributes
    ----------
    tau_s
        averaging times, s.
    m
        averaging factors (tau = m / rate_hz).
    adev
        deviation, in the rate unit of the input (e.g. deg/h).
    terms
        number of squared differences behind each value.
    edf
        equivalent degrees of freedom (SP 1065 Table 5).
    alpha
        power-law noise exponent used for each edf (S_y(f) ~ f^alpha).
    ci_low, ci_high
        chi-squared confidence interval of the deviation (probability `ci`).
    ci
        two-sided probability of the interval.
    n_samples
        record length (rate samples, or phase samples for kind="phase").
    rate_hz
        sample rate.
    kind
        "rate" or "phase".
    deviation
        which deviation `adev` holds ("oadev", or "mdev", "tdev", "hdev",
        "ohdev", "totdev" from gyrodrift.deviation).
    noise_id
        per tau, how alpha was found: "acf" (lag-1 autocorrelation), "slope"
        (local slope of the curve) or "given" (by the caller).

    Examples
    --------
    >>> r = oadev(np.random.default_rng(0).standard_normal(1000), 10.0)
    >>> r.tau_s[:3].tolist(), r.kind
    ([0.1, 0.2, 0.4], 'rate')
    """

    tau_s: np.ndarray
    m: np.ndarray
    adev: np.ndarray
    terms: np.ndarray
    edf: np.ndarray
    alpha: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    ci: float
    n_samples: int
    rate_hz: float
    kind: str
    deviation: str = "oadev"
    noise_id: np.ndarray | None = None

    def scaled(self, factor: float) -> AllanResult:
        """The same result with the deviation in another unit (deviation x factor > 0)."""
        if not (factor > 0 and math.isfinite(factor)):
            raise GyrodriftValueError(f"factor must be positive and finite, got {factor!r}")
        return AllanResult(
            self.tau_s, self.m, self.adev * factor, self.terms, self.edf, self.alpha,
            self.ci_low * factor, self.ci_high * factor, self.ci, self.n_samples,
            self.rate_hz, self.kind, self.deviation, self.noise_id,
        )

    def as_dict(self) -> dict[str, object]:
        return {
            "tau_s": self.tau_s.tolist(),
            "m": self.m.tolist(),
            "adev": self.adev.tolist(),
            "terms": self.terms.tolist(),
            "edf": self.edf.tolist(),
            "alpha": self.alpha.tolist(),
            "ci_low": self.ci_low.tolist(),
            "ci_high": self.ci_high.tolist(),
            "ci": self.ci,
            "n_samples": self.n_samples,
            "rate_hz": self.rate_hz,
            "kind": self.kind,
            "deviation": self.deviation,
            "noise_id": None if self.noise_id is None else [str(v) for v in self.noise_id],
        }


def _max_m(n_data: int, kind: str) -> int:
    # At least two squared differences (allantools drops single-difference results too):
    # rate: N - 2m + 1 >= 2; phase: Np - 2m >= 2.
    return max((n_data - 1) // 2, 0) if kind == "rate" else max((n_data - 2) // 2, 0)


def averaging_factors(
    n_data: int, taus: str | np.ndarray | list[float] = "octave", *, rate_hz: float = 1.0,
    kind: str = "rate", per_decade: int = 10,
) -> np.ndarray:
    """Averaging factors m (int64, increasing) for a record of n_data samples.

    taus: "octave" (1, 2, 4, ...), "decade" (round(10^(k/per_decade)), duplicates removed),
    "all" (1, 2, 3, ...), or explicit taus in seconds (rounded to m = tau * rate_hz; every one
    must fit the record, else ValueError naming the longest tau the record supports).

    Examples
    --------
    >>> averaging_factors(100).tolist()
    [1, 2, 4, 8, 16, 32]
    """
    if kind not in ("rate", "phase"):
        raise GyrodriftValueError(f"kind must be 'rate' or 'phase', got {kind!r}")
    max_m = _max_m(int(n_data), kind)
    if max_m < 1:
        raise GyrodriftValueError(
            f"record too short for Allan analysis: {n_data} {kind} samples "
            f"(need at least {3 if kind == 'rate' else 4})"
        )
    return factors_for_taus(taus, max_m, rate_hz, per_decade,
                            f"record too short for tau = {{tau:g}} s: {n_data} samples at "
                            f"{rate_hz:g} Hz support tau <= {max_m / rate_hz:g} s (two "
                            "non-overlapping clusters of 2 tau)")


def record_scale(arr: np.ndarray, chunk: int = DEFAULT_CHUNK_SAMPLES) -> float:
    """`gyrodrift._scale.normalising_scale` of a record (1.0 inside the safe range), a
    file-backed memory map read in chunks from its file (no page of the mapping resident).

    Examples
    --------
    >>> record_scale(np.array([1.0, -3.0])), record_scale(np.array([1e150])) > 1e149
    (1.0, True)
    """
    if not is_file_backed(arr):
        return normalising_scale(arr)
    peak = 0.0
    for p in iter_chunks(arr, max(int(chunk), 1)):
        pk = max(float(np.max(p)), -float(np.min(p))) if p.size else 0.0
        if pk > peak:  # NaN is left to the kernels' own check
            peak = pk
    return scale_for_peak(peak)


def scaled_back(res: AllanResult, c: float) -> AllanResult:
    """The deviation of the record c times the one analysed (`AllanResult.scaled`); a
    deviation beyond the floating-point range at that scale is refused with one line.

    Examples
    --------
    >>> r = oadev(np.random.default_rng(0).normal(size=256), 1.0, progress=False)
    >>> bool(np.allclose(scaled_back(r, 2.0**200).adev, r.adev * 2.0**200))
    True
    """
    with np.errstate(over="ignore"):
        out = res.scaled(c)
    if not (np.all(np.isfinite(out.adev)) and np.all(np.isfinite(out.ci_high))):
        raise GyrodriftValueError(
            f"x: the {res.deviation} of this record (or its interval) is beyond the "
            f"floating-point range (up to {float(np.max(res.adev)):.3g} x {c:.3g})")
    return out


def checked_record(x: object, rate_hz: object, kind: str, arg: str) -> np.ndarray:
    """``x`` as a 1-D real array (a numpy.memmap stays one, for the streamed paths), after
    checking the rate and kind shared by every deviation; `arg` names x in the messages.

    Examples
    --------
    >>> checked_record([1.0, 2.0, 3.0], 10.0, "rate", "x").shape
    (3,)
    """
    if not (isinstance(rate_hz, int | float) and math.isfinite(rate_hz) and rate_hz > 0):
        raise GyrodriftValueError(f"rate_hz must be a positive finite number, got {rate_hz!r}")
    if kind not in ("rate", "phase"):
        raise GyrodriftValueError(f"kind must be 'rate' or 'phase', got {kind!r}")
    arr = x if isinstance(x, np.memmap) else np.asarray(x)
    if arr.ndim != 1:
        raise GyrodriftValueError(f"{arg}: expected a 1-D record, got shape {arr.shape}")
    if not np.issubdtype(arr.dtype, np.number) or np.iscomplexobj(arr):
        raise GyrodriftTypeError(f"{arg}: expected real numbers, got dtype {arr.dtype}")
    return arr


def factors_for_taus(taus: str | np.ndarray | list[float], max_m: int, rate_hz: float,
                     per_decade: int, too_long: str) -> np.ndarray:
    """Averaging factors m (int64, increasing, 1..max_m) for a tau grid name ("octave",
    "decade", "all") or explicit taus in seconds; `too_long` is the error message for a tau
    beyond max_m, with ``{tau}`` for the longest tau asked for. Shared by every deviation.

    Examples
    --------
    >>> factors_for_taus([0.1, 0.2], 10, 10.0, 10, "too long: {tau}").tolist()
    [1, 2]
    """
    if isinstance(taus, str):
        if taus not in ("octave", "decade", "all"):
            raise GyrodriftValueError(
                f"taus must be 'octave', 'decade', 'all' or an array, got {taus!r}")
        return np.asarray(core("allan").tau_grid(taus, max_m, per_decade), dtype=np.int64)
    tau_arr = np.asarray(taus, dtype=np.float64)
    if tau_arr.ndim != 1 or tau_arr.size == 0 or not np.all(np.isfinite(tau_arr)):
        raise GyrodriftValueError("taus: expected a non-empty 1-D array of finite taus in seconds")
    m = np.unique(np.rint(tau_arr * rate_hz).astype(np.int64))
    if m[0] < 1:
        raise GyrodriftValueError(
            f"tau {tau_arr.min()} s is shorter than one sample (1/{rate_hz} s)")
    if m[-1] > max_m:
        raise GyrodriftValueError(too_long.format(tau=float(tau_arr.max())))
    return m


def chi2_interval(dev: np.ndarray, edf: np.ndarray, ci: float = ONE_SIGMA_CI
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Two-sided chi-squared interval of a deviation (NIST SP 1065 eq. 45), probability ci.

    Examples
    --------
    >>> lo, hi = chi2_interval(np.array([1.0]), np.array([100.0]))
    >>> bool(lo[0] < 1.0 < hi[0])
    True
    """
    if not 0.0 < ci < 1.0:
        raise GyrodriftValueError(f"ci must be in (0, 1), got {ci!r}")
    dev = np.asarray(dev, dtype=np.float64)
    edf = np.asarray(edf, dtype=np.float64)
    p_low = (1.0 - ci) / 2.0
    # scipy.stats.chi2.ppf(p, edf) is 2 gammaincinv(edf / 2, p) for edf > 0 (scipy's own
    # _ppf); called directly it skips ~0.2 ms of argument handling per call (a tenth of a
    # 1e6-sample hdev). Not a positive edf: NaN, as chi2.ppf gives.
    ok = edf > 0.0
    half = np.where(ok, edf, 1.0) / 2.0
    chi2_low = np.where(ok, 2.0 * scipy.special.gammaincinv(half, p_low), np.nan)
    chi2_high = np.where(ok, 2.0 * scipy.special.gammaincinv(half, 1.0 - p_low), np.nan)
    var = dev * dev
    return np.sqrt(var * edf / chi2_high), np.sqrt(var * edf / chi2_low)


def lag1_noise_id(y: np.ndarray, m: int, *, dmax: int = 2, max_points: int = 1 << 16
                  ) -> int | None:
    """Power-law noise exponent alpha (S_y(f) ~ f^alpha) of rate (frequency) data at
    averaging factor m by the lag-1 autocorrelation method (Riley & Greenhall 2004; NIST
    SP 1065 sec. 5.6; gyrodrift.stability.noise_type.lag1_alpha) on the first min(N // m,
    max_points)
    non-overlapping averages. Returns None when fewer than 30 averages exist (the method's
    minimum).

    Examples
    --------
    >>> lag1_noise_id(np.random.default_rng(0).standard_normal(10_000), 1)  # white FM
    0
    """
    y = np.asarray(y, dtype=np.float64)
    n_avg = min(y.size // m, max_points)
    if n_avg < noise_type.MIN_ACF_POINTS:
        return None
    return noise_type.lag1_alpha(y[: n_avg * m].reshape(n_avg, m).mean(axis=1), dmax=dmax)


def _filename(mm: np.memmap) -> str:
    if mm.filename is None:  # a memmap always has a file; None only for anonymous maps
        raise GyrodriftValueError("memory map without a file")
    return str(mm.filename)


def _file_chunks(mm: np.memmap, start: int, stop: int, chunk: int) -> Iterator[np.ndarray]:
    """float64 copies of mm[start:stop] in pieces of at most `chunk`, read with file reads."""
    itemsize = mm.dtype.itemsize
    with open(_filename(mm), "rb") as fh:
        pos = start
        while pos < stop:
            count = min(chunk, stop - pos)
            fh.seek(mm.offset + pos * itemsize)
            piece = np.fromfile(fh, dtype=mm.dtype, count=count)
            if piece.size != count:
                raise GyrodriftValueError(f"{mm.filename}: file shorter than its header says")
            yield np.ascontiguousarray(piece, dtype=np.float64)
            pos += count


def _read_range(fh: Any, mm: np.memmap, start: int, stop: int) -> np.ndarray:
    """float64 copy of mm[start:stop] (clipped to the record) read from the open file."""
    stop = min(stop, mm.shape[0])
    if stop <= start:
        return np.empty(0)
    fh.seek(mm.offset + start * mm.dtype.itemsize)
    piece = np.fromfile(fh, dtype=mm.dtype, count=stop - start)
    if piece.size != stop - start:
        raise GyrodriftValueError(f"{mm.filename}: file shorter than its header says")
    return np.ascontiguousarray(piece, dtype=np.float64)


def _chunked_fused_rate(mm: np.memmap, m_all: np.ndarray, chunk: int, bar: tqdm
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Rate input from a file: the fused kernel over term ranges of W samples, one window
    per segment (memory ~ segments x W x 8 bytes, W ~ 3 chunk / segments)."""
    n_data = mm.shape[0]
    sigma2 = np.empty(m_all.size)
    terms = np.empty(m_all.size, dtype=np.int64)
    # The in-memory block when the chunk allows it; with the in-memory factor groups
    # (oadev_fused_groups) the results are then bit-identical.
    block = FUSED_BLOCK if 3 * chunk >= 8 * FUSED_BLOCK else SMALL_BLOCK
    with open(_filename(mm), "rb") as fh:
        for lo, hi in core("allan").oadev_fused_groups(n_data, np.ascontiguousarray(m_all), block):
            group = np.ascontiguousarray(m_all[lo:hi])
            st = core("allan").OadevFusedStream(n_data, group, block)
            if n_data >= 4 * 64:  # the rate line the in-memory kernel removes
                st.set_ramp(_read_range(fh, mm, 0, 64), _read_range(fh, mm, n_data - 64, n_data))
            segs = st.segments()
            for j, m in enumerate(int(v) for v in group):
                for a, b in zip(_file_chunks(mm, 0, m, chunk), _file_chunks(mm, m, 2 * m, chunk),
                                strict=True):
                    st.seed(j, a, b)
                del a, b  # loop variables would keep the last two chunks alive
            width = max(block, (3 * chunk // len(segs)) // block * block)
            n_terms0 = st.n_terms0
            group_terms = n_data - 2 * group + 1
            for b0 in range(0, n_terms0, width):
                b1 = min(b0 + width, n_terms0)
                windows = [_read_range(fh, mm, b0 + start, b1 + start + span)
                           for start, span in segs]
                st.process(b0, b1, windows)
                del windows  # before the next range is read: one set of windows at a time
                bar.update(int(np.clip(group_terms - b0, 0, b1 - b0).sum()))
            sigma2[lo:lo + group.size], terms[lo:lo + group.size] = st.finish()
    return sigma2, terms


def _streamed_sigma2(pieces: Callable[[int, int], Iterator[np.ndarray]], n_data: int,
                     m_all: np.ndarray, kind: str, bar: tqdm
                     ) -> tuple[np.ndarray, np.ndarray]:
    """One OadevStream per factor m over float64 chunks of record[start:stop] from
    pieces(start, stop) (views of an array or file reads), three streams m apart."""
    sigma2 = np.empty(m_all.size)
    terms = np.empty(m_all.size, dtype=np.int64)
    for j, m in enumerate(int(v) for v in m_all):
        acc = core("allan").OadevStream(m, kind)
        if kind == "rate":
            for lo, hi in zip(pieces(0, m), pieces(m, 2 * m), strict=True):
                acc.seed(lo, hi)
        # phase: n - 2m terms; rate: n - 2m + 1 terms, the last one added by finish()
        n_adv = n_data - 2 * m
        streams = zip(pieces(0, n_adv), pieces(m, m + n_adv), pieces(2 * m, 2 * m + n_adv),
                      strict=True)
        for y0, y1, y2 in streams:
            acc.advance(y0, y1, y2)
            bar.update(y0.size)
        if kind == "rate":
            acc.finish()
            bar.update(1)
        sigma2[j] = acc.sigma2()
        terms[j] = acc.terms
    return sigma2, terms


def _chunked_sigma2(mm: np.memmap, m_all: np.ndarray, kind: str, chunk: int,
                    bar: tqdm) -> tuple[np.ndarray, np.ndarray]:
    if kind == "rate":
        return _chunked_fused_rate(mm, m_all, chunk, bar)
    return _streamed_sigma2(lambda start, stop: _file_chunks(mm, start, stop, chunk),
                            mm.shape[0], m_all, kind, bar)


def oadev(
    x: np.ndarray,
    rate_hz: float,
    *,
    kind: str = "rate",
    taus: str | np.ndarray | list[float] = "octave",
    per_decade: int = 10,
    ci: float = ONE_SIGMA_CI,
    alpha: int | np.ndarray | str | None = None,
    chunk_samples: int | None = None,
    progress: bool | str = "auto",
    threads: int | None = None,
) -> AllanResult:
    """Overlapping Allan deviation with chi-squared confidence intervals.

    Parameters
    ----------
    x
        1-D rate samples (any rate unit; kind="rate") or cumulative angle samples
        (kind="phase"; the deviation is then in angle unit per second). Angle increments
        per sample are rate x dt: divide them by dt first (gyrodrift.io.records does). A
        numpy.memmap is processed in chunks read from its file (bounded memory).
    rate_hz
        sample rate, Hz.
    taus
        "octave", "decade" (per_decade points per decade), "all", or taus in s.
    ci
        two-sided probability of the confidence interval (default 1 sigma, 0.683).
    alpha
        noise exponent for the edf (one for all taus, or one per tau); default (None
        or "acf"): the lag-1 autocorrelation method (gyrodrift.stability.noise_type) at every
        tau
        with at least 30 averages (reads at most 65536 averages per tau; a memmap in
        chunks), the local slope of the deviation (noise_alpha_from_slope, capped by the
        last ACF value) beyond; "slope": the slope method at every tau. The method used
        per tau is in the result's `noise_id`.
    chunk_samples
        chunk size of the memmap path (default 2**20); forces the chunked
        path for in-memory arrays too when given.
    progress
        tqdm bar on stderr: True, False or "auto" (when the work exceeds
        AUTO_PROGRESS_TERMS squared differences, a few seconds).
    threads
        worker threads of the in-memory rate path (None: all cores). The fused
        kernel runs factor groups (two cost-balanced halves); each thread takes whole
        groups, so the result is the same bit for bit for any thread count.

    Raises
    ------
    ValueError
        not 1-D, too short for the taus, NaN/Inf (with their count), bad rate.

    Examples
    --------
    >>> x = np.random.default_rng(0).standard_normal(100_000)  # white rate noise
    >>> r = oadev(x, 100.0, progress=False)
    >>> bool(abs(r.adev[0] - 1.0) < 0.01)  # ADEV at tau0 of unit white noise is 1
    True
    """
    is_memmap = isinstance(x, np.memmap)
    arr = checked_record(x, rate_hz, kind, "x")
    c = record_scale(arr, int(chunk_samples or DEFAULT_CHUNK_SAMPLES))
    if c != 1.0:
        # A record of extreme magnitude (its Allan sums overflow or underflow): analysed
        # divided by a power of two (exact), the deviation scaled back. Such a record is
        # read into memory (a memmap too).
        return scaled_back(oadev(np.asarray(arr, dtype=np.float64) / c, rate_hz, kind=kind,
                                 taus=taus, per_decade=per_decade, ci=ci, alpha=alpha,
                                 chunk_samples=chunk_samples, progress=progress,
                                 threads=threads), c)
    n_data = int(arr.shape[0])
    m = averaging_factors(n_data, taus, rate_hz=rate_hz, kind=kind, per_decade=per_decade)
    n_terms = n_data - 2 * m + (1 if kind == "rate" else 0)
    work = int(n_terms.sum())
    show = (work > AUTO_PROGRESS_TERMS) if progress == "auto" else bool(progress)
    chunked = is_memmap or chunk_samples is not None
    n_threads = (os.cpu_count() or 1) if threads is None else int(threads)
    if n_threads < 1:
        raise GyrodriftValueError(f"threads must be >= 1, got {threads!r}")
    with tqdm(total=work, disable=not show, unit="term", unit_scale=True,
              desc="Allan", leave=False) as bar:
        if chunked:
            chunk = int(chunk_samples or DEFAULT_CHUNK_SAMPLES)
            if chunk < 1:
                raise GyrodriftValueError(f"chunk_samples must be >= 1, got {chunk}")
            if not (is_memmap and isinstance(arr.base, mmap.mmap) and arr.flags.c_contiguous):
                # In-memory arrays (and views into a memmap, whose file offset numpy does not
                # track) take the same chunked sums over views instead of file reads.
                sigma2, terms = _chunked_in_memory(np.asarray(arr), m, kind, chunk, bar)
            else:
                sigma2, terms = _chunked_sigma2(arr, m, kind, chunk, bar)
        else:
            x = arr if arr.dtype in (np.float64, np.float32) else arr.astype(np.float64)
            x = np.ascontiguousarray(x)
            sigma2 = np.empty(m.size)
            terms = np.empty(m.size, dtype=np.int64)
            # One fused pass over all taus; with a bar, groups of 8 taus so that it moves
            # (each group is one more pass over the record). Each call releases the GIL;
            # the binding checks finiteness in its first pass, the count is made here only
            # for the error message.
            group = 8 if show else m.size
            for lo in range(0, m.size, group):
                try:
                    lib = core("allan")
                    s2, t = lib.oadev_sigma2(
                        x, np.ascontiguousarray(m[lo:lo + group]),
                        lib.OadevOptions(kind=kind, method="fused", block=FUSED_BLOCK,
                                         threads=n_threads))
                except ValueError as exc:
                    bad = int(np.count_nonzero(~np.isfinite(x)))
                    if bad:
                        raise GyrodriftValueError(
                            f"x: {bad} NaN/Inf samples; drop or repair them first "
                            "(gyrodrift.io.records.load_record has an explicit nan_policy)"
                        ) from exc
                    raise
                sigma2[lo:lo + group] = s2
                terms[lo:lo + group] = t
                bar.update(int(n_terms[lo:lo + group].sum()))
    if not np.any(sigma2 > 0):
        raise GyrodriftValueError(f"x: the record is constant (its Allan deviation is zero at all "
                         f"{m.size} taus); nothing to analyse")
    if kind == "phase":
        sigma2 = sigma2 * rate_hz * rate_hz  # the kernel leaves out 1/tau0^2
    adev = np.sqrt(sigma2)
    tau_s = m / float(rate_hz)
    alpha_arr, method = _oadev_alpha(alpha, x, kind, m, tau_s, adev, rate_hz,
                                     int(chunk_samples or DEFAULT_CHUNK_SAMPLES))
    n_phase = n_data + 1 if kind == "rate" else n_data
    edf = np.maximum(edf_simple(n_phase, m, alpha_arr), 1.0)
    lo_ci, hi_ci = chi2_interval(adev, edf, ci)
    return AllanResult(tau_s, m, adev, terms, edf, alpha_arr, lo_ci, hi_ci, float(ci),
                       n_data, float(rate_hz), kind, "oadev", method)


def _oadev_alpha(alpha: int | np.ndarray | str | None, data: np.ndarray, kind: str,
                 m: np.ndarray, tau_s: np.ndarray, adev: np.ndarray, rate_hz: float,
                 chunk: int) -> tuple[np.ndarray, np.ndarray]:
    """Noise type per tau and the method per tau ("acf", "slope", "given"): the lag-1 ACF
    where >= 30 averages exist, else the slope capped by the last ACF value (None, "acf");
    the slope everywhere ("slope"); or the caller's integers."""
    if alpha is None or (isinstance(alpha, str) and alpha == "acf"):
        slope_alpha = noise_type.noise_alpha_from_slope(tau_s, adev)
        if isinstance(data, np.memmap) or kind == "phase":
            # bounded memory: averages read in chunks (file reads for a memmap)
            src = RecordSource(data, kind, float(rate_hz), chunk)
            averages = noise_type.averages_from_pieces(src.raw_pieces)
            n_rate = src.n
        else:
            x_id = np.asarray(data)
            averages = noise_type.averages_in_memory(x_id)
            n_rate = x_id.shape[0]
        return noise_type.alpha_per_tau(averages, m, n_rate, slope_alpha)
    if isinstance(alpha, str):
        if alpha != "slope":
            raise GyrodriftValueError(
                f"alpha must be None, 'acf', 'slope', or integers, got {alpha!r}")
        return noise_type.noise_alpha_from_slope(tau_s, adev), np.full(m.size, "slope")
    alpha_arr = np.broadcast_to(np.asarray(alpha, dtype=np.int64), m.shape).copy()
    return alpha_arr, np.full(m.size, "given")


def _chunked_in_memory(x: np.ndarray, m_all: np.ndarray, kind: str, chunk: int,
                       bar: tqdm) -> tuple[np.ndarray, np.ndarray]:
    x = np.ascontiguousarray(x, dtype=np.float64)
    bad = int(np.count_nonzero(~np.isfinite(x)))
    if bad:
        raise GyrodriftValueError(f"x: {bad} NaN/Inf samples; drop or repair them first")

    def pieces(start: int, stop: int) -> Iterator[np.ndarray]:
        for lo in range(start, stop, chunk):
            yield x[lo:min(lo + chunk, stop)]

    return _streamed_sigma2(pieces, x.size, m_all, kind, bar)
