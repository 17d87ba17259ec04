"""The gyro monitor the target runs, over whole records: streaming Allan statistics, online
noise estimates (N, B, K with intervals), online re-identification of the drift model with its
retuned gain, and latched health alarms, sample by sample through the C++ core
(include/gyrodrift/imu/gyro_monitor.hpp).

Units: every rate quantity is in the channel's base unit, rad/s (N in rad/sqrt(s), B in rad/s,
K in rad/s/sqrt(s), q and r in (rad/s)^2); the command line converts to deg/sqrt(h), deg/h and
deg/h/sqrt(h).

The reference the alarms compare against is an expected Allan variance per octave: from a
drift model (:func:`reference_from_model`, the model's exact Allan variance) or learned from
the first part of a record (:func:`reference_from_record`: the offline maximum-likelihood fit
of that span, and the span's own streaming Allan curve).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from gyrodrift._native import core
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.imu.config import MonitorConfig, ProcessorConfig

__all__ = [
    "LAG_FIT_STATUS_NAMES",
    "STATUS_NAMES",
    "MonitorReference",
    "MonitorTrace",
    "model_avar",
    "monitor_alarm_bits",
    "monitor_flags",
    "reference_from_config",
    "reference_from_model",
    "reference_from_record",
    "run_monitor",
]

#: Names of the re-identification status codes (OnlineDriftStatus, both identifiers), and
#: "off" when the re-identification is not run.
STATUS_NAMES = {-1: "off", 0: "unconfigured", 1: "learning", 2: "tracking",
                3: "not_identified", 4: "fallback"}

#: Names of the lag identifier's fit status codes (LagDriftFitStatus, of the last fit applied;
#: too_few_samples before the first).
LAG_FIT_STATUS_NAMES = ("ok", "too_few_samples", "truncation", "not_converged", "non_finite",
                        "bad_model", "needs_head")

#: Squared differences per block test of the alarms at each octave (HealthAlarmSettings
#: block_terms, its default): the edf of a model reference is that of such a block.
BLOCK_TERMS = 64

#: A learned reference keeps the octaves whose Allan variance has at least this many squared
#: differences in the learning span (fewer: too uncertain to compare against).
LEARN_MIN_TERMS = 8


@dataclass(frozen=True)
class MonitorReference:
    """What the alarms compare against and where the re-identification starts.

    drift: the configured drift model (a1, a2, q, r, mean), units rad/s and (rad/s)^2; the
    fallback of the re-identification. avar: expected Allan variance at tau0 * 2^k, (rad/s)^2,
    one value per octave (from the drift model, or learned from the first part of a record).
    source: "config" or "learned" (with the learning span in seconds in learn_s).
    edf_per_term: equivalent degrees of freedom per squared difference of the alarms' block
    test, per octave, under the drift model (None: the alarms derive it from the curve's
    slope, as for a learned reference).

    Examples
    --------
    >>> ref = reference_from_model((0.0, 0.0, 0.0, 1e-8, 0.0), 100.0, 3)  # white noise
    >>> ref.source, [round(float(v) / 1e-8, 6) for v in ref.avar]  # r / m at m = 1, 2, 4
    ('config', [1.0, 0.5, 0.25])
    """

    drift: tuple[float, float, float, float, float]
    avar: np.ndarray
    source: str = "config"
    learn_s: float = 0.0
    edf_per_term: np.ndarray | None = None


@dataclass(frozen=True)
class MonitorTrace:
    """One row per report interval (arrays of equal length).

    t_s: time of the report, s from the record's start. n, b, k with lo/hi: online noise
    estimates and their intervals (NaN where not estimable; k_upper_limit marks rows where only
    k_hi is meaningful). a1, a2, q, r, mean: the model in use by the filter gain; gain0, gain1:
    its steady-state Kalman gain (NaN when the re-identification is off). status: the
    re-identification status name per row ("off" when it is not run). health: latched alarm
    bits per row; alarm_names: the name of each bit (bit i = alarm_names[i]). trips: for each
    raised alarm, the statistic that tripped it (statistic, threshold, tau_s, t_s).
    reference: what the alarms compared against. b_tau_s: averaging time of the Allan minimum
    B is read at. est_*: the running estimate of the re-identification (a1, a2, q, r, mean).
    retunes, refused_retunes: cumulative counts per row. avar: the streaming Allan variance
    per row and octave ((rad/s)^2, NaN before an octave has a term); tau_s: its averaging
    times. identifier: the re-identification's method ("recursive" or "lag"); fit_status:
    with the lag identifier, the status name of the last fit applied per row
    (:data:`LAG_FIT_STATUS_NAMES`; empty for the recursive one); paused: with the lag
    identifier, samples left out of its statistics so far while fits ran (zeros otherwise).

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> ref = reference_from_model((0.0, 0.0, 0.0, 1e-8, 0.0), 100.0, 8)
    >>> tr = run_monitor(rng.normal(0.0, 1e-4, 3000), 100.0, ref, report_every_s=10.0)
    >>> tr.t_s.tolist(), tr.flags(2), tr.status
    ([10.0, 20.0, 30.0], [], ('off', 'off', 'off'))
    """

    t_s: np.ndarray
    n: np.ndarray
    n_lo: np.ndarray
    n_hi: np.ndarray
    b: np.ndarray
    b_lo: np.ndarray
    b_hi: np.ndarray
    k: np.ndarray
    k_lo: np.ndarray
    k_hi: np.ndarray
    k_upper_limit: np.ndarray
    a1: np.ndarray
    a2: np.ndarray
    q: np.ndarray
    r: np.ndarray
    mean: np.ndarray
    gain0: np.ndarray
    gain1: np.ndarray
    status: tuple[str, ...]
    health: np.ndarray
    alarm_names: tuple[str, ...]
    trips: dict[str, dict[str, float]] = field(default_factory=dict)
    reference: MonitorReference | None = None
    b_tau_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    est_a1: np.ndarray = field(default_factory=lambda: np.zeros(0))
    est_a2: np.ndarray = field(default_factory=lambda: np.zeros(0))
    est_q: np.ndarray = field(default_factory=lambda: np.zeros(0))
    est_r: np.ndarray = field(default_factory=lambda: np.zeros(0))
    est_mean: np.ndarray = field(default_factory=lambda: np.zeros(0))
    retunes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    refused_retunes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    avar: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    tau_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    identifier: str = "recursive"
    fit_status: tuple[str, ...] = ()
    paused: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def flags(self, row: int) -> list[str]:
        """Names of the alarms raised at report ``row`` (empty when healthy)."""
        return monitor_flags(int(self.health[row]), self.alarm_names)


def monitor_flags(bits: int, alarm_names: tuple[str, ...] | None = None) -> list[str]:
    """Names of the alarm bits set in `bits` (bit i: ``alarm_names[i]``, by default the core's
    alarm names).

    Examples
    --------
    >>> monitor_flags(0b1001)
    ['arw_high', 'stuck']
    """
    names = tuple(core("imu").MONITOR_ALARM_NAMES) if alarm_names is None else alarm_names
    return [name for i, name in enumerate(names) if bits >> i & 1]


# ----------------------------------------------------------------------------- references


def _drift_autocovariance(a1: float, a2: float, q: float, lags: int) -> np.ndarray:
    """gamma_0 .. gamma_{lags-1} of the stationary AR(2) drift (drift_likelihood.hpp's g0, g1,
    then gamma_k = a1 gamma_{k-1} + a2 gamma_{k-2}), in chunks: the pairs (gamma_k,
    gamma_{k-1}) of one chunk map to the next chunk's by the companion matrix to the chunk's
    length, so the recursion runs vectorised."""
    g = np.zeros(lags)
    if q == 0.0 or lags == 0:
        return g
    d = (1.0 + a2) * ((1.0 - a2) ** 2 - a1 * a1)
    g0 = q * (1.0 - a2) / d
    g1 = a1 * g0 / (1.0 - a2)
    chunk = min(lags, 4096)
    first = np.empty(chunk)
    first[0] = g0
    if chunk > 1:
        first[1] = g1
    for k in range(2, chunk):
        first[k] = a1 * first[k - 1] + a2 * first[k - 2]
    g[:chunk] = first
    if lags <= chunk:
        return g
    comp = np.array([[a1, a2], [1.0, 0.0]])
    step = np.linalg.matrix_power(comp, chunk)
    # (gamma_j, gamma_{j-1}) -> (gamma_{j+1}, gamma_j) by the companion matrix for every j >= 0
    # (gamma_{-1} = gamma_1, and gamma_1 = a1 gamma_0 + a2 gamma_1 is the Yule-Walker equation)
    prev = np.concatenate(([g1], first[:-1]))
    cur = first
    start = chunk
    while start < lags:
        nxt = step[0, 0] * cur + step[0, 1] * prev
        nxt_prev = step[1, 0] * cur + step[1, 1] * prev
        n = min(chunk, lags - start)
        g[start:start + n] = nxt[:n]
        cur, prev = nxt, nxt_prev
        start += chunk
    return g


def model_avar(drift: tuple[float, float, float, float, float], octaves: int) -> np.ndarray:
    """The exact (non-overlapped) Allan variance of the drift model "AR(2) drift + white noise"
    at averaging factors m = 2^k, k = 0 .. octaves - 1, in (units of the model)^2::

        sigma^2(m) = r / m + (1 / m^2) [ sum_{|k|<m} (m - |k|) gamma_k
                                         - sum_{k=1}^{2m-1} min(k, 2m - k) gamma_k ],

    Var of a cluster mean minus the covariance of two consecutive cluster means, with gamma_k
    the drift's autocovariance (the mean does not enter).

    Examples
    --------
    >>> [round(float(v), 12) for v in model_avar((0.0, 0.0, 0.0, 1.0, 0.0), 3)]  # white: r / m
    [1.0, 0.5, 0.25]
    >>> v = model_avar((0.5, 0.0, 1.0, 0.0, 0.0), 2)  # AR(1): sigma^2(1) = gamma0 - gamma1
    >>> round(float(v[0]), 9), round(4.0 / 3.0 - 2.0 / 3.0, 9)
    (0.666666667, 0.666666667)
    """
    a1, a2, q, r, _ = (float(x) for x in drift)
    if isinstance(octaves, bool) or int(octaves) != octaves or not 1 <= octaves <= 40:
        raise GyrodriftValueError(f"octaves: expected an integer in 1..40, got {octaves!r}")
    m_max = 1 << (int(octaves) - 1)
    gamma = _drift_autocovariance(a1, a2, q, 2 * m_max)
    out = np.empty(int(octaves))
    for k in range(int(octaves)):
        m = 1 << k
        lag = np.arange(1, 2 * m)
        var_mean = m * gamma[0] + 2.0 * np.dot(m - lag[: m - 1], gamma[1:m])
        cov_next = np.dot(np.minimum(lag, 2 * m - lag), gamma[1:2 * m])
        out[k] = r / m + (var_mean - cov_next) / (m * m)
    return out


def reference_from_model(drift: tuple[float, float, float, float, float], rate_hz: float,
                         octaves: int) -> MonitorReference:
    """The reference of a configured drift model (a1, a2, q, r, mean; rad/s): its exact Allan
    variance per octave (:func:`model_avar`). rate_hz is checked, not used (the octaves are
    averaging factors).

    Examples
    --------
    >>> ref = reference_from_model((0.9, 0.0, 1e-10, 1e-8, 0.0), 400.0, 12)
    >>> ref.source, ref.avar.shape, bool(np.all(ref.avar > 0))
    ('config', (12,), True)
    """
    if not (math.isfinite(rate_hz) and rate_hz > 0.0):
        raise GyrodriftValueError(f"rate_hz must be a positive finite number, got {rate_hz!r}")
    from gyrodrift.stability.model_allan import ar2_white_edf_per_term

    if len(drift) != 5:
        raise GyrodriftValueError("drift: expected (a1, a2, q, r, mean)")
    a1, a2, q, r, mean = (float(x) for x in drift)
    d = (a1, a2, q, r, mean)
    edf = ar2_white_edf_per_term(a1, a2, q, r, int(octaves), BLOCK_TERMS)
    return MonitorReference(drift=d, avar=model_avar(d, octaves), source="config",
                            edf_per_term=np.asarray(edf, dtype=np.float64))


def reference_from_config(cfg: ProcessorConfig, channel: str) -> MonitorReference:
    """The reference of a monitored channel of a configuration: its first stage's
    ar2_kalman model (a1, a2, q, r, mean) and its Allan variance at the monitor's octaves.

    Examples
    --------
    >>> from gyrodrift.imu.config import drift_filter_config
    >>> cfg = drift_filter_config("gz", a1=0.6, a2=0.2, mean=0.0, q=1e-10, r=1e-8,
    ...                           sample_rate_hz=100.0).with_monitor(enabled=True, octaves=6)
    >>> ref = reference_from_config(cfg, "gz")
    >>> ref.drift, ref.avar.shape
    ((0.6, 0.2, 1e-10, 1e-08, 0.0), (6,))
    """
    if channel not in cfg.monitored_channels():
        raise GyrodriftValueError(f"channel {channel!r} is not monitored: its first stage is not "
                                  "ar2_kalman (or it is not a gyro channel)")
    st = cfg.channel(channel).stages[0]
    drift = (st.a1, st.a2, st.q, st.r, st.mean)  # type: ignore[union-attr]
    return reference_from_model(drift, cfg.timing.sample_rate_hz, cfg.monitor.octaves)


def reference_from_record(y_rad_s: ArrayLike, rate_hz: float, learn_s: float,
                          octaves: int) -> MonitorReference:
    """The reference learned from the first `learn_s` seconds of a record: the offline
    maximum-likelihood fit of that span as the drift model (AR(2) + white, AR(1) + white or
    white, chosen by AIC as :func:`gyrodrift.filters.drift_model.compare_drift_models` does;
    white noise when the chosen drift/noise split is not identified), and the span's own
    streaming Allan variance as the expected curve, at the octaves where it has at least
    ``LEARN_MIN_TERMS`` squared differences (at most `octaves`).

    Raises
    ------
    GyrodriftValueError
        The span has too few samples for the fit or for one octave.

    Examples
    --------
    >>> y = np.random.default_rng(2).normal(0.0, 1e-4, 6000)
    >>> ref = reference_from_record(y, 100.0, 30.0, 10)
    >>> ref.source, ref.learn_s, ref.avar.shape  # 3000 samples: octaves with >= 8 terms
    ('learned', 30.0, (9,))
    """
    from gyrodrift.filters.drift_model import compare_drift_models
    from gyrodrift.stability.streaming import StreamingAllan

    y = np.asarray(y_rad_s, dtype=np.float64)
    if y.ndim != 1:
        raise GyrodriftValueError(f"y_rad_s: expected a 1-D array, got shape {y.shape}")
    if not (math.isfinite(learn_s) and learn_s > 0.0):
        raise GyrodriftValueError(f"learn_s must be a positive finite number, got {learn_s!r}")
    n = min(y.size, round(learn_s * rate_hz))
    span = y[:n]
    span = span[np.isfinite(span)]
    if span.size < 2 * (LEARN_MIN_TERMS + 1):
        raise GyrodriftValueError(f"the learning span ({learn_s!r} s) holds {span.size} finite "
                                  "samples: too few to learn a reference")
    # An AR(2) forced onto a white span ends at a2 -> -1 (not stationary in float): choose the
    # model as `gyrodrift fit` does, and take white noise when the split is not identified.
    comparison = compare_drift_models(span, rate_hz, "aic")
    fit = comparison.best
    if not fit.identified:
        fit = comparison.fit("white")
    sa = StreamingAllan(rate_hz, min(int(octaves), 40))
    sa.push(span)
    keep = int(np.count_nonzero(sa.counts >= LEARN_MIN_TERMS))
    avar = sa.avar[:keep]
    if keep < 1 or not np.all(avar > 0.0):
        raise GyrodriftValueError("the learning span's Allan variance is zero (a constant record)")
    drift = (fit.a1, fit.a2, fit.q, fit.r, fit.mean)
    return MonitorReference(drift=drift, avar=np.array(avar), source="learned",
                            learn_s=float(learn_s))


# ----------------------------------------------------------------------------- running


def _stuck_saturated(y: np.ndarray, saturation: float,
                     stuck_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """The processor's per-value checks (imu_processor.hpp): |x| >= saturation is saturated;
    the stuck_samples-th identical finite value in a row (non-finite values skipped, exact
    comparison) is stuck."""
    finite = np.isfinite(y)
    with np.errstate(invalid="ignore"):
        saturated = finite & (np.abs(y) >= saturation)
    stuck = np.zeros(y.size, dtype=bool)
    if stuck_samples > 0:
        idx = np.flatnonzero(finite)
        v = y[idx]
        new_run = np.ones(v.size, dtype=bool)
        new_run[1:] = v[1:] != v[:-1]
        starts = np.flatnonzero(new_run)
        run_id = np.cumsum(new_run) - 1
        run_len = np.arange(v.size) - starts[run_id] + 1
        stuck[idx[run_len >= stuck_samples]] = True
    return stuck, saturated


def monitor_alarm_bits(cfg: ProcessorConfig, values: ArrayLike) -> np.ndarray:
    """The gyro monitors of configuration `cfg` ([monitor] enabled) over the accepted samples
    of a record, as the float32 processor runs them: per sample, the OR of the monitored
    channels' latched alarm bits (nonzero: the processor sets its health_alarm flag).

    values: (n, 6) accepted input samples in the processor's order (gx gy gz in rad/s, ...);
    each monitored channel's stuck and saturated flags follow the channel's own checks.
    Zeros when the monitor is off.

    Examples
    --------
    >>> from gyrodrift.imu.config import drift_filter_config
    >>> cfg = drift_filter_config("gz", a1=0.5, a2=0.0, mean=0.0, q=1e-10, r=1e-8,
    ...                           sample_rate_hz=100.0).with_monitor(enabled=True, octaves=6)
    >>> monitor_alarm_bits(cfg, np.zeros((3, 6))).tolist()  # no stuck detection configured
    [0, 0, 0]
    """
    v = np.asarray(values, dtype=np.float32)
    if v.ndim != 2 or v.shape[1] != 6:
        raise GyrodriftValueError(f"values: expected shape (n, 6), got {v.shape}")
    out = np.zeros(v.shape[0], dtype=np.uint16)
    if not cfg.monitor.enabled:
        return out
    native = core("imu")
    rate = cfg.timing.sample_rate_hz
    s = _settings(native, cfg.monitor, rate, int(cfg.monitor.octaves))
    for ch in cfg.monitored_channels():
        c = ("gx", "gy", "gz").index(ch)
        cc = cfg.channel(ch)
        ref = reference_from_config(cfg, ch)
        y = np.ascontiguousarray(v[:, c])
        stuck, sat = _stuck_saturated(y, float(np.float32(cc.saturation)), int(cc.stuck_samples))
        mon = native.GyroMonitorRunF32(s, tuple(float(x) for x in ref.drift),
                                       np.ascontiguousarray(ref.avar, dtype=np.float64),
                                       _edf(ref))
        out |= np.asarray(mon.latched(y, stuck, sat), dtype=np.uint16)
    return out


def _edf(reference: MonitorReference) -> np.ndarray:
    """The reference's edf per term for the binding (zeros: derived from the curve's slope)."""
    if reference.edf_per_term is None:
        return np.zeros(np.asarray(reference.avar).size)
    return np.ascontiguousarray(reference.edf_per_term, dtype=np.float64)


def _settings(native: Any, cfg: MonitorConfig, rate_hz: float, octaves: int) -> Any:
    n = cfg.samples(rate_hz)
    return native.GyroMonitorSettings(
        rate_hz=rate_hz, octaves=octaves, arw_factor=cfg.arw_factor,
        bias_instability_factor=cfg.bias_instability_factor,
        rate_random_walk_factor=cfg.rate_random_walk_factor,
        false_alarm_probability=cfg.false_alarm_probability,
        stuck_samples=n["stuck_samples"], saturated_samples=n["saturated_samples"],
        reidentify=cfg.reidentify, block_samples=n["block_samples"],
        retune_blocks=n["retune_blocks"], min_samples=n["min_samples"],
        memory_blocks=n["memory_blocks"], max_step=cfg.max_step,
        max_rel_stderr=cfg.identified_max_rel_stderr, adapt_ar=cfg.reidentify_ar,
        identifier=cfg.identifier, fit_delay_samples=n["fit_delay_samples"],
        restart_after_fit=cfg.restart_after_fit)


def run_monitor(y_rad_s: ArrayLike, rate_hz: float, reference: MonitorReference, *,
                settings: MonitorConfig | None = None, report_every_s: float | None = None,
                stuck: ArrayLike | None = None, saturated: ArrayLike | None = None,
                dtype: DTypeLike = np.float64, saturation: float = math.inf,
                stuck_samples: int = 0) -> MonitorTrace:
    """Run the monitor over one gyro channel ``y_rad_s`` (rad/s) sampled at ``rate_hz``.

    Parameters
    ----------
    y_rad_s : array_like, shape (n,)
        The channel's raw samples (rad/s); NaN/Inf are skipped as the target skips them.
    rate_hz : float
        Sample rate (Hz).
    reference : MonitorReference
        What the alarms compare against and the re-identification's start
        (:func:`reference_from_config`, :func:`reference_from_model`,
        :func:`reference_from_record`).
    settings : MonitorConfig, optional
        The configuration file's monitor section (None: its defaults). Its ``octaves`` is
        the streaming curve's length (at least the reference's); ``enabled`` is not looked
        at (this runs the monitor); ``reidentify`` and ``identifier`` choose the
        re-identification (with ``identifier="lag"`` its fits run inline, at their request,
        as in the host loop; ``fit_delay_s`` must be at most ``retune_s``).
    report_every_s : float, optional
        Report interval, s (None: the settings' report_interval_s). One row per whole
        interval.
    stuck, saturated : array_like of bool, optional
        Per-sample flags from the processor's checks (None: computed as the processor does
        from `saturation` and `stuck_samples`, whose defaults detect nothing).
    dtype : {np.float64, np.float32}
        The monitor's state: double, or float as on the target.

    Returns
    -------
    MonitorTrace

    Raises
    ------
    GyrodriftValueError
        Bad shapes, rate, reference or settings.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> ref = reference_from_model((0.0, 0.0, 0.0, 1e-8, 0.0), 100.0, 8)
    >>> tr = run_monitor(rng.normal(0.0, 1e-4, 2000), 100.0, ref, report_every_s=5.0,
    ...                  settings=MonitorConfig(octaves=8))
    >>> len(tr.t_s), tr.alarm_names[:2], tr.avar.shape
    (4, ('arw_high', 'bias_instability_high'), (4, 8))
    """
    cfg = MonitorConfig() if settings is None else settings
    if not isinstance(cfg, MonitorConfig):
        raise GyrodriftValueError(f"settings: expected a MonitorConfig, got {type(cfg).__name__}")
    rate = float(rate_hz)
    if not (math.isfinite(rate) and rate > 0.0):
        raise GyrodriftValueError(f"rate_hz must be a positive finite number, got {rate_hz!r}")
    every_s = cfg.report_interval_s if report_every_s is None else float(report_every_s)
    if not (math.isfinite(every_s) and every_s > 0.0):
        raise GyrodriftValueError(f"report_every_s must be positive, got {report_every_s!r}")
    every = max(1, math.floor(every_s * rate + 0.5))
    dt = np.dtype(dtype)
    if dt not in (np.dtype(np.float64), np.dtype(np.float32)):
        raise GyrodriftValueError(f"dtype must be float64 or float32, got {dt}")
    y = np.ascontiguousarray(y_rad_s, dtype=dt)
    if y.ndim != 1:
        raise GyrodriftValueError(f"y_rad_s: expected a 1-D array, got shape {y.shape}")
    auto_stuck, auto_sat = _stuck_saturated(y, float(saturation), int(stuck_samples))
    stuck_a = auto_stuck if stuck is None else np.ascontiguousarray(stuck, dtype=bool)
    sat_a = auto_sat if saturated is None else np.ascontiguousarray(saturated, dtype=bool)
    if stuck_a.shape != y.shape or sat_a.shape != y.shape:
        raise GyrodriftValueError("stuck, saturated: expected one flag per sample")
    ref_avar = np.ascontiguousarray(reference.avar, dtype=np.float64)
    octaves = max(int(cfg.octaves), int(ref_avar.size))
    native = core("imu")
    if octaves > int(native.MONITOR_MAX_OCTAVES):
        raise GyrodriftValueError(f"octaves: at most {native.MONITOR_MAX_OCTAVES}, got {octaves}")
    if cfg.reidentify:
        cfg.check_fit_delay(rate, 1)  # one gyro: its fit applied within a retune interval
    try:
        s = _settings(native, cfg, rate, octaves)
        cls = native.GyroMonitorRun if dt == np.float64 else native.GyroMonitorRunF32
        mon = cls(s, tuple(float(x) for x in reference.drift), ref_avar, _edf(reference))
        out = mon.run(y, stuck_a, sat_a, every, float(cfg.coverage))
        raw_trips = mon.trips()
    except ValueError as exc:
        raise GyrodriftValueError(str(exc)) from None
    sample = np.asarray(out["sample"])
    trips = {name: {"statistic": float(d["statistic"]), "threshold": float(d["threshold"]),
                    "tau_s": float(d["tau_s"]), "t_s": float(d["sample"]) / rate}
             for name, d in raw_trips.items()}

    def col(name: str) -> np.ndarray:
        return np.asarray(out[name], dtype=np.float64)

    return MonitorTrace(
        t_s=sample / rate, n=col("n"), n_lo=col("n_lo"), n_hi=col("n_hi"), b=col("b"),
        b_lo=col("b_lo"), b_hi=col("b_hi"), k=col("k"), k_lo=col("k_lo"), k_hi=col("k_hi"),
        k_upper_limit=col("k_upper_limit") != 0.0, a1=col("a1"), a2=col("a2"), q=col("q"),
        r=col("r"), mean=col("mean"), gain0=col("gain0"), gain1=col("gain1"),
        status=tuple(STATUS_NAMES.get(int(c), "unknown") for c in col("status")),
        health=col("health").astype(np.uint16),
        alarm_names=tuple(native.MONITOR_ALARM_NAMES), trips=trips, reference=reference,
        b_tau_s=col("b_tau_s"), est_a1=col("est_a1"), est_a2=col("est_a2"),
        est_q=col("est_q"), est_r=col("est_r"), est_mean=col("est_mean"),
        retunes=col("retunes").astype(np.int64),
        refused_retunes=col("refused_retunes").astype(np.int64),
        avar=np.asarray(out["avar"], dtype=np.float64),
        tau_s=np.ldexp(1.0, np.arange(octaves)) / rate, identifier=cfg.identifier,
        fit_status=tuple(LAG_FIT_STATUS_NAMES[int(c)] if 0 <= c < len(LAG_FIT_STATUS_NAMES)
                         else "off" for c in col("fit_status"))
        if cfg.identifier == "lag" else (),
        paused=col("paused").astype(np.int64))
