"""Characterize a whole IMU: Allan deviation per channel, noise terms with intervals, Kalibr
export and a self-check by simulation (`gyrodrift characterize`).

Every channel is analysed in SI units (gyro rad/s, accelerometer m/s^2). The IEEE Std 952
Annex C fit (the default identifier, `gyrodrift.stability.allan_fit.fit_allan`: automatic fit
range, log-scale objective, misspecification-robust intervals, self-check) gives
sigma^2(tau) = sum_k C_k tau^k, k = -2..2,
from which, for a record unit U (rad/s or m/s^2)::

    Q = sqrt(C_-2 / 3)            U s           (quantization; rad, m/s)
    N = sqrt(C_-1)                U / sqrt(Hz)  (white noise density: Kalibr *_noise_density)
    B = sqrt(C_0) / 0.6643        U             (bias instability floor, sqrt(2 ln2 / pi))
    K = sqrt(3 C_1)               U / s / sqrt(Hz)  (random walk: Kalibr *_random_walk)
    R = sqrt(2 C_2)               U / s         (rate ramp)

so that the continuous-time densities Kalibr reads need no further factor (sigma^2 = N^2 / tau
for white noise of one-sided density N^2; sigma^2 = K^2 tau / 3 for a random walk driven by
white noise of density K^2). Kalibr's discrete-time values are sigma_d = N / sqrt(dt) (the
standard deviation of one sample) and sigma_bd = K sqrt(dt) (the standard deviation of one
bias step).

Intervals of the kept terms: the fit's (misspecification-robust, see
`gyrodrift.stability.allan_fit`) joined with the range the band below allows (so a term the
band admits at zero has an interval reaching zero). Dropped terms are 0 with an upper end
from a simultaneous confidence band for the Allan variance, the
chi-squared interval of every tau (edf of NIST SP 1065 Table 5) at probability
1 - (1 - ci) / n_taus (Bonferroni: the true curve lies inside the whole band with probability
>= ci), projected onto each coefficient by linear programming: C_k ranges over all models
sum_k C_k tau^k with C >= 0 that stay inside the band. When the model is right, the true C_k
is inside with probability >= ci whatever the correlation between taus and between terms (the
intervals are conservative). When no model of the chosen terms fits inside the band (noise
the terms do not describe, e.g. vibration), the band's log-width is widened by the smallest
factor that admits one, reported as `band_scale` (> 1 flags a misfit).

`method="gmwm"` identifies the terms by the generalized method of wavelet moments
(`gyrodrift.identify_gmwm`) instead of the Allan fit.

Examples
--------
>>> import numpy as np
>>> rng = np.random.default_rng(1)
>>> from gyrodrift.io.imu_data import ImuData
>>> rec = ImuData({"gyro_x": 1e-3 * rng.standard_normal(20000)}, 100.0, "sim", "npy", 20000)
>>> res = characterize(rec)
>>> round(res.channels[0].terms["N"].value / (1e-3 / 10.0), 1)  # N = sigma sqrt(dt)
1.0
"""

from __future__ import annotations

import base64
import io
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gyrodrift.errors import GyrodriftValueError
from gyrodrift.io.atomic import atomic_output, atomic_write_text
from gyrodrift.io.imu_data import CHANNELS, ImuData
from gyrodrift.io.json_text import json_text
from gyrodrift.stability import DEFAULT_IDENTIFIER, IEEE952_TERMS, MODEL_IDENTIFIERS
from gyrodrift.stability.allan import ONE_SIGMA_CI, AllanResult, oadev
from gyrodrift.stability.fit_check import FitCheck
from gyrodrift.stability.ieee952 import B_FLOOR_FACTOR
from gyrodrift.stability.self_check import check_summary, fit_check_of
from gyrodrift.units import TERM_UNITS

__all__ = [
    "TERMS",
    "ChannelResult",
    "CharacterizeResult",
    "SelfCheck",
    "TermEstimate",
    "characterize",
    "characterize_channels",
    "check_rows",
    "kalibr_values",
    "kalibr_warnings",
    "kalibr_yaml",
    "plot_sensor",
    "self_check",
    "version",
    "write_outputs",
]

TERMS: tuple[str, ...] = IEEE952_TERMS
_POWERS = {"Q": -2, "N": -1, "B": 0, "K": 1, "R": 2}
TERM_NAMES = {"Q": "quantization", "N": "white noise density", "B": "bias instability",
              "K": "random walk", "R": "rate ramp"}


def version() -> str:
    """The installed gyrodrift version (the package metadata, else the source tree's).

    Examples
    --------
    >>> import gyrodrift
    >>> version() == gyrodrift.__version__
    True
    """
    try:
        from importlib.metadata import version as _v

        return _v("gyrodrift")
    except Exception:
        return "0.1.0+src"


def _sensor(name: str) -> str:
    return "gyro" if name.startswith("gyro") else "accel"


@dataclass(frozen=True)
class TermEstimate:
    """One noise term in SI units with its interval (`ci` probability).

    Examples
    --------
    >>> TermEstimate(name="N", value=1e-5, ci_low=9e-6, ci_high=1.1e-5, unit="rad/s/sqrt(Hz)").name
    'N'
    """

    name: str
    value: float
    ci_low: float
    ci_high: float
    unit: str

    def as_dict(self) -> dict[str, object]:
        return {"name": self.name, "value": self.value, "ci_low": self.ci_low,
                "ci_high": self.ci_high, "unit": self.unit}

    def contains(self, x: float) -> bool:
        return self.ci_low <= x <= self.ci_high


@dataclass(frozen=True)
class ChannelResult:
    """Allan deviation and identified terms of one channel (SI units).

    Examples
    --------
    One white gyro channel (1e-4 rad/s per sample at 100 Hz):

    >>> from gyrodrift.io.imu_data import ImuData
    >>> rng = np.random.default_rng(0)
    >>> rec = ImuData({"gyro_x": rng.normal(0, 1e-4, 4096)}, rate_hz=100.0, source="bench",
    ...               fmt="npy", n_total=4096)
    >>> ch = characterize(rec).channels[0]
    >>> ch.channel, ch.sensor, ch.unit, sorted(ch.terms)
    ('gyro_x', 'gyro', 'rad/s', ['B', 'K', 'N', 'Q', 'R'])
    """

    channel: str
    sensor: str
    unit: str
    allan: AllanResult
    terms: dict[str, TermEstimate]
    fit_adev: np.ndarray
    method: str
    extra: dict[str, object] = field(default_factory=dict)
    #: whether the fitted model describes the measured curve (Allan deviation, or the
    #: wavelet variance of a GMWM fit), point by point; None where no model was fitted
    check: FitCheck | None = None

    def as_dict(self) -> dict[str, object]:
        a = self.allan
        return {
            "self_check": None if self.check is None else self.check.as_dict(),
            "channel": self.channel, "sensor": self.sensor, "unit": self.unit,
            "method": self.method,
            "taus": [{"tau_s": float(t), "adev": float(d), "ci_low": float(lo),
                      "ci_high": float(hi), "edf": float(e), "fit_adev": float(f)}
                     for t, d, lo, hi, e, f in zip(a.tau_s, a.adev, a.ci_low, a.ci_high, a.edf,
                                                   self.fit_adev, strict=True)],
            "terms": {k: v.as_dict() for k, v in self.terms.items()},
            **({"extra": self.extra} if self.extra else {}),
        }


@dataclass(frozen=True)
class CharacterizeResult:
    """The whole IMU: one ChannelResult per channel present.

    Examples
    --------
    The result of a one-channel record, and what its JSON form holds:

    >>> from gyrodrift.io.imu_data import ImuData
    >>> rng = np.random.default_rng(0)
    >>> rec = ImuData({"gyro_x": rng.normal(0, 1e-4, 4096)}, rate_hz=100.0, source="bench",
    ...               fmt="npy", n_total=4096)
    >>> res = characterize(rec)
    >>> res.method, list(res.as_dict())
    ('allan-nnls', ['version', 'method', 'ci', 'record', 'holds', 'channels'])
    """

    record: dict[str, object]
    channels: tuple[ChannelResult, ...]
    ci: float
    method: str
    version: str

    def channel(self, name: str) -> ChannelResult:
        for c in self.channels:
            if c.channel == name:
                return c
        raise KeyError(name)

    @property
    def holds(self) -> bool:
        """Every channel's fitted model describes its measured curve."""
        return all(c.check is None or c.check.holds for c in self.channels)

    def as_dict(self) -> dict[str, object]:
        return {"version": self.version, "method": self.method, "ci": self.ci,
                "record": self.record, "holds": self.holds,
                "channels": {c.channel: c.as_dict() for c in self.channels}}


# ------------------------------------------------------------------------------ the analysis

def _term_intervals(tau: np.ndarray, a: AllanResult, pos: np.ndarray, coeffs: np.ndarray,
                    used: Sequence[str], ci: float
                    ) -> tuple[dict[str, tuple[float, float]], float]:
    """Coefficient interval per term (module docstring): the range of C_k over all models
    sum_k C_k tau^k with C >= 0 inside the simultaneous (Bonferroni) band of every tau, by
    linear programming. Returns ({term: (c_low, c_high)}, band_scale); band_scale > 1 when no
    model of the chosen terms fits inside the band and the band's log-width had to be
    multiplied by it (a misfit: the record holds noise the terms do not describe)."""
    import scipy.optimize

    from gyrodrift.stability.allan import chi2_interval

    t, dev, edf = tau[pos], a.adev[pos], a.edf[pos]
    p_each = 1.0 - (1.0 - ci) / t.size
    lo, hi = chi2_interval(dev, edf, p_each)
    idx = [j for j, name in enumerate(TERMS) if name in used]
    basis = np.stack([t ** list(_POWERS.values())[j] for j in idx], axis=1) / (dev * dev)[:, None]
    col = np.linalg.norm(basis, axis=0)
    design = basis / col
    log_lo, log_hi = np.log(lo / dev), np.log(hi / dev)

    def solve(scale: float) -> dict[str, tuple[float, float]] | None:
        # Exponents capped below exp's overflow: a band that wide no longer limits the
        # model, so a misfit of any size still ends the widening with a finite scale.
        b_hi = np.exp(np.minimum(2.0 * scale * log_hi, 690.0))
        b_lo = np.exp(np.maximum(2.0 * scale * log_lo, -690.0))
        a_ub = np.vstack([design, -design])
        b_ub = np.concatenate([b_hi, -b_lo])
        out: dict[str, tuple[float, float]] = {}
        for jj, j in enumerate(idx):
            ends = []
            for sign in (1.0, -1.0):
                cost = np.zeros(len(idx))
                cost[jj] = sign
                r = scipy.optimize.linprog(cost, A_ub=a_ub, b_ub=b_ub, bounds=(0, None),
                                           method="highs")
                if r.status == 2:
                    return None
                if r.status == 3:  # unbounded above: the band does not limit this term
                    ends.append(math.inf)
                    continue
                if r.status != 0:
                    raise GyrodriftValueError(f"interval LP failed: {r.message}")
                ends.append(float(r.x[jj]) / col[jj])
            out[TERMS[j]] = (ends[0], ends[1])
        return out

    res = solve(1.0)
    if res is not None:
        return res, 1.0
    low_s, high_s = 1.0, 2.0
    while solve(high_s) is None:
        low_s, high_s = high_s, 2.0 * high_s
        if high_s > 1e4:
            raise GyrodriftValueError("no model of the chosen terms comes near the Allan deviation")
    for _ in range(20):
        mid = 0.5 * (low_s + high_s)
        if solve(mid) is None:
            low_s = mid
        else:
            high_s = mid
    final = solve(high_s)
    assert final is not None
    return final, high_s


def _coef_to_term(name: str, c: float) -> float:
    c = max(c, 0.0)
    if name == "Q":
        return math.sqrt(c / 3.0)
    if name == "N":
        return math.sqrt(c)
    if name == "B":
        return math.sqrt(c) / B_FLOOR_FACTOR
    if name == "K":
        return math.sqrt(3.0 * c)
    return math.sqrt(2.0 * c)


def characterize_channel(x: np.ndarray, rate_hz: float, channel: str, *, ci: float = ONE_SIGMA_CI,
                         taus: str = "octave", terms: Sequence[str] = TERMS,
                         method: str = DEFAULT_IDENTIFIER, threads: int | None = None
                         ) -> ChannelResult:
    """Allan deviation and noise terms of one channel in SI units (module docstring)."""
    sensor = _sensor(channel)
    a = oadev(x, rate_hz, taus=taus, ci=ci, progress=False, threads=threads)
    pos = a.adev > 0
    tau = a.tau_s
    used = [t for t in TERMS if t in terms]
    if int(pos.sum()) < max(len(used), 3):
        raise GyrodriftValueError(
            f"{channel}: {int(pos.sum())} usable taus; the record is too short to "
            f"identify {len(used)} terms")
    if method == "gmwm":
        return _gmwm_channel(x, rate_hz, channel, a, ci)
    if method not in MODEL_IDENTIFIERS:
        raise GyrodriftValueError(
            f"method must be one of {', '.join(MODEL_IDENTIFIERS)}, got {method!r}")
    # The default identifier, the same fit as `gyrodrift allan` and `identify`: automatic
    # range, log-scale objective, robust intervals, self-check (gyrodrift.stability.allan_fit).
    # It works in the record's own unit; C_k are (unit)^2 s^k whatever the unit.
    from gyrodrift.stability.allan_fit import fit_allan

    afit = fit_allan(tau, a.adev, a.edf, terms=tuple(used), ci=ci, n_samples=a.n_samples,
                     rate_hz=a.rate_hz)
    coeffs = np.zeros(len(TERMS))
    for t in afit.terms:
        coeffs[TERMS.index(t.name)] = t.coeff
    iv, band_scale = _term_intervals(tau, a, pos, coeffs, used, ci)
    est = {}
    for j, name in enumerate(TERMS):
        if name not in used:
            continue
        c = float(coeffs[j])
        if name in afit.names:
            # the fit's misspecification-robust interval (ratio to the value: unit-free),
            # joined with the band's range (which reaches 0 where the band admits no term)
            t = afit.term(name)
            v = _coef_to_term(name, c)
            est[name] = TermEstimate(
                name, v, min(v * t.ci_low / t.value, _coef_to_term(name, iv[name][0])),
                max(v * t.ci_high / t.value, _coef_to_term(name, iv[name][1])),
                TERM_UNITS[sensor][name].si)
        else:
            # dropped: zero, with the band's upper end (linear programming, docstring)
            est[name] = TermEstimate(name, 0.0, 0.0, _coef_to_term(name, iv[name][1]),
                                     TERM_UNITS[sensor][name].si)
    unit = "rad/s" if sensor == "gyro" else "m/s^2"
    return ChannelResult(channel, sensor, unit, a, est, afit.fit_adev, "allan-nnls",
                         {"coeffs": [float(c) for c in coeffs], "band_scale": band_scale,
                          "fit_tau_s": [afit.tau_min_s, afit.tau_max_s],
                          "fit_range": afit.range_note, "approximate": afit.approximate,
                          "b_readoff": {"value": afit.b_readoff, "tau_s": afit.b_readoff_tau_s,
                                        "unit": unit},
                          "k_upper_limit": (None if "K" not in afit.upper_limits
                                            else afit.upper_limits["K"] / 60.0),
                          "check": afit.check.as_dict()},
                         afit.check)


def _gmwm_channel(x: np.ndarray, rate_hz: float, channel: str, a: AllanResult,
                  ci: float) -> ChannelResult:
    """GMWM on one channel; its record unit is deg/h, so the channel is scaled by s
    into a pseudo-deg/h and the IEEE-unit results are taken back to SI: Q/s, 60 N/s, K/(60 s),
    R/(3600 s) (the unit factors of gyrodrift.stability.ieee952's docstring)."""
    from gyrodrift.stability.gmwm import identify_gmwm as gmwm
    sensor = _sensor(channel)
    s = TERM_UNITS["gyro"]["B"].ieee_factor if sensor == "gyro" else 1.0
    res = gmwm(np.asarray(x, dtype=np.float64) * s, rate_hz, ci=ci)
    back = {"Q": 1.0 / s, "N": 60.0 / s, "K": 1.0 / (60.0 * s), "R": 1.0 / (3600.0 * s)}
    est: dict[str, TermEstimate] = {}
    extra: dict[str, object] = {"model": res.model}
    for prm in res.params:
        if prm.name in back:
            f = back[prm.name]
            est[prm.name] = TermEstimate(prm.name, prm.value * f, prm.ci_low * f,
                                         prm.ci_high * f, TERM_UNITS[sensor][prm.name].si)
        else:
            extra[prm.name] = {"value": prm.value, "ci_low": prm.ci_low, "ci_high": prm.ci_high,
                               "unit": prm.unit if not prm.name.endswith("sigma")
                               else ("rad/s" if sensor == "gyro" else "m/s^2") + " (x 1/s)"}
    # N and K as the fit implies them (GMWM's implied()): a Gauss-Markov term faster than the
    # shortest scale is white noise, one at its upper correlation-time bound a random walk;
    # K only where the record resolves it, else 0 with its upper limit as the interval's top.
    imp = res.implied()
    est["N"] = TermEstimate("N", imp["N"] * back["N"], imp["N_ci_low"] * back["N"],
                            imp["N_ci_high"] * back["N"], TERM_UNITS[sensor]["N"].si)
    if imp["K_resolved"]:
        est["K"] = TermEstimate("K", imp["K"] * back["K"], imp["K_ci_low"] * back["K"],
                                imp["K_ci_high"] * back["K"], TERM_UNITS[sensor]["K"].si)
    else:
        est["K"] = TermEstimate("K", 0.0, 0.0, imp["K_upper_limit"] * back["K"],
                                TERM_UNITS[sensor]["K"].si)
    extra["k_upper_limit"] = imp["K_upper_limit"] * back["K"]
    fit_adev = np.full(a.tau_s.shape, np.nan)
    unit = "rad/s" if sensor == "gyro" else "m/s^2"
    return ChannelResult(channel, sensor, unit, a, est, fit_adev, "gmwm", extra,
                         fit_check_of(res))


def characterize(rec: ImuData, *, ci: float = ONE_SIGMA_CI, taus: str = "octave",
                 terms: Sequence[str] = TERMS, method: str = DEFAULT_IDENTIFIER,
                 threads: int | None = None,
                 progress: Callable[[str], None] | None = None) -> CharacterizeResult:
    """Characterize every channel of an IMU record (module docstring).

    Parameters
    ----------
    ci : two-sided probability of every interval.
    taus : Allan tau grid ("octave", "decade", "all").
    terms : IEEE 952 terms the fit may use (subset of Q, N, B, K, R).
    method : "allan-nnls" (IEEE 952 Annex C fit, the default) or "gmwm" (generalized method of
        wavelet moments); gyrodrift.stability.MODEL_IDENTIFIERS.
    threads : threads of the in-memory Allan kernel (None: all cores; fleet workers use 1).
    progress : called with each channel name before it is analysed.

    Examples
    --------
    A gyro and an accelerometer channel of white noise at 100 Hz:

    >>> from gyrodrift.io.imu_data import ImuData
    >>> rng = np.random.default_rng(0)  # white gyro 1e-4 rad/s, white accel 1e-3 m/s^2, 100 Hz
    >>> rec = ImuData({"gyro_x": rng.normal(0, 1e-4, 4096), "accel_x": rng.normal(0, 1e-3, 4096)},
    ...               rate_hz=100.0, source="bench", fmt="npy", n_total=4096)
    >>> res = characterize(rec)
    >>> [c.channel for c in res.channels]
    ['gyro_x', 'accel_x']
    >>> res.channels[0].terms["N"]  # 1e-4 * sqrt(0.01 s) = 1e-5 rad/s/sqrt(Hz)
    TermEstimate(name='N', value=9.99...e-06, ci_low=9.27...e-06, ci_high=1.02...e-05,
                 unit='rad/s/sqrt(Hz)')
    """
    return characterize_channels(rec.names, rec.channels.__getitem__, rec.rate_hz,
                                 rec.summary(), ci=ci, taus=taus, terms=terms, method=method,
                                 threads=threads, progress=progress)


def characterize_channels(names: Sequence[str], load: Callable[[str], np.ndarray],
                          rate_hz: float, record: dict[str, object], *,
                          ci: float = ONE_SIGMA_CI, taus: str = "octave",
                          terms: Sequence[str] = TERMS, method: str = DEFAULT_IDENTIFIER,
                          threads: int | None = None,
                          progress: Callable[[str], None] | None = None
                          ) -> CharacterizeResult:
    """`characterize` over channels that `load(name)` returns one at a time (each is let go
    before the next is loaded: a fleet task holds one channel in memory, not the record);
    `record` is the record's summary (`ImuData.summary`). Same arguments and result.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> cols = {"gyro_x": rng.normal(0, 1e-4, 4096)}
    >>> res = characterize_channels(["gyro_x"], cols.__getitem__, 100.0, {"source": "sim"})
    >>> res.record, res.channels[0].channel
    ({'source': 'sim'}, 'gyro_x')
    """
    bad = [t for t in terms if t not in TERMS]
    if bad or not terms:
        raise GyrodriftValueError(
            f"terms must be a non-empty subset of {','.join(TERMS)}, got {terms}")
    if not 0.0 < ci < 1.0:
        raise GyrodriftValueError(f"ci must be in (0, 1), got {ci!r}")
    out = []
    for name in names:
        if progress is not None:
            progress(name)
        x = load(name)
        out.append(characterize_channel(x, rate_hz, name, ci=ci, taus=taus, terms=terms,
                                        method=method, threads=threads))
        del x  # before the next channel is loaded
    return CharacterizeResult(record, tuple(out), float(ci), method, version())


# ------------------------------------------------------------------------------------ Kalibr

KALIBR_KEYS = {("gyro", "N"): "gyroscope_noise_density", ("gyro", "K"): "gyroscope_random_walk",
               ("accel", "N"): "accelerometer_noise_density",
               ("accel", "K"): "accelerometer_random_walk"}


def kalibr_values(res: CharacterizeResult, axis: str = "worst"
                  ) -> dict[str, tuple[float, str, TermEstimate]]:
    """Kalibr key -> (value, channel it came from, its TermEstimate). axis: "worst" (largest
    value over the axes present, per parameter) or "x", "y", "z".

    Examples
    --------
    The four Kalibr parameters of a gyro and an accelerometer channel (white noise):

    >>> from gyrodrift.io.imu_data import ImuData
    >>> rng = np.random.default_rng(0)
    >>> rec = ImuData({"gyro_x": rng.normal(0, 1e-4, 4096), "accel_x": rng.normal(0, 1e-3, 4096)},
    ...               rate_hz=100.0, source="bench", fmt="npy", n_total=4096)
    >>> vals = kalibr_values(characterize(rec))
    >>> value, channel, term = vals["gyroscope_noise_density"]
    >>> round(value, 7), channel, term.name
    (1e-05, 'gyro_x', 'N')
    >>> sorted(vals)  # doctest: +NORMALIZE_WHITESPACE
    ['accelerometer_noise_density', 'accelerometer_random_walk', 'gyroscope_noise_density',
     'gyroscope_random_walk']
    """
    if axis not in ("worst", "x", "y", "z"):
        raise GyrodriftValueError(f"axis must be worst, x, y or z, got {axis!r}")
    out: dict[str, tuple[float, str, TermEstimate]] = {}
    for (sensor, term), key in KALIBR_KEYS.items():
        cands = [c for c in res.channels if c.sensor == sensor and term in c.terms]
        if axis != "worst":
            cands = [c for c in cands if c.channel.endswith("_" + axis)]
        if not cands:
            continue
        best = max(cands, key=lambda c: c.terms[term].value)
        out[key] = (best.terms[term].value, best.channel, best.terms[term])
    return out


#: The Kalibr file warns when the Allan interval band had to be widened more than this for
#: any model of the chosen terms to fit (ChannelResult.extra["band_scale"]): the fit then
#: describes a curve far from the measured one.
BAND_SCALE_WARN = 3.0
#: ... and when a random walk alone implies an Allan deviation more than this many times the
#: measured one at the longest averaging time (a random walk no record of this length shows).
RANDOM_WALK_EXCESS_WARN = 2.0


def kalibr_warnings(res: CharacterizeResult, axis: str = "worst") -> list[str]:
    """The warning lines a Kalibr export of `res` carries: every channel whose fitted model
    does not hold (its self-check), whose interval band was widened more than
    BAND_SCALE_WARN, and an exported random walk that alone exceeds the measured Allan
    deviation at the longest averaging time by more than RANDOM_WALK_EXCESS_WARN. Empty when
    the export can be trusted as far as the record tells.

    Examples
    --------
    >>> from gyrodrift.io.imu_data import ImuData
    >>> rec = ImuData({"gyro_x": np.random.default_rng(0).normal(0, 1e-4, 4096)}, rate_hz=100.0,
    ...               source="bench", fmt="npy", n_total=4096)
    >>> kalibr_warnings(characterize(rec))
    []
    """
    out: list[str] = []
    for c in res.channels:
        if c.check is not None:
            out += [f"{c.channel}: {w}" for w in c.check.warnings]
        scale = c.extra.get("band_scale")
        if isinstance(scale, float) and scale > BAND_SCALE_WARN:
            out.append(f"{c.channel}: no model of the chosen terms fits inside the Allan "
                       f"interval band; it was widened {scale:.3g}x (far beyond the measured "
                       "curve's interval): the terms are approximate")
    for (sensor, term), key in KALIBR_KEYS.items():
        if term != "N":
            continue
        # An axis whose model holds no white noise cannot be the worst axis: the density
        # then comes from the others, which may understate this axis's noise.
        for c in res.channels:
            if (c.sensor == sensor and term in c.terms and c.terms[term].value == 0.0
                    and (axis == "worst" or c.channel.endswith("_" + axis))):
                out.append(f"{key}: {c.channel}'s model has no white-noise term (0); the "
                           "exported density comes from the other axes and may understate "
                           f"{c.channel}'s noise")
    for (_sensor, term), key in KALIBR_KEYS.items():
        if term != "K":
            continue
        vals = kalibr_values(res, axis)
        if key not in vals:
            continue
        k, ch_name, _ = vals[key]
        a = res.channel(ch_name).allan
        pos = a.adev > 0
        if k > 0 and np.any(pos):
            t_max, dev = float(a.tau_s[pos][-1]), float(a.adev[pos][-1])
            excess = k * math.sqrt(t_max / 3.0) / dev
            if excess > RANDOM_WALK_EXCESS_WARN:
                out.append(f"{key} {k:.4g} (from {ch_name}) alone implies an Allan deviation "
                           f"{excess:.3g}x the measured one at tau = {t_max:.4g} s: not "
                           "credible")
    return out


def kalibr_yaml(res: CharacterizeResult, axis: str = "worst", rostopic: str | None = None) -> str:
    """Kalibr imu.yaml text (continuous-time densities, SI units), with comments stating the
    source, the axis choice, every axis's value, the discrete-time relations, and a leading
    block with the fit self-check of every channel and a WARNING line for each
    :func:`kalibr_warnings` (comments: Kalibr reads none of them).

    Raises
    ------
    GyrodriftValueError
        when a sensor present has no white-noise density or one fitted as zero: Kalibr
        would trust that sensor blindly (nothing is written).

    Examples
    --------
    The imu.yaml of a white gyro and accelerometer channel (comments give each source):

    >>> from gyrodrift.io.imu_data import ImuData
    >>> rng = np.random.default_rng(0)
    >>> rec = ImuData({"gyro_x": rng.normal(0, 1e-4, 4096), "accel_x": rng.normal(0, 1e-3, 4096)},
    ...               rate_hz=100.0, source="bench", fmt="npy", n_total=4096)
    >>> text = kalibr_yaml(characterize(rec))
    >>> print("\\n".join([line for line in text.splitlines() if not line.startswith("#")][:2]))
    rostopic: /imu0
    update_rate: 100.0

    The values are written with all their digits (a computed float; shown rounded here, as
    the last digits differ between machines):

    >>> line = next(ln for ln in text.splitlines() if ln.startswith("gyroscope_noise_density"))
    >>> value, comment = line.split(":", 1)[1].split("#")
    >>> f"{float(value):.4g}", comment.strip()
    ('9.996e-06', 'rad/s/sqrt(Hz), from gyro_x')
    >>> print([line for line in text.splitlines() if "self-check" in line][0])
    # fit self-check: every channel's model holds
    """
    vals = kalibr_values(res, axis)
    if not vals:
        raise GyrodriftValueError("no gyro or accelerometer channel to export")
    for sensor in sensors_present(res):
        key = KALIBR_KEYS[(sensor, "N")]
        got_n = vals.get(key)
        if got_n is None or not (math.isfinite(got_n[0]) and got_n[0] > 0.0):
            got = ("no white-noise term" if got_n is None
                   else f"{got_n[0]!r} (from {got_n[1]})")
            raise GyrodriftValueError(
                f"Kalibr export refused: {key} is {got}; a filter given that value trusts "
                f"the {sensor} blindly. Fit a model with a white-noise term (--terms with N, "
                "or another --identifier) or choose another --kalibr-axis")
    rate = float(res.record["rate_hz"])  # type: ignore[arg-type]
    topic = rostopic or str(res.record.get("topic") or "/imu0")
    warns = kalibr_warnings(res, axis)
    lines = [f"# Kalibr IMU noise model written by gyrodrift {res.version} (characterize)"]
    if warns:
        lines.append("# WARNING: the noise model below is approximate or wrong; read these "
                     "lines before using it:")
        lines += [f"# WARNING: {w}" for w in warns]
    else:
        lines.append("# fit self-check: every channel's model holds")
    for c in res.channels:
        if c.check is not None:
            lines.append(f"# {c.channel} {check_summary(c.check)}")
    lines += [
        f"# source: {res.record['source']} ({res.record['n_used']} samples at {rate:g} Hz)",
        f"# method: {res.method}; intervals at probability {res.ci:.4g}",
        "# axis: " + ("worst (largest value over the axes present, per parameter)"
                      if axis == "worst" else f"{axis} (chosen)"),
        "# continuous-time densities; the discrete-time values are",
        "#   sigma_d = noise_density / sqrt(dt), sigma_bd = random_walk * sqrt(dt), "
        f"dt = 1/update_rate = {1.0 / rate:.9g} s",
    ]
    for (sensor, term), key in KALIBR_KEYS.items():
        per = [(c.channel, c.terms[term]) for c in res.channels
               if c.sensor == sensor and term in c.terms]
        if per:
            lines.append(f"# {key} per axis [{TERM_UNITS[sensor][term].si}]: " + ", ".join(
                f"{ch} {t.value:.6g} [{t.ci_low:.4g}, {t.ci_high:.4g}]" for ch, t in per))
    lines.append(f"rostopic: {topic}")
    lines.append(f"update_rate: {rate!r}")
    for (sensor, term), key in KALIBR_KEYS.items():
        if key in vals:
            v, ch, t = vals[key]
            if v == 0.0:
                # A zero random walk makes a filter trust the bias forever: say so in the file.
                lines.append(f"# WARNING: {key} was fitted as 0 (term not identified; upper "
                             f"limit {t.ci_high:.4g}): do not use 0 in a filter")
            lines.append(f"{key}: {v!r}  # {TERM_UNITS[sensor][term].si}, from {ch}")
        else:
            lines.append(f"# {key}: no {sensor} channel in the record")
    return "\n".join(lines) + "\n"


# -------------------------------------------------------------------------------- self-check

@dataclass(frozen=True)
class SelfCheck:
    """Re-identification of a record simulated with the identified terms.

    Examples
    --------
    The rows of a self-check: truth, estimate and interval per channel and term:

    >>> from gyrodrift.io.imu_data import ImuData
    >>> rec = ImuData({"gyro_x": np.random.default_rng(0).normal(0, 1e-4, 4096)}, rate_hz=100.0,
    ...               source="bench", fmt="npy", n_total=4096)
    >>> sc = self_check(characterize(rec), seed=1)
    >>> sc.seed, sorted(sc.rows[0])
    (1, ['channel', 'ci_high', 'ci_low', 'estimate', 'inside', 'term', 'truth', 'unit'])
    """

    rows: tuple[dict[str, object], ...]  # channel, term, truth, estimate, ci_low, ci_high, inside
    seed: int

    @property
    def all_inside(self) -> bool:
        return all(bool(r["inside"]) for r in self.rows)

    def as_dict(self) -> dict[str, object]:
        return {"seed": self.seed, "all_inside": self.all_inside, "rows": list(self.rows)}


def simulate_like(res: CharacterizeResult, *, seed: int = 0) -> ImuData:
    """A record with the identified terms of every channel, same length and rate (the
    project's simulator `gyrodrift.simulation.records.simulate`, whose deg/h parameterization is
    linear
    in the record unit: N in U sqrt(h) = N_SI / 60, K in U/sqrt(h) = 60 K_SI, R in U/h =
    3600 R_SI, B in U, Q in U h = Q_SI / 3600)."""
    from gyrodrift.simulation.records import simulate

    n = int(res.record["n_used"])  # type: ignore[call-overload]
    rate = float(res.record["rate_hz"])  # type: ignore[arg-type]
    seeds = np.random.SeedSequence(seed).generate_state(len(res.channels), dtype=np.uint32)
    cols = {}
    for c, s in zip(res.channels, seeds, strict=True):
        v = {k: (t.value if k in c.terms else 0.0) for k, t in c.terms.items()}
        rec = simulate(n=n, rate_hz=rate, q_deg=v.get("Q", 0.0) / 3600.0,
                       n_deg_rt_h=v.get("N", 0.0) / 60.0, b_deg_h=v.get("B", 0.0),
                       k_deg_h_rt_h=v.get("K", 0.0) * 60.0, r_deg_h2=v.get("R", 0.0) * 3600.0,
                       seed=int(s))
        cols[c.channel] = rec.rate_deg_h
    return ImuData(cols, rate, f"simulation of {res.record['source']}", "simulated", n)


def self_check(res: CharacterizeResult, *, seed: int = 0, taus: str = "octave",
               terms: Sequence[str] = TERMS, threads: int | None = None) -> SelfCheck:
    """Simulate the identified model, identify it again with the same options, and report for
    every term whether the value used in the simulation lies inside the new interval.

    Examples
    --------
    Every term of a white gyro channel, simulated from the fit and recovered inside its interval:

    >>> from gyrodrift.io.imu_data import ImuData
    >>> rec = ImuData({"gyro_x": np.random.default_rng(0).normal(0, 1e-4, 4096)}, rate_hz=100.0,
    ...               source="bench", fmt="npy", n_total=4096)
    >>> sc = self_check(characterize(rec), seed=1)  # simulate the fitted model, fit it again
    >>> [(row["term"], row["inside"]) for row in sc.rows], sc.all_inside
    ([('Q', True), ('N', True), ('B', True), ('K', True), ('R', True)], True)
    """
    sim = simulate_like(res, seed=seed)
    again = characterize(sim, ci=res.ci, taus=taus, terms=terms, method=res.method,
                         threads=threads)
    rows = []
    for c0, c1 in zip(res.channels, again.channels, strict=True):
        for name, t0 in c0.terms.items():
            t1 = c1.terms[name]
            rows.append({"channel": c0.channel, "term": name, "unit": t0.unit,
                         "truth": t0.value, "estimate": t1.value, "ci_low": t1.ci_low,
                         "ci_high": t1.ci_high, "inside": t1.contains(t0.value)})
    return SelfCheck(tuple(rows), seed)


# ------------------------------------------------------------------------------------- plots

def plot_sensor(res: CharacterizeResult, sensor: str, path: str | Path | None = None) -> bytes:
    """One figure for one sensor type: the three axes' Allan deviations with interval error
    bars and the fitted totals (same colour, line). Returns the PNG bytes (and writes them to
    `path` when given).

    Examples
    --------
    The Allan plot of the gyro channels as PNG bytes:

    >>> from gyrodrift.io.imu_data import ImuData
    >>> rec = ImuData({"gyro_x": np.random.default_rng(0).normal(0, 1e-4, 4096)}, rate_hz=100.0,
    ...               source="bench", fmt="npy", n_total=4096)
    >>> plot_sensor(characterize(rec), "gyro")[:8]  # PNG bytes (also written to `path` if given)
    b'\\x89PNG\\r\\n\\x1a\\n'
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    chans = [c for c in res.channels if c.sensor == sensor]
    if not chans:
        raise GyrodriftValueError(f"no {sensor} channel")
    fig, ax = plt.subplots(figsize=(7.5, 5.2), dpi=100)
    for c, color in zip(chans, ("tab:red", "tab:green", "tab:blue"), strict=False):
        a = c.allan
        err = np.vstack([a.adev - a.ci_low, a.ci_high - a.adev])
        ax.errorbar(a.tau_s, a.adev, yerr=err, fmt="o", ms=3, capsize=2, color=color,
                    label=f"{c.channel}")
        if np.all(np.isfinite(c.fit_adev)):
            ax.plot(a.tau_s, c.fit_adev, "-", lw=1.2, color=color,
                    label=f"{c.channel} fit ({c.method})")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("tau (s)")
    ax.set_ylabel(f"Allan deviation ({chans[0].unit})")
    ax.set_title(f"{'Gyroscopes' if sensor == 'gyro' else 'Accelerometers'}: overlapping Allan "
                 f"deviation, {res.ci:.3g} intervals")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    # Fixed margins: tight_layout on log axes with error bars costs seconds per figure.
    fig.subplots_adjust(left=0.11, right=0.97, bottom=0.1, top=0.92)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    data = buf.getvalue()
    if path is not None:
        with atomic_output(path) as tmp:
            tmp.write_bytes(data)
    return data


def png_data_uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def table_rows(res: CharacterizeResult) -> list[dict[str, Any]]:
    """Flat per-axis table: channel, term, SI value and interval, IEEE-unit value."""
    rows = []
    for c in res.channels:
        for name, t in c.terms.items():
            f, unit = TERM_UNITS[c.sensor][name].ieee_factor, TERM_UNITS[c.sensor][name].ieee
            rows.append({"channel": c.channel, "term": name, "meaning": TERM_NAMES[name],
                         "value": t.value, "ci_low": t.ci_low, "ci_high": t.ci_high,
                         "unit": t.unit, "ieee_value": t.value * f, "ieee_low": t.ci_low * f,
                         "ieee_high": t.ci_high * f, "ieee_unit": unit})
    return rows


def _finite_or_none(v: float) -> float | None:
    return v if math.isfinite(v) else None


def check_rows(res: CharacterizeResult) -> list[dict[str, Any]]:
    """One row per channel with a fitted model: its self-check for the HTML report.

    Examples
    --------
    >>> from gyrodrift.io.imu_data import ImuData
    >>> rec = ImuData({"gyro_x": np.random.default_rng(0).normal(0, 1e-4, 4096)}, rate_hz=100.0,
    ...               source="bench", fmt="npy", n_total=4096)
    >>> row = check_rows(characterize(rec))[0]
    >>> row["channel"], row["holds"], len(row["points"]) == row["n_used"]
    ('gyro_x', True, True)
    """
    rows = []
    for c in res.channels:
        chk = c.check
        if chk is None:
            continue
        rows.append({
            "channel": c.channel, "what": chk.what, "holds": chk.holds,
            "statistic": _finite_or_none(chk.statistic), "n_failed": chk.n_failed,
            "n_used": int(np.count_nonzero(chk.used)),
            "worst_ratio": _finite_or_none(chk.worst_ratio),
            "points": [(float(x), _finite_or_none(float(r)), bool(u), bool(ok))
                       for x, r, u, ok in zip(chk.x, chk.ratio, chk.used, chk.passed,
                                              strict=True)]})
    return rows


def sensors_present(res: CharacterizeResult) -> list[str]:
    return [s for s in ("gyro", "accel") if any(c.sensor == s for c in res.channels)]


assert CHANNELS[0] == "gyro_x"  # channel order the plots' colours follow


def write_outputs(res: Any, *, kalibr: str | None, kalibr_path: str | None,
                  html_path: str | None, out_dir: str | None, self_check: Any = None,
                  json_path: str | None = None, kalibr_axis: str = "worst",
                  kalibr_refused: str | None = None) -> dict[str, Any]:
    """Write the plots (``out_dir``/gyro.png, accel.png), the Kalibr yaml, the HTML report and
    the JSON of one characterization, each atomically; returns the paths written.

    Examples
    --------
    >>> import os, tempfile
    >>> from gyrodrift.io.imu_data import ImuData
    >>> rng = np.random.default_rng(0)
    >>> rec = ImuData({"gyro_x": rng.normal(0, 1e-4, 4096)}, rate_hz=100.0, source="bench",
    ...               fmt="npy", n_total=4096)
    >>> res = characterize(rec)
    >>> d = tempfile.mkdtemp()
    >>> files = write_outputs(res, kalibr=None, kalibr_path=None, html_path=None, out_dir=None,
    ...                       json_path=os.path.join(d, "r.json"))
    >>> os.path.basename(files["json"]), files["html"]
    ('r.json', None)
    """
    from gyrodrift.report.html import characterize_html

    files: dict[str, Any] = {"kalibr": None, "html": None, "plots": []}
    pngs = {s: plot_sensor(res, s) for s in sensors_present(res)}
    if out_dir:
        d = Path(out_dir)
        d.mkdir(parents=True, exist_ok=True)
        for s, data in pngs.items():
            with atomic_output(d / f"{s}.png") as tmp:
                tmp.write_bytes(data)
            files["plots"].append(str(d / f"{s}.png"))
    if kalibr_path and kalibr is not None:
        atomic_write_text(kalibr_path, kalibr)
        files["kalibr"] = kalibr_path
    if html_path:
        text = characterize_html(
            name=Path(str(res.record["source"])).name, version=res.version, method=res.method,
            ci=res.ci, record=res.record, rows=table_rows(res),
            images=[(f"{'Gyroscopes' if s == 'gyro' else 'Accelerometers'}",
                     png_data_uri(data)) for s, data in pngs.items()],
            kalibr=kalibr, self_check=None if self_check is None else self_check.as_dict(),
            fit_checks=check_rows(res), kalibr_warnings=kalibr_warnings(res, kalibr_axis),
            kalibr_refused=kalibr_refused)
        atomic_write_text(html_path, text)
        files["html"] = html_path
    if json_path:
        atomic_write_text(json_path, json_text(res.as_dict(), indent=1))
        files["json"] = json_path
    return files
