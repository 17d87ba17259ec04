#!/usr/bin/env python3
"""Monte Carlo: the online-retuned AR(2)-Kalman filter against the offline ML filter, the
papers' tuning and the configured model, on stationary records and on records whose noise
changes halfway.

For the papers' two correlated AR(2) pairs and r/q in {1, 3} (q = 1 before any change),
simulate AR(2) drift plus white noise on a constant offset and filter the record with the
steady-state AR(2)-Kalman filter tuned five ways; the MSE is against the simulated drift
(offset + x_k, which only a simulation knows), after the first 500 samples:
  optimum    - the true model's gain (piecewise on a changing record): the yardstick;
  configured - a fixed configured model, 20 % off in a1, a2 = a2/2 + 0.03, q x1.5, r x0.7
               (stationary records), or the first half's true model (changing records);
  online     - gyrodrift.filters.online.OnlineDriftIdentifier run over the record, the gain
               of in_use() applied from the sample after each retune (the configured gain
               before the first); stationary: no forgetting; changing: memory_blocks = 100,
               adapt_ar off (q and r tracked);
  lag        - the re-identification from lag statistics (the C++ LagDriftIdentifier through
               the gyro monitor, double state as the host loop's), the gain of the model in use
               applied from the sample after each fit's apply point (the configured gain before
               the first): a fit every --lag-cadence samples (default 24000: 60 s at 400 Hz,
               the configuration's retune_s), each applied --lag-delay samples after its
               request (default 6000: the configuration's fit_delay_s of 15 s; the statistics
               pause meanwhile), bounded step --lag-max-step (default 1: every fit is a whole
               ML fit, so one retune may take it); stationary: min_samples 60000 as the
               recursive row, the statistics of the whole record (no restart), a1, a2 fitted;
               changing: restart_after_fit (each fit reads the samples since the previous
               one), min_samples 12000, adapt_ar off as the recursive row;
  ml         - gyrodrift.fit_drift_model on the whole record (.kalman()): the offline optimum
               a navigation computer cannot have while it runs;
  papers     - the papers' recipe: Yule-Walker AR(2) on the noisy record, q = sigma2, r = its
               prediction-error variance (gyrodrift.fit_ar2 defaults).
Prints one row per case (averaged over seeds) with the ratios to the optimum; --identifier
recursive or lag runs one of the two online rows only (default both, side by side).

    python scripts/online_drift_mc.py            # fast: 1 seed, 240000 samples
    python scripts/online_drift_mc.py --full     # the docs run: 5 seeds, 480000 samples
    python scripts/online_drift_mc.py --convergence   # online estimate vs offline ML fit
    python scripts/online_drift_mc.py --convergence --samples 960000 --seeds 5

--convergence: for both pairs, r/q in {1, 3} and seeds 1-3 (--seeds), 240000 samples
(--samples), no forgetting, the configured model as above; prints (online - ML) / (the offline
fit's standard error) for a1, a2, q, r, mean after the last sample, the likelihood distance
sqrt(2 (log L(ML) - log L(online))) on the same record, and the offline fit's a2.

--shared: what sharing one identifier among three gyros costs, measured on the identifier
the processor's monitor runs (gyrodrift.filters.online.SharedDriftIdentifier, each row of
samples in channel order as the processor steps its gyros), one watched gyro against three
fed independent records of the same model:
  cadence      - the sample index of every retune per gyro at the identifier's defaults
                 (blocks of 400, a retune every 60 blocks, min_samples 240000; 960000 samples);
  convergence  - as --convergence, on records of --samples (default 720000) per gyro: the
                 single-gyro estimate after N/3 and after N samples and the three-gyro one after
                 N, against the offline ML fit of the samples each ran over, and their error
                 against the true parameters in units of the expected standard errors of N
                 samples (the inverse Fisher information at the truth); "turns": a single
                 identifier fed only the samples of the gyro's turns (what the shared estimate
                 has seen, without its restarts and its mean of every sample);
  tracking     - q = r = 1, then r x2 (or q x2) halfway through --tracking-samples (default
                 480000) and three times that, memory_blocks 100, adapt_ar off: the time from
                 the change until the changed variance's estimate (and the gain's model) stays
                 within 20 %, and the largest error over the last 100000 samples.

    python scripts/online_drift_mc.py --shared                # the docs run
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass

import gyrodrift
import numpy as np
import scipy.linalg
from gyrodrift._native import core
from gyrodrift.filters.drift_model import drift_fisher_information
from gyrodrift.filters.online import (
    DriftParams,
    OnlineDriftIdentifier,
    OnlineDriftSettings,
    OnlineDriftTrace,
    SharedDriftIdentifier,
)
from gyrodrift.imu.monitor import model_avar
from scipy.signal import lfilter

PAIRS = ((0.6868, -0.0213), (0.2297, 0.1638))
RATIOS = (1.0, 3.0)
CHANGES = ("none", "r x2", "q x2")
MEAN = 9.7
SKIP = 500
RATE_HZ = 400.0


@dataclass(frozen=True)
class Case:
    """One simulated record: pair, r/q, the change halfway, length, seed."""

    a1: float
    a2: float
    ratio: float
    change: str
    n: int
    seed: int


def simulate(case: Case) -> tuple[np.ndarray, np.ndarray, tuple[float, float], tuple[float, float]]:
    """Record, true drift (offset included), (q, r) before and after the halfway change."""
    rng = np.random.default_rng(case.seed)
    q1, r1 = 1.0, case.ratio
    q2, r2 = (q1, 2 * r1) if case.change == "r x2" else (2 * q1, r1) if case.change == "q x2" \
        else (q1, r1)
    h = case.n // 2
    w = np.r_[rng.normal(0, math.sqrt(q1), h + 2000), rng.normal(0, math.sqrt(q2), case.n - h)]
    x = lfilter([1.0], [1.0, -case.a1, -case.a2], w)[2000:]
    v = np.r_[rng.normal(0, math.sqrt(r1), h), rng.normal(0, math.sqrt(r2), case.n - h)]
    truth = MEAN + x
    return truth + v, truth, (q1, r1), (q2, r2)


def gain_filter(y: np.ndarray, a1: np.ndarray, a2: np.ndarray, k0: np.ndarray, k1: np.ndarray,
                mean: np.ndarray) -> np.ndarray:
    """Constant-gain AR(2)-Kalman filter with per-sample model and gain arrays (piecewise
    constant): X- = A X, X = X- + K (y - mean - x0-); returns x0 + mean."""
    out = np.empty_like(y)
    x0 = x1 = 0.0
    for k in range(len(y)):
        p0 = a1[k] * x0 + a2[k] * x1
        e = y[k] - mean[k] - p0
        x0, x1 = p0 + k0[k] * e, x0 + k1[k] * e
        out[k] = x0 + mean[k]
    return out


def steady_state_gain(p: DriftParams) -> tuple[float, float]:
    """Steady-state Kalman gain (k0, k1) of a model: the stabilising DARE solution (scipy)."""
    a = np.array([[p.a1, p.a2], [1.0, 0.0]])
    c = np.array([[1.0], [0.0]])
    pp = scipy.linalg.solve_discrete_are(a.T, c, np.diag([p.q, 0.0]), np.array([[p.r]]))
    f = pp[0, 0] + p.r
    return float(pp[0, 0] / f), float(pp[1, 0] / f)


def piecewise(n: int, starts: list[int], values: list[float]) -> np.ndarray:
    """Array of length n taking values[i] from starts[i] on."""
    out = np.empty(n)
    for i, s in enumerate(starts):
        out[s:] = values[i]
    return out


def model_filter(y: np.ndarray, m: DriftParams, starts: list[int] | None = None,
                 models: list[DriftParams] | None = None) -> np.ndarray:
    """The steady-state filter of one model, or of models[i] from starts[i] on."""
    models = models or [m]
    starts = starts or [0]
    gains = [steady_state_gain(p) for p in models]
    n = len(y)
    return gain_filter(y, piecewise(n, starts, [p.a1 for p in models]),
                       piecewise(n, starts, [p.a2 for p in models]),
                       piecewise(n, starts, [float(g[0]) for g in gains]),
                       piecewise(n, starts, [float(g[1]) for g in gains]),
                       piecewise(n, starts, [p.mean for p in models]))


def online_settings(change: str) -> OnlineDriftSettings:
    """The identifier's settings of the study (stationary: converge; changing: track)."""
    if change == "none":
        return OnlineDriftSettings(block_samples=400, retune_blocks=25, min_samples=60000)
    return OnlineDriftSettings(block_samples=400, retune_blocks=25, min_samples=60000,
                               memory_blocks=100.0, adapt_ar=False)


@dataclass(frozen=True)
class LagSchedule:
    """The lag identifier's schedule in the study (see the module docstring), in samples."""

    cadence: int = 24000
    delay: int = 6000
    max_step: float = 1.0
    min_samples_stationary: int = 60000
    min_samples_changing: int = 12000


BLOCK = 400
IDENTIFIERS = ("recursive", "lag")


def lag_settings(change: str, lag: LagSchedule) -> dict[str, object]:
    """The gyro monitor's settings of the lag identifier in the study (stationary: the whole
    record's statistics; changing: restart after each fit, the AR part held)."""
    if lag.cadence % BLOCK or lag.cadence < BLOCK:
        raise ValueError(f"lag cadence: a positive multiple of {BLOCK} samples, got {lag.cadence}")
    if not 1 <= lag.delay <= lag.cadence:
        raise ValueError(f"lag delay: 1..cadence samples, got {lag.delay}")
    stationary = change == "none"
    return {"block_samples": BLOCK, "retune_blocks": lag.cadence // BLOCK,
            "min_samples": lag.min_samples_stationary if stationary else lag.min_samples_changing,
            "max_step": lag.max_step, "fit_delay_samples": lag.delay,
            "restart_after_fit": not stationary, "adapt_ar": stationary}


def run_lag(y: np.ndarray, configured: DriftParams, change: str, lag: LagSchedule
            ) -> tuple[list[int], list[tuple[float, ...]], dict[str, float]]:
    """The lag identifier (double state) over y through the gyro monitor: the sample counts at
    which each fit was applied (its gain in use from the next sample on), the model in use
    (a1, a2), gain (k0, k1) and mean from there, and its retunes, refused retunes and whether
    its final status is tracking."""
    native = core("imu")
    settings = native.GyroMonitorSettings(rate_hz=RATE_HZ, octaves=8, reidentify=True,
                                          identifier="lag", **lag_settings(change, lag))
    model = (configured.a1, configured.a2, configured.q, configured.r, configured.mean)
    mon = native.GyroMonitorRun(settings, model, model_avar(model, 8), np.zeros(8))
    flags = np.zeros(y.size, dtype=bool)
    # A report at every multiple of gcd(cadence, delay): every apply point (a request at a
    # multiple of the cadence, one gyro, plus the delay) is a report.
    every = math.gcd(lag.cadence, lag.delay)
    out = mon.run(np.ascontiguousarray(y, dtype=np.float64), flags, flags, every, 0.6827)
    applied = np.asarray(out["retunes"]) + np.asarray(out["refused_retunes"])
    rows = np.flatnonzero(np.diff(np.r_[0.0, applied]) > 0)
    samples = [int(out["sample"][i]) for i in rows]
    if np.any(np.diff(np.r_[0.0, applied])[rows] != 1) or any(
            (s - lag.delay) % lag.cadence for s in samples):
        raise RuntimeError("lag identifier: a fit applied off the schedule")
    use = [tuple(float(out[k][i]) for k in ("a1", "a2", "gain0", "gain1", "mean"))
           for i in rows]
    last = len(out["sample"]) - 1
    stats = {"retunes": float(out["retunes"][last]),
             "refused": float(out["refused_retunes"][last]),
             "tracking": 1.0 if int(out["status"][last]) == 2 else 0.0}
    return samples, use, stats


def run_case(case: Case, identifiers: tuple[str, ...] = IDENTIFIERS,
             lag: LagSchedule | None = None) -> dict[str, float]:
    """MSE of each tuning on one record (see the module docstring), plus each online run's
    retunes, refused retunes and final status (keys of the lag identifier prefixed "lag_");
    identifiers: which of the two online rows to run."""
    lag = lag or LagSchedule()
    y, truth, (q1, r1), (q2, r2) = simulate(case)
    n = len(y)
    h = n // 2

    def mse(est: np.ndarray) -> float:
        return float(np.mean((est[SKIP:] - truth[SKIP:]) ** 2))

    a1, a2 = case.a1, case.a2
    true1, true2 = DriftParams(a1, a2, q1, r1, MEAN), DriftParams(a1, a2, q2, r2, MEAN)
    if case.change == "none":
        configured = DriftParams(0.8 * a1, 0.5 * a2 + 0.03, 1.5 * q1, 0.7 * r1, MEAN)
    else:
        configured = true1
    out = {"optimum": mse(model_filter(y, true1, [0, h], [true1, true2])),
           "configured": mse(model_filter(y, configured))}
    g0 = steady_state_gain(configured)
    first = (configured.a1, configured.a2, g0[0], g0[1], configured.mean)

    def retuned_filter(starts: list[int], use: list[tuple[float, ...]]) -> np.ndarray:
        # The model's a1, a2, gain k0, k1 and mean use[i] from sample starts[i] on.
        return gain_filter(y, *(piecewise(n, starts, [u[j] for u in use]) for j in range(5)))

    if "recursive" in identifiers:
        ident = OnlineDriftIdentifier(configured, online_settings(case.change))
        trace = ident.push(y)
        # The gain in use from the sample after each block end (the configured one before).
        starts = [0] + [min(int(s), n) for s in trace.samples]
        use = [first] + [(p[0], p[1], g[0], g[1], p[4])
                         for p, g in zip(trace.in_use.tolist(), trace.gain.tolist(), strict=True)]
        out["online"] = mse(retuned_filter(starts, use))
        out["retunes"] = float(ident.retunes)
        out["refused"] = float(ident.refused_retunes)
        out["tracking"] = 1.0 if ident.status == "tracking" else 0.0
    if "lag" in identifiers:
        samples, use, stats = run_lag(y, configured, case.change, lag)
        out["lag"] = mse(retuned_filter([0, *samples], [first, *use]))
        out.update({"lag_" + k: v for k, v in stats.items()})
    fit = gyrodrift.fit_drift_model(y, rate_hz=400.0)
    out["ml"] = mse(fit.kalman().process(y))
    out["papers"] = mse(gyrodrift.kalman_filter(y, gyrodrift.fit_ar2(y), steady_state=True))
    return out


def convergence(seeds: int = 3, n: int = 240000, extra: dict[str, float] | None = None
                ) -> None:
    """Print the online estimate's distance to the offline ML fit in offline standard errors,
    and as a likelihood distance, sqrt(2 (log L(ML) - log L(online))) on the same record (the
    Mahalanobis distance in the offline fit's information for a quadratic likelihood: below 1
    puts every parameter, and every combination of them, within one standard error). extra:
    settings of the identifier changed from the study's."""
    settings = {"block_samples": 400, "retune_blocks": 50, "min_samples": 100000, **(extra or {})}
    loglike = core("drift").drift_loglike
    if extra:
        print(f"# settings changed: {extra}")
    print(f"# {n} samples; (online - ML) / offline stderr; d_LL = sqrt(2 (logL_ML - "
          "logL_online)); a2_ML: the offline fit's a2")
    print(f"{'a1':>7} {'a2':>7} {'r/q':>4} {'seed':>4} {'z_a1':>6} {'z_a2':>6} {'z_q':>6} "
          f"{'z_r':>6} {'z_mean':>6} {'d_LL':>5} {'a2_ML':>7} {'ident':>5} {'status':>9}")
    names = ("a1", "a2", "q", "r", "mean")
    worst: dict[tuple[float, float], list[float]] = {}
    t0 = time.monotonic()
    for a1, a2 in PAIRS:
        for ratio in RATIOS:
            for seed in range(1, seeds + 1):
                y, _, _, _ = simulate(Case(a1, a2, ratio, "none", n, seed))
                fit = gyrodrift.fit_drift_model(y, rate_hz=400.0)
                ident = OnlineDriftIdentifier(
                    DriftParams(0.8 * a1, 0.5 * a2 + 0.03, 1.5, 0.7 * ratio, 0.0),
                    OnlineDriftSettings(**settings))  # type: ignore[arg-type]
                ident.push(y)
                est = ident.estimate
                z = [(getattr(est, k) - getattr(fit, k)) / fit.stderr[k] for k in names]
                ll_ml = loglike(y, fit.a1, fit.a2, fit.q, fit.r, fit.mean)[0]
                ll_on = loglike(y, est.a1, est.a2, est.q, est.r, est.mean)[0]
                d_ll = math.sqrt(max(2.0 * (ll_ml - ll_on), 0.0))
                worst.setdefault((a1, a2), []).append(max(abs(v) for v in z[:4]))
                print(f"{a1:7.4f} {a2:7.4f} {ratio:4.1f} {seed:4d} "
                      + " ".join(f"{v:+6.2f}" for v in z)
                      + f" {d_ll:5.2f} {fit.a2:+7.4f} {fit.identified!s:>5} {ident.status:>9}")
    for (a1, a2), zs in worst.items():
        within = sum(v <= 1.0 for v in zs)
        print(f"# ({a1}, {a2}): {within} of {len(zs)} records within 1 standard error, "
              f"largest |z| {max(zs):.2f}")
    print(f"# {time.monotonic() - t0:.0f} s")


GYROS = 3


def gyro_records(a1: float, a2: float, ratio: float, change: str, n: int, seed: int
                 ) -> np.ndarray:
    """Independent records of one model for the three gyros, shape (n, 3): gyro g is the
    record of seed + 100 g (gyro 0 is the single-gyro study's record)."""
    return np.stack([simulate(Case(a1, a2, ratio, change, n, seed + 100 * g))[0]
                     for g in range(GYROS)], axis=1)


def run_single_and_shared(y: np.ndarray, configured: DriftParams, settings: OnlineDriftSettings
                          ) -> tuple[list[OnlineDriftTrace], list[DriftParams],
                                     list[OnlineDriftTrace], list[DriftParams]]:
    """Each gyro's record through its own identifier (one watched gyro), and all three through
    one shared identifier: (traces, final estimates) of each."""
    single_t, single_e = [], []
    for g in range(y.shape[1]):
        ident = OnlineDriftIdentifier(configured, settings)
        single_t.append(ident.push(y[:, g]))
        single_e.append(ident.estimate)
    shared = SharedDriftIdentifier([configured] * y.shape[1], settings)
    shared_t = shared.push(y)
    return single_t, single_e, shared_t, [shared.estimate(g) for g in range(y.shape[1])]


def retune_points(trace: OnlineDriftTrace, retune_blocks: int
                  ) -> tuple[np.ndarray, np.ndarray, int]:
    """Sample indices (the gyro's samples at the end of the block) of every retune attempt and
    of every accepted retune (status tracking after a retune that changed the gain), and the
    number of refused retunes (status not_identified or fallback after an attempt)."""
    blocks = np.arange(1, len(trace.samples) + 1)
    attempt = blocks % retune_blocks == 0
    accepted = attempt & trace.retuned & (trace.status == 2)
    refused = attempt & np.isin(trace.status, (3, 4))
    return trace.samples[attempt], trace.samples[accepted], int(np.count_nonzero(refused))


def shared_cadence(seed: int) -> None:
    """Retune sample indices per gyro at the identifier's defaults, 1 gyro against 3."""
    settings = OnlineDriftSettings()
    n = 960000
    a1, a2 = PAIRS[1]
    y = gyro_records(a1, a2, 1.0, "none", n, seed)
    configured = DriftParams(0.8 * a1, 0.5 * a2 + 0.03, 1.5, 0.7, MEAN)
    single_t, _, shared_t, _ = run_single_and_shared(y, configured, settings)
    print(f"# cadence: pair ({a1}, {a2}), r/q = 1, {n} samples ({n / RATE_HZ / 60:.0f} min at "
          f"{RATE_HZ:.0f} Hz), blocks of {settings.block_samples}, a retune every "
          f"{settings.retune_blocks} blocks, min_samples {settings.min_samples}")
    print(f"{'gyros':>5} {'gyro':>4} {'blocks':>6} {'attempt interval':>16} {'first attempts':>24} "
          f"{'first accepted':>14} {'accepted':>8} {'refused':>7}")
    for mode, traces in (("1", single_t[:1]), ("3", shared_t)):
        for g, t in enumerate(traces):
            att, acc, refused = retune_points(t, settings.retune_blocks)
            gaps = sorted(set(np.diff(att).tolist()))
            gap = "/".join(str(v) for v in gaps)
            first_acc = f"{int(acc[0])}" if len(acc) else "none"
            interval = f"{gap} ({gaps[0] / RATE_HZ:.1f} s)"
            firsts = ",".join(str(int(v)) for v in att[:3])
            print(f"{mode:>5} {g:4d} {len(t.samples):6d} {interval:>16} {firsts:>24} "
                  f"{first_acc:>14} {len(acc):8d} {refused:7d}")


def turn_samples(n: int, channel: int, channels: int, block: int) -> np.ndarray:
    """Indices of the samples of `channel` that ran through the shared identifier's filters
    (its turns) in a record of n rows: each row's samples go in channel order, so a turn passed
    on at the end of a block starts with the next channel's sample of the same row, and a cycle
    of turns takes channels (block - 1) + 1 rows."""
    cycle = channels * (block - 1) + 1
    starts = np.arange(channel * (block - 1), n - block + 1, cycle)
    return (starts[:, None] + np.arange(block)[None, :]).ravel()


def expected_stderr(a1: float, a2: float, q: float, r: float, n: int) -> np.ndarray:
    """Expected standard errors of (a1, a2, q, r) from n samples: the inverse Fisher
    information at the true parameters."""
    info = drift_fisher_information(a1, a2, q, r, n)
    return np.sqrt(np.diag(np.linalg.inv(info)))


def shared_convergence(seeds: int, n: int) -> None:
    """One gyro against three: distance to the offline ML fit and to the truth."""
    settings = OnlineDriftSettings(block_samples=400, retune_blocks=50, min_samples=100000)
    loglike = core("drift").drift_loglike
    names = ("a1", "a2", "q", "r")
    third = n // GYROS
    print(f"# convergence: {n} samples per gyro; z: max abs (online - ML) / offline stderr over "
          "a1, a2, q, r, against the ML fit of the samples the estimate ran over (N/3: the "
          "first third); d_LL as --convergence; err: RMS over a1, a2, q, r of (estimate - "
          f"truth) / expected stderr of {n} samples")
    print(f"{'a1':>7} {'a2':>7} {'r/q':>4} {'seed':>4} {'gyro':>4} | {'z 1@N/3':>7} {'z 1@N':>6} "
          f"{'z 3@N':>6} {'z turns':>7} | {'d 1@N/3':>7} {'d 1@N':>6} {'d 3@N':>6} | "
          f"{'err ML N/3':>10} {'1@N/3':>6} {'ML N':>6} {'1@N':>6} {'3@N':>6} {'turns':>6} | "
          f"{'status 3@N':>10}")
    summary: dict[tuple[float, float], list[list[float]]] = {}
    t0 = time.monotonic()
    for a1, a2 in PAIRS:
        for ratio in RATIOS:
            truth = np.array([a1, a2, 1.0, ratio])
            se_true = expected_stderr(a1, a2, 1.0, ratio, n)
            configured = DriftParams(0.8 * a1, 0.5 * a2 + 0.03, 1.5, 0.7 * ratio, 0.0)
            for seed in range(1, seeds + 1):
                y = gyro_records(a1, a2, ratio, "none", n, seed)
                _, single_n, _, shared_n = run_single_and_shared(y, configured, settings)
                _, single_3, _, _ = run_single_and_shared(y[:third], configured, settings)
                shared = SharedDriftIdentifier([configured] * GYROS, settings)
                shared.push(y)
                for g in range(GYROS):
                    turns = OnlineDriftIdentifier(configured, settings)
                    turns.push(y[turn_samples(n, g, GYROS, settings.block_samples), g])
                    fit_n = gyrodrift.fit_drift_model(y[:, g], rate_hz=RATE_HZ)
                    fit_3 = gyrodrift.fit_drift_model(y[:third, g], rate_hz=RATE_HZ)

                    def z(est: DriftParams, fit: object) -> float:
                        return max(abs((getattr(est, k) - getattr(fit, k)) / fit.stderr[k])  # type: ignore[attr-defined]
                                   for k in names)

                    def d_ll(est: DriftParams, fit: object, rec: np.ndarray) -> float:
                        ll_ml = loglike(rec, fit.a1, fit.a2, fit.q, fit.r, fit.mean)[0]  # type: ignore[attr-defined]
                        ll_on = loglike(rec, est.a1, est.a2, est.q, est.r, est.mean)[0]
                        return math.sqrt(max(2.0 * (ll_ml - ll_on), 0.0))

                    def err(p: object, truth: np.ndarray = truth,
                            se: np.ndarray = se_true) -> float:
                        v = np.array([getattr(p, k) for k in names])
                        return float(np.sqrt(np.mean(((v - truth) / se) ** 2)))

                    row = [z(single_3[g], fit_3), z(single_n[g], fit_n), z(shared_n[g], fit_n),
                           z(turns.estimate, fit_n),
                           d_ll(single_3[g], fit_3, y[:third, g]),
                           d_ll(single_n[g], fit_n, y[:, g]), d_ll(shared_n[g], fit_n, y[:, g]),
                           err(fit_3), err(single_3[g]), err(fit_n), err(single_n[g]),
                           err(shared_n[g]), err(turns.estimate)]
                    summary.setdefault((a1, a2), []).append(row)
                    print(f"{a1:7.4f} {a2:7.4f} {ratio:4.1f} {seed:4d} {g:4d} | {row[0]:7.2f} "
                          f"{row[1]:6.2f} {row[2]:6.2f} {row[3]:7.2f} | {row[4]:7.2f} "
                          f"{row[5]:6.2f} {row[6]:6.2f} | {row[7]:10.2f} {row[8]:6.2f} "
                          f"{row[9]:6.2f} {row[10]:6.2f} {row[11]:6.2f} {row[12]:6.2f} | "
                          f"{shared.status(g):>10}")
    print("# mean over the records of each pair (and the share within 1 standard error)")
    for (a1, a2), rows in summary.items():
        m = np.nanmean(np.array(rows), axis=0)
        w = [sum(r[i] <= 1.0 for r in rows) for i in range(4)]
        undefined = sum(not np.isfinite(r[1]) for r in rows)
        print(f"# ({a1}, {a2}), {len(rows)} records ({undefined} without offline standard errors "
              f"of N samples: z nan, left out of the means): z 1@N/3 {m[0]:.2f}, 1@N {m[1]:.2f}, "
              f"3@N {m[2]:.2f}, turns {m[3]:.2f} (within 1: {w[0]} / {w[1]} / {w[2]} / {w[3]}); "
              f"d_LL {m[4]:.2f} / {m[5]:.2f} / {m[6]:.2f}; err ML N/3 {m[7]:.2f}, "
              f"1@N/3 {m[8]:.2f}, ML N {m[9]:.2f}, 1@N {m[10]:.2f}, 3@N {m[11]:.2f}, "
              f"turns {m[12]:.2f}")
    print(f"# {time.monotonic() - t0:.0f} s")


def settle_time(samples: np.ndarray, values: np.ndarray, target: float, start: int,
                tol: float = 0.2) -> float:
    """Samples from `start` until `values` (one per block end) stays within tol of target for
    every later block (inf if it does not by the end)."""
    after = samples > start
    bad = after & (np.abs(values / target - 1.0) >= tol)
    if bad[-1]:
        return math.inf
    idx = np.flatnonzero(bad)
    first_ok = idx[-1] + 1 if len(idx) else int(np.flatnonzero(after)[0])
    return float(samples[first_ok] - start)


def shared_tracking(seeds: int, n: int) -> None:
    """One gyro against three: tracking a 2x step of r or q with forgetting."""
    settings = OnlineDriftSettings(block_samples=400, retune_blocks=25, min_samples=100000,
                                   memory_blocks=100.0, adapt_ar=False)
    print(f"# tracking: q = r = 1, the change halfway; memory_blocks {settings.memory_blocks:g}, "
          f"adapt_ar off, blocks of {settings.block_samples}, a retune every "
          f"{settings.retune_blocks} blocks; t20: seconds at {RATE_HZ:.0f} Hz from the change "
          "until the changed variance stays within 20 % (estimate; the gain's model); last: "
          "largest relative error over the last 100000 samples (changed; other variance)")
    print(f"{'a1':>7} {'a2':>7} {'change':>6} {'samples':>7} {'seed':>4} {'gyros':>5} {'gyro':>4} "
          f"{'t20 est':>7} {'t20 use':>7} {'last chg':>8} {'last oth':>8}")
    t0 = time.monotonic()
    summary: dict[tuple[str, float, int, str], list[list[float]]] = {}
    for change in ("r x2", "q x2"):
        col, other = (3, 2) if change == "r x2" else (2, 3)
        for a1, a2 in PAIRS:
            configured = DriftParams(a1, a2, 1.0, 1.0, MEAN)
            for length in (n, 3 * n):
                h = length // 2
                for seed in range(1, seeds + 1):
                    y = gyro_records(a1, a2, 1.0, change, length, seed)
                    single_t, _, shared_t, _ = run_single_and_shared(y, configured, settings)
                    for mode, traces in (("1", single_t[:1]), ("3", shared_t)):
                        for g, t in enumerate(traces):
                            t_est = settle_time(t.samples, t.estimate[:, col], 2.0, h)
                            t_use = settle_time(t.samples, t.in_use[:, col], 2.0, h)
                            last = t.samples > length - 100000
                            e_chg = float(np.max(np.abs(t.estimate[last, col] / 2.0 - 1.0)))
                            e_oth = float(np.max(np.abs(t.estimate[last, other] - 1.0)))
                            print(f"{a1:7.4f} {a2:7.4f} {change:>6} {length:7d} {seed:4d} "
                                  f"{mode:>5} {g:4d} {t_est / RATE_HZ:7.0f} "
                                  f"{t_use / RATE_HZ:7.0f} {e_chg:8.3f} {e_oth:8.3f}")
                            summary.setdefault((change, a1, length, mode), []).append(
                                [t_est / RATE_HZ, t_use / RATE_HZ, e_chg, e_oth])
    print("# range over the seeds and gyros: t20 est, t20 use (s); largest last chg, last oth")
    for (change, a1, length, mode), rows in summary.items():
        v = np.array(rows)
        print(f"# {change} a1 {a1} {length} samples, {mode} gyro(s), {len(rows)} runs: "
              f"t20 est {v[:, 0].min():.0f}-{v[:, 0].max():.0f}, t20 use "
              f"{v[:, 1].min():.0f}-{v[:, 1].max():.0f}, last {v[:, 2].max():.3f} / "
              f"{v[:, 3].max():.3f}")
    print(f"# {time.monotonic() - t0:.0f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="5 seeds, 480000 samples (docs run)")
    ap.add_argument("--seed", type=int, default=1, help="first seed")
    ap.add_argument("--convergence", action="store_true",
                    help="the online estimate against the offline ML fit instead")
    ap.add_argument("--samples", type=int, default=None,
                    help="--convergence: record length (default 240000; --shared: 720000)")
    ap.add_argument("--seeds", type=int, default=3,
                    help="--convergence: seeds 1..SEEDS per pair and r/q (default 3)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="--convergence: an OnlineDriftSettings field changed from the study's "
                         "(repeatable), e.g. --set warmup_blocks=25")
    ap.add_argument("--shared", action="store_true",
                    help="one gyro against three sharing one identifier: cadence, convergence "
                         "(--samples, default 720000; --seeds) and tracking (--tracking-samples)")
    ap.add_argument("--tracking-samples", type=int, default=480000,
                    help="--shared: length of the tracking records (and three times it)")
    ap.add_argument("--identifier", choices=(*IDENTIFIERS, "both"), default="both",
                    help="the online row(s) of the MSE study: the recursive identifier, the one "
                         "from lag statistics, or both side by side (default)")
    d = LagSchedule()
    ap.add_argument("--lag-cadence", type=int, default=d.cadence,
                    help=f"samples between two fits of the lag identifier (default {d.cadence})")
    ap.add_argument("--lag-delay", type=int, default=d.delay,
                    help=f"samples from a fit's request to its apply point (default {d.delay})")
    ap.add_argument("--lag-max-step", type=float, default=d.max_step,
                    help=f"the lag identifier's bounded step (default {d.max_step:g})")
    args = ap.parse_args()
    if args.shared:
        shared_cadence(args.seed)
        shared_convergence(args.seeds, args.samples or 720000)
        shared_tracking(args.seeds, args.tracking_samples)
        return
    if args.convergence:
        extra: dict[str, float] = {}
        defaults = OnlineDriftSettings().as_dict()
        for item in args.set:
            name, sep, value = item.partition("=")
            if not sep or name not in defaults:
                ap.error(f"--set: expected NAME=VALUE, NAME a field of OnlineDriftSettings, "
                         f"got {item!r}")
            kind = type(defaults[name])
            try:
                extra[name] = (value.lower() in ("1", "true")) if kind is bool else kind(value)
            except ValueError:
                ap.error(f"--set: {name} expects a {kind.__name__}, got {value!r}")
        convergence(seeds=args.seeds, n=args.samples or 240000, extra=extra)
        return
    seeds, n = (5, 480000) if args.full else (1, 240000)
    identifiers = IDENTIFIERS if args.identifier == "both" else (args.identifier,)
    lag = LagSchedule(cadence=args.lag_cadence, delay=args.lag_delay,
                      max_step=args.lag_max_step)
    try:
        lag_settings("none", lag)
    except ValueError as exc:
        ap.error(str(exc))
    t0 = time.monotonic()
    print(f"# {n} samples, {seeds} seed(s) per row, q = 1 before the change; MSE against the "
          "true drift, ratio to the optimum")
    if "lag" in identifiers:
        print(f"# lag: a fit every {lag.cadence} samples, applied {lag.delay} after its "
              f"request, max_step {lag.max_step:g}; min_samples {lag.min_samples_stationary} "
              f"(stationary) / {lag.min_samples_changing} (changing, restart after each fit, "
              "adapt_ar off)")
    print(f"{'a1':>7} {'a2':>7} {'r/q':>4} {'change':>6} {'optimum':>8} {'config':>7} "
          f"{'online':>7} {'lag':>7} {'ML':>7} {'papers':>7} {'retunes':>7} {'refused':>7} "
          f"{'tracking':>8} {'lag ret':>7} {'lag ref':>7} {'lag trk':>7}")

    def col(m: dict[str, float], key: str, fmt: str, scale: float = 1.0) -> str:
        return f"{m[key] / scale:{fmt}}" if key in m else f"{'-':>{fmt.split('.')[0]}}"

    for change in CHANGES:
        for a1, a2 in PAIRS:
            for ratio in RATIOS:
                rows = [run_case(Case(a1, a2, ratio, change, n, args.seed + s), identifiers,
                                 lag) for s in range(seeds)]
                m = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}
                opt = m["optimum"]
                print(f"{a1:7.4f} {a2:7.4f} {ratio:4.1f} {change:>6} {opt:8.4f} "
                      f"{m['configured'] / opt:7.3f} {col(m, 'online', '7.3f', opt)} "
                      f"{col(m, 'lag', '7.3f', opt)} "
                      f"{m['ml'] / opt:7.3f} {m['papers'] / opt:7.3f} "
                      f"{col(m, 'retunes', '7.1f')} {col(m, 'refused', '7.1f')} "
                      f"{col(m, 'tracking', '8.2f')} {col(m, 'lag_retunes', '7.1f')} "
                      f"{col(m, 'lag_refused', '7.1f')} {col(m, 'lag_tracking', '7.2f')}",
                      flush=True)
    print(f"# {time.monotonic() - t0:.0f} s")


if __name__ == "__main__":
    main()
