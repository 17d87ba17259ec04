"""The gyro monitor (include/gyrodrift/imu/gyro_monitor.hpp) through its binding
(gyrodrift.imu.monitor.run_monitor), its configuration table ([monitor], off by default), and
its place in the processor and the loop program (counters, the health_alarm flag, retunes).

Expected values come from independent computations: the drift model's Allan variance as a
quadratic form of the model's covariance matrix (scipy.linalg.toeplitz), the streaming Allan
curve from gyrodrift.stability.StreamingAllan over the samples the monitor must use, the
stuck/saturated rules written out sample by sample, and faults we put into the records.
"""

from __future__ import annotations

import json
import math
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.imu.config import (
    ConfigError,
    MonitorConfig,
    default_config,
    drift_filter_config,
    dumps_config,
    parse_config,
    write_config,
)
from gyrodrift.imu.monitor import (
    MonitorReference,
    MonitorTrace,
    model_avar,
    reference_from_config,
    reference_from_model,
    reference_from_record,
    run_monitor,
)
from gyrodrift.stability.streaming import StreamingAllan
from scipy.linalg import toeplitz
from scipy.signal import lfilter

RATE_HZ = 400.0
WHITE = (0.0, 0.0, 0.0, 1e-8, 0.0)  # white noise of 1e-4 rad/s (one sigma)


def _ar2_record(rng: np.random.Generator, n: int, a1: float, a2: float, q: float, r: float,
                mean: float = 0.0) -> np.ndarray:
    """AR(2) drift (stationary start: a burn-in of 5000 samples) + white noise + mean."""
    w = rng.normal(0.0, math.sqrt(q), n + 5000)
    x = lfilter([1.0], [1.0, -a1, -a2], w)[5000:]
    return mean + x + rng.normal(0.0, math.sqrt(r), n)


# ----------------------------------------------------------------------------- references


def _avar_quadratic_form(drift: tuple[float, float, float, float, float], m: int) -> float:
    """1/2 E[(ybar2 - ybar1)^2] = 1/2 w^T Sigma w over 2m samples, Sigma from the AR(2)
    autocovariance (Yule-Walker g0, g1 and the recursion) plus r I."""
    a1, a2, q, r, _ = drift
    d = (1.0 + a2) * ((1.0 - a2) ** 2 - a1 * a1)
    g = np.zeros(2 * m)
    g[0] = q * (1.0 - a2) / d
    if 2 * m > 1:
        g[1] = a1 * g[0] / (1.0 - a2)
    for k in range(2, 2 * m):
        g[k] = a1 * g[k - 1] + a2 * g[k - 2]
    sigma = toeplitz(g) + r * np.eye(2 * m)
    w = np.concatenate((-np.ones(m), np.ones(m))) / m
    return 0.5 * float(w @ sigma @ w)


@pytest.mark.parametrize("drift", [
    (1.2, -0.3, 1e-10, 1e-8, 0.0),     # real roots 0.86, 0.35
    (1.6, -0.8, 1e-10, 1e-9, 0.0),     # complex roots (an oscillating drift)
    (0.999, 0.0, 1e-12, 1e-8, 0.01),   # AR(1) near a random walk
    WHITE,
], ids=["real-roots", "complex-roots", "near-random-walk", "white"])
def test_model_avar_equals_the_quadratic_form(drift: tuple[float, float, float, float, float]
                                              ) -> None:
    # double, sums of <= 256 terms: 1e-10 relative leaves room for the cancellation of
    # Var(mean) - Cov(means) near a random walk (both ~ g0, their difference ~ g0 (1 - a1) m)
    got = model_avar(drift, 8)
    want = [_avar_quadratic_form(drift, 1 << k) for k in range(8)]
    np.testing.assert_allclose(got, want, rtol=1e-10)


def test_model_avar_chunked_autocovariance_is_the_recursion() -> None:
    # beyond 4096 lags the autocovariance is advanced a chunk at a time by a matrix power:
    # octave 13 (m = 8192) needs lags up to 16383; compare with the plain recursion's sums
    drift = (1.9, -0.905, 1e-10, 1e-8, 0.0)
    m = 1 << 13
    a1, a2, q, r, _ = drift
    d = (1.0 + a2) * ((1.0 - a2) ** 2 - a1 * a1)
    g = np.zeros(2 * m)
    g[0] = q * (1.0 - a2) / d
    g[1] = a1 * g[0] / (1.0 - a2)
    for k in range(2, 2 * m):
        g[k] = a1 * g[k - 1] + a2 * g[k - 2]
    lag = np.arange(1, 2 * m)
    var = m * g[0] + 2.0 * np.dot(m - lag[: m - 1], g[1:m])
    cov = np.dot(np.minimum(lag, 2 * m - lag), g[1:])
    want = r / m + (var - cov) / (m * m)
    assert model_avar(drift, 14)[13] == pytest.approx(want, rel=1e-9)


def test_model_avar_matches_a_simulated_record(rng: np.random.Generator) -> None:
    # a statistical check of the formula's meaning: 2e6 samples, octaves 0..7 have >= 15600
    # differences each, so the relative standard error is <= sqrt(2 / 15600) = 1.1 %: 5 %
    drift = (1.2, -0.3, 1.0, 4.0, 0.0)
    y = _ar2_record(rng, 2_000_000, *drift[:4])
    sa = StreamingAllan(1.0, 8)
    sa.push(y)
    np.testing.assert_allclose(sa.avar, model_avar(drift, 8), rtol=0.05)


def test_reference_from_config_and_record(rng: np.random.Generator) -> None:
    cfg = drift_filter_config("gy", a1=1.2, a2=-0.3, mean=1e-3, q=1e-10, r=1e-8,
                              sample_rate_hz=RATE_HZ).with_monitor(enabled=True, octaves=10)
    ref = reference_from_config(cfg, "gy")
    assert ref.drift == (1.2, -0.3, 1e-10, 1e-8, 1e-3) and ref.source == "config"
    np.testing.assert_array_equal(ref.avar, model_avar(ref.drift, 10))
    with pytest.raises(GyrodriftValueError, match="'gx' is not monitored"):
        reference_from_config(cfg, "gx")
    y = _ar2_record(rng, 40_000, 1.2, -0.3, 1e-10, 1e-8, 1e-3)
    learned = reference_from_record(y, RATE_HZ, 60.0, 16)  # 24000 samples
    sa = StreamingAllan(RATE_HZ, 16)
    sa.push(y[:24000])
    keep = sa.counts >= 8
    np.testing.assert_array_equal(learned.avar, sa.avar[keep])
    assert learned.source == "learned" and learned.learn_s == 60.0
    assert learned.avar.size == 12  # floor(24000 / 2^k) - 1 >= 8 for k <= 11
    with pytest.raises(GyrodriftValueError, match="too few"):
        reference_from_record(y, RATE_HZ, 0.01, 16)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_reference_learned_from_white_noise_runs_in_float(seed: int) -> None:
    """A white learning span once gave an AR(2) fit at a2 ~ -0.999999, which the float monitor
    refused as non-stationary; the reference now takes the model `gyrodrift fit` would choose."""
    y = np.random.default_rng(seed).normal(2e-4, 1e-3, 6000)  # 60 s of white noise at 100 Hz
    ref = reference_from_record(y, 100.0, 10.0, 10)
    a1, a2 = ref.drift[0], ref.drift[1]
    assert abs(a2) < 0.99 and abs(a1) + abs(a2) < 1.0
    trace = run_monitor(y, 100.0, ref, report_every_s=10.0, dtype=np.float32)
    assert trace.t_s.size >= 5


# ----------------------------------------------------------------------------- the run


def _stuck_saturated_by_hand(y: np.ndarray, saturation: float,
                             stuck_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """The processor's rules (imu_processor.hpp), one sample at a time."""
    stuck = np.zeros(y.size, bool)
    sat = np.zeros(y.size, bool)
    last, run = None, 0
    for i, x in enumerate(y):
        if not math.isfinite(x):
            continue
        run = run + 1 if last is not None and x == last else 1
        last = x
        sat[i] = abs(x) >= saturation
        stuck[i] = stuck_samples != 0 and run >= stuck_samples
    return stuck, sat


def _faulty_record(rng: np.random.Generator, n: int = 48_000) -> np.ndarray:
    y = _ar2_record(rng, n, 1.2, -0.3, 1e-10, 1e-8, 2e-3)
    y[1000:1003] = np.nan
    y[5000] = np.inf
    y[9000:9400] = y[9000]  # stuck for 1 s
    y[20_000:20_050] = 0.5  # saturated (and stuck)
    y[30_000:30_004] = y[29_999]  # a short repeat: stuck only from the 5th equal value on
    return y


def test_run_monitor_curve_is_the_streaming_allan_of_the_good_samples(
        rng: np.random.Generator) -> None:
    y = _faulty_record(rng)
    ref = reference_from_model((1.2, -0.3, 1e-10, 1e-8, 2e-3), RATE_HZ, 12)
    settings = MonitorConfig(octaves=14)
    tr = run_monitor(y, RATE_HZ, ref, settings=settings, report_every_s=20.0, saturation=0.1,
                     stuck_samples=5)
    stuck, sat = _stuck_saturated_by_hand(y, 0.1, 5)
    good = np.isfinite(y) & ~stuck & ~sat
    every = 8000
    assert tr.t_s.tolist() == [20.0 * (i + 1) for i in range(6)]
    assert tr.avar.shape == (6, 14) and tr.tau_s[0] == 1.0 / RATE_HZ
    for row in range(6):
        sa = StreamingAllan(RATE_HZ, 14)
        upto = (row + 1) * every
        sa.push(y[:upto][good[:upto]])
        # double, the same cascaded sums on the same samples: 1e-12 relative
        np.testing.assert_allclose(tr.avar[row], sa.avar, rtol=1e-12, equal_nan=True)
    # the same with the flags given instead of computed
    tr2 = run_monitor(y, RATE_HZ, ref, settings=settings, report_every_s=20.0, stuck=stuck,
                      saturated=sat)
    np.testing.assert_array_equal(tr2.avar, tr.avar)
    assert tr.status == ("off",) * 6 and np.all(np.isnan(tr.gain0))


def test_run_monitor_float_state_within_bound(rng: np.random.Generator) -> None:
    # 30 min at 400 Hz of a float32 record: the float monitor's curve against the double
    # monitor's on the same (float32) samples; bound 1e-5 relative (the streaming curve's
    # float error is ~1e-6 after 10 h, docs/validation/streaming-allan.md)
    y = _ar2_record(rng, 720_000, 1.2, -0.3, 1e-10, 1e-8, 1e-3).astype(np.float32)
    ref = reference_from_model((1.2, -0.3, 1e-10, 1e-8, 1e-3), RATE_HZ, 16)
    t64 = run_monitor(y, RATE_HZ, ref, report_every_s=600.0)
    t32 = run_monitor(y, RATE_HZ, ref, report_every_s=600.0, dtype=np.float32)
    np.testing.assert_allclose(t32.avar, t64.avar, rtol=1e-5, equal_nan=True)
    assert np.array_equal(t32.health, t64.health)


def test_run_monitor_refuses_bad_input() -> None:
    ref = reference_from_model(WHITE, RATE_HZ, 8)
    y = np.zeros(100)
    with pytest.raises(GyrodriftValueError, match="1-D"):
        run_monitor(np.zeros((10, 3)), RATE_HZ, ref)
    with pytest.raises(GyrodriftValueError, match="rate_hz"):
        run_monitor(y, 0.0, ref)
    with pytest.raises(GyrodriftValueError, match="one flag per sample"):
        run_monitor(y, RATE_HZ, ref, stuck=np.zeros(99, bool))
    bad = MonitorReference(drift=(1.5, 0.0, 1e-10, 1e-8, 0.0), avar=ref.avar)
    with pytest.raises(GyrodriftValueError, match="stationary"):
        run_monitor(y, RATE_HZ, bad)
    zero = MonitorReference(drift=WHITE, avar=np.zeros(8))
    with pytest.raises(GyrodriftValueError, match="positive and finite"):
        run_monitor(y, RATE_HZ, zero)


def test_stuck_channel_raises_the_stuck_alarm_with_its_duration(
        rng: np.random.Generator) -> None:
    # 0.5 s allowed; a stuck run of 1 s from sample 9000 (stuck from its 5th equal value)
    y = _faulty_record(rng)
    ref = reference_from_model((1.2, -0.3, 1e-10, 1e-8, 2e-3), RATE_HZ, 12)
    tr = run_monitor(y, RATE_HZ, ref, settings=MonitorConfig(stuck_alarm_s=0.5,
                                                             saturated_alarm_s=0.0),
                     report_every_s=10.0, saturation=0.1, stuck_samples=5)
    assert "stuck" in tr.flags(len(tr.t_s) - 1)  # latched to the end
    assert tr.flags(0) == []  # the first 10 s are clean
    trip = tr.trips["stuck"]
    # the 200th stuck sample in a row is sample 9000 + 4 + 199
    assert trip["t_s"] == pytest.approx((9000 + 4 + 200) / RATE_HZ)
    assert "saturated" not in tr.trips  # off


def test_arw_increase_raises_the_arw_alarm(rng: np.random.Generator) -> None:
    # white noise whose variance goes up 9x (ARW 3x) after 10 minutes: the arw_high alarm
    # (factor 2) is raised, not before the change, and within 10 minutes after it
    n = 480_000
    y = rng.normal(0.0, 1e-4, n)
    y[240_000:] *= 3.0
    ref = reference_from_model(WHITE, RATE_HZ, 12)
    tr = run_monitor(y, RATE_HZ, ref, settings=MonitorConfig(octaves=12), report_every_s=60.0)
    first = next(i for i in range(len(tr.t_s)) if "arw_high" in tr.flags(i))
    assert 600.0 < tr.t_s[first] <= 1200.0
    assert 600.0 < tr.trips["arw_high"]["t_s"] <= 1200.0
    assert tr.trips["arw_high"]["statistic"] > tr.trips["arw_high"]["threshold"]


def test_stationary_record_raises_no_alarm(rng: np.random.Generator) -> None:
    drift = (1.2, -0.3, 1e-10, 1e-8, 1e-3)
    y = _ar2_record(rng, 720_000, *drift[:4], mean=1e-3)
    tr = run_monitor(y, RATE_HZ, reference_from_model(drift, RATE_HZ, 14),
                     settings=MonitorConfig(octaves=14), report_every_s=60.0)
    assert not np.any(tr.health), tr.trips


def test_reidentification_retunes_on_a_long_record(rng: np.random.Generator) -> None:
    # the configured model is off by 4x in q; after the learning time the re-identification
    # tracks and retunes the gain towards the record's model
    true = (1.2, -0.3, 4e-10, 1e-8, 0.0)
    y = _ar2_record(rng, 400_000, *true[:4])
    ref = reference_from_model((1.2, -0.3, 1e-10, 1e-8, 0.0), RATE_HZ, 12)
    cfg = MonitorConfig(octaves=12, reidentify=True, min_learn_s=300.0, retune_s=60.0)
    tr = run_monitor(y, RATE_HZ, ref, settings=cfg, report_every_s=60.0)
    assert tr.status[0] == "learning"
    assert tr.status[-1] == "tracking" and tr.retunes[-1] >= 1
    # the model in use left the configured q (1e-10) towards the record's (4e-10); how close
    # the estimator gets in how long is the identifier's own validation
    assert tr.q[-1] > 2e-10 and tr.q[0] == pytest.approx(1e-10, rel=1e-6)
    assert np.all(np.isfinite(tr.gain0))


def test_reidentify_ar_false_holds_the_ar_coefficients(rng: np.random.Generator) -> None:
    """[monitor] reidentify_ar = false reaches the re-identification: a1 and a2 of its running
    estimate stay at the configured model's while q moves; with the default (true) the AR
    part is estimated too (the same record and settings otherwise)."""
    true = (1.2, -0.3, 4e-10, 1e-8, 0.0)
    y = _ar2_record(rng, 200_000, *true[:4])
    ref = reference_from_model((1.1, -0.25, 1e-10, 1e-8, 0.0), RATE_HZ, 12)
    held = run_monitor(y, RATE_HZ, ref, report_every_s=60.0, settings=MonitorConfig(
        octaves=12, reidentify=True, reidentify_ar=False, min_learn_s=100.0, retune_s=60.0))
    free = run_monitor(y, RATE_HZ, ref, report_every_s=60.0, settings=MonitorConfig(
        octaves=12, reidentify=True, min_learn_s=100.0, retune_s=60.0))
    assert np.all(held.est_a1 == held.est_a1[0]) and np.all(held.est_a2 == held.est_a2[0])
    assert held.est_a1[0] == pytest.approx(1.1, rel=1e-12)
    assert held.est_q[-1] != pytest.approx(1e-10, rel=1e-3)
    assert free.est_a1[-1] != pytest.approx(1.1, rel=1e-3)


def test_lag_fit_status_names_are_the_core_enum() -> None:
    from gyrodrift._native import core
    from gyrodrift.imu.monitor import LAG_FIT_STATUS_NAMES

    members = core("drift").LagDriftFitStatus.__members__
    assert {int(v): k for k, v in members.items()} == dict(enumerate(LAG_FIT_STATUS_NAMES))


def test_run_monitor_lag_fit_delay_within_the_retune_interval(rng: np.random.Generator) -> None:
    """The lag identifier over one gyro: its fit must be applied within one retune interval
    (fit_delay_s <= retune_s, in samples); the recursive identifier does not look at it."""
    y = rng.normal(0.0, 1e-4, 4000)
    ref = reference_from_model(WHITE, RATE_HZ, 8)
    slow = MonitorConfig(octaves=8, reidentify=True, identifier="lag", retune_s=5.0,
                         fit_delay_s=5.5)
    with pytest.raises(ConfigError, match=r"^monitor\.fit_delay_s: 1 gyro x 2200 samples "
                                          r"exceed retune_s = 2000 samples at 400\.0 Hz"):
        run_monitor(y, RATE_HZ, ref, settings=slow)
    tr = run_monitor(y, RATE_HZ, ref, settings=replace(slow, identifier="recursive"))
    assert tr.identifier == "recursive" and tr.fit_status == ()
    tr = run_monitor(y, RATE_HZ, ref, settings=replace(slow, fit_delay_s=5.0))
    assert tr.identifier == "lag" and set(tr.fit_status) == {"too_few_samples"}


# ----------------------------------------------------------------------------- configuration


def test_monitor_is_off_by_default_and_absent_from_the_default_file() -> None:
    cfg = default_config()
    assert cfg.monitor == MonitorConfig() and not cfg.monitor.enabled
    assert "[monitor]" not in dumps_config(cfg)


def test_monitor_section_round_trips() -> None:
    cfg = drift_filter_config("gz", a1=0.6, a2=0.2, mean=0.0, q=1e-10, r=1e-8,
                              sample_rate_hz=RATE_HZ).with_monitor(
        enabled=True, octaves=14, reidentify=True, block_s=0.5, retune_s=30.0,
        stuck_alarm_s=0.25, memory_s=3600.0, identified_max_rel_stderr=0.3,
        identifier="lag", fit_delay_s=7.5, restart_after_fit=True)
    text = dumps_config(cfg)
    assert "[monitor]\nenabled = true\noctaves = 14\n" in text
    assert 'identifier = "lag"\n' in text and "restart_after_fit = true\n" in text
    back = parse_config(text)
    assert back == cfg and back.monitor.samples(RATE_HZ) == {
        "stuck_samples": 100, "saturated_samples": 400, "block_samples": 200,
        "retune_blocks": 60, "retune_samples": 12_000, "min_samples": 240_000,
        "memory_blocks": 7200.0, "report_samples": 4000, "fit_delay_samples": 3000}
    assert cfg.monitored_channels() == ("gz",)
    assert MonitorConfig().identifier == "recursive" and not MonitorConfig().restart_after_fit


@pytest.mark.parametrize("table,key", [
    ("[monitor]\nenabled = true\n", "monitor.enabled"),  # the default chain: wavelet first
    ("[monitor]\noctaves = 1\n", "monitor.octaves"),
    ("[monitor]\narw_factor = 1.0\n", "monitor.arw_factor"),
    ("[monitor]\nfalse_alarm_probability = 1e-50\n", "monitor.false_alarm_probability"),
    ("[monitor]\nbogus = 1\n", "monitor.bogus"),
    ("[monitor]\nreidentify = 1\n", "monitor.reidentify"),
    ('[monitor]\nidentifier = "kalman"\n', "monitor.identifier"),
    ("[monitor]\nfit_delay_s = 0.0\n", "monitor.fit_delay_s"),
    ("[monitor]\nrestart_after_fit = 1\n", "monitor.restart_after_fit"),
    # the lag identifier's fit must be applied within one retune interval (one gyro here)
    ('[monitor]\nidentifier = "lag"\nfit_delay_s = 61.0\n', "monitor.fit_delay_s"),
    ("monitor = 3\n", "monitor"),
])
def test_monitor_section_errors_name_the_key(table: str, key: str) -> None:
    text = dumps_config(default_config())
    at = (text.index("[channels.gx]") if table.startswith("[")
          else text.index("version = 1\n") + len("version = 1\n"))  # a top-level key
    with pytest.raises(ConfigError) as info:
        parse_config(text[:at] + table + "\n" + text[at:])
    assert str(info.value).startswith(key + ":"), str(info.value)


# ----------------------------------------------------------------------------- the loop


@pytest.fixture(scope="module")
def loop_bin(cpp_build_dir: Path) -> Path:
    from gyrodrift.replay.harness import LOOP_RELATIVE

    path = cpp_build_dir / LOOP_RELATIVE
    assert path.is_file(), path
    return path


def _run_loop(loop_bin: Path, config: Path, frames: bytes, n: int) -> tuple[bytes, dict]:
    from test_loop_program import Loop

    loop = Loop(loop_bin, "--serial", "--config", str(config), "--no-rt")
    loop.write(frames)
    got = loop.read_until(n * 42, timeout_s=30.0)
    return got, loop.finish()


def _monitor_records(rng: np.random.Generator, n: int) -> tuple[bytes, np.ndarray]:
    from gyrodrift.codecs.wire import encode_frames, make_samples

    t = np.arange(n) / RATE_HZ
    gyro = rng.normal(0.0, 1e-4, (n, 3))
    if n > 2400:
        gyro[2000:2400, 2] = gyro[2000, 2]  # gz stuck for 1 s
    s = make_samples(t, gyro, rng.normal(0.0, 1.0, (n, 3)))
    return encode_frames(s).tobytes(), s.channels


def _configs(tmp_path: Path) -> tuple[Path, Path]:
    from gyrodrift.imu.config import ChannelConfig

    base = drift_filter_config("gz", a1=0.0, a2=0.0, mean=0.0, q=0.0, r=1e-8,
                               sample_rate_hz=RATE_HZ)
    gz = base.channel("gz")
    base = base.with_channel("gz", ChannelConfig("gz", gz.stages, stuck_samples=5))
    on = base.with_monitor(enabled=True, octaves=10, stuck_alarm_s=0.5)
    return write_config(base, tmp_path / "off.toml"), write_config(on, tmp_path / "on.toml")


def test_loop_with_monitor_counts_alarms_and_keeps_outputs(loop_bin: Path, tmp_path: Path,
                                                           rng: np.random.Generator) -> None:
    from gyrodrift.codecs.wire import decode_stream
    from gyrodrift.imu import contract

    off, on = _configs(tmp_path)
    n = 4000
    frames, _ = _monitor_records(rng, n)
    out_off, stats_off = _run_loop(loop_bin, off, frames, n)
    out_on, stats_on = _run_loop(loop_bin, on, frames, n)
    d_off, d_on = decode_stream(out_off), decode_stream(out_on)
    assert len(d_off.samples.seq) == len(d_on.samples.seq) == n
    # without re-identification the monitor only watches: the same values, bit for bit
    np.testing.assert_array_equal(d_on.samples.channels, d_off.samples.channels)
    alarm = contract.FLAG_HEALTH_ALARM
    assert not np.any(d_off.samples.flags & alarm)
    # the stuck alarm: 200 stuck samples in a row (0.5 s) from the 5th equal value at 2004
    raised = np.flatnonzero(d_on.samples.flags & alarm)
    assert raised.size and raised[0] == 2004 + 199 and raised[-1] == n - 1
    assert np.array_equal(d_on.samples.flags & (0xFFFF ^ alarm), d_off.samples.flags)
    keys = list(stats_on["health"])[-7:]
    assert keys == ["arw_high_alarms", "bias_instability_alarms",
                    "rate_random_walk_alarms", "stuck_alarms", "saturated_alarms",
                    "monitor_retunes", "monitor_refused_retunes"]
    assert stats_on["health"]["stuck_alarms"] == 1
    assert all(stats_off["health"][k] == 0 for k in keys)


def _steady_state_outputs(x: np.ndarray, trace: MonitorTrace) -> np.ndarray:
    """The processor's steady-state AR(2)-Kalman stage over float32 inputs `x`, written out
    from its equations (ar2_steady_state.hpp) in float32, with the model and gain of the
    monitor trace's row i (one row per sample) in use at sample i: a retune moves the state by
    the change of the mean (the filtered rate is kept)."""
    f = np.float32
    model = (f(trace.a1[0]), f(trace.a2[0]), f(trace.mean[0]), f(trace.gain0[0]),
             f(trace.gain1[0]))
    s0 = s1 = f(0.0)
    out = np.empty(x.size)
    for i in range(x.size):
        now = (f(trace.a1[i]), f(trace.a2[i]), f(trace.mean[i]), f(trace.gain0[i]),
               f(trace.gain1[i]))
        if now != model:
            shift = f(model[2] - now[2])
            s0, s1, model = f(s0 + shift), f(s1 + shift), now
        a1, a2, mean, k0, k1 = model
        x0 = f(f(a1 * s0) + f(a2 * s1))
        v = f(f(x[i] - mean) - x0)
        s0, s1 = f(x0 + f(k0 * v)), f(s0 + f(k1 * v))
        out[i] = float(f(s0 + mean))
    return out


def test_loop_with_the_lag_identifier_equals_the_monitor_run(loop_bin: Path, tmp_path: Path,
                                                            rng: np.random.Generator) -> None:
    """[monitor] identifier = "lag" in the loop: the one watched gyro's fits are the ones
    run_monitor computes over the same float32 samples (the Python side of the same core,
    inline fits), applied at the same samples. 300 s at 100 Hz of the papers' pair
    (0.6868, -0.0213), r/q = 1, from a configured model off by 2x-4x: fits every 60 s
    (5 s delay, each from the samples since the previous one: 55 s, at least the 30 s
    min_learn_s), steps of at most 0.5.
    The loop's filtered gz equals the steady-state filter written out in float32 with the
    trace's model and gain per sample, within 1e-5 of the output's standard deviation
    (float rounding; retuning one sample late moves outputs by 14 % of it), and its retune
    counters equal the trace's gain changes and refusals."""
    from gyrodrift.codecs.wire import decode_stream, encode_frames, make_samples

    rate, n, sig = 100.0, 30000, 1e-5
    gz = sig * _ar2_record(rng, n, 0.6868, -0.0213, 1.0, 1.0, mean=0.5)
    cfg = drift_filter_config("gz", a1=0.5, a2=0.1, mean=0.0, q=2.0 * sig**2, r=0.25 * sig**2,
                              sample_rate_hz=rate).with_monitor(
        enabled=True, octaves=10, reidentify=True, identifier="lag", retune_s=60.0,
        fit_delay_s=5.0, min_learn_s=30.0, max_step=0.5, restart_after_fit=True)
    gyro = np.zeros((n, 3))
    gyro[:, 2] = gz
    s = make_samples(np.arange(n) / rate, gyro, np.zeros((n, 3)))
    got, stats = _run_loop(loop_bin, write_config(cfg, tmp_path / "lag.toml"),
                           encode_frames(s).tobytes(), n)
    out = decode_stream(got).samples.channels[:, 2].astype(np.float64)
    x = np.ascontiguousarray(s.channels[:, 2], dtype=np.float32)
    trace = run_monitor(x, rate, reference_from_config(cfg, "gz"), settings=cfg.monitor,
                        report_every_s=1.0 / rate, dtype=np.float32)
    assert trace.t_s.size == n and trace.identifier == "lag"
    # fits requested at 60, 120, 180, 240 s, each applied 5 s later (the one at 300 s is
    # not); from 55 s each, some are refused (not identified): both outcomes are compared
    assert int(trace.retunes[-1]) + int(trace.refused_retunes[-1]) == 4
    assert int(trace.retunes[-1]) >= 1
    # the loop counts the gain changes its filter takes (accepted fits, and fallbacks that put
    # the configured gain back), and the refusals
    changed = np.flatnonzero(np.diff(trace.gain0) != 0.0) + 1
    assert changed.size >= 1 and set(changed.tolist()) <= {6499, 12499, 18499, 24499}
    assert stats["health"]["monitor_retunes"] == changed.size
    assert stats["health"]["monitor_refused_retunes"] == int(trace.refused_retunes[-1])
    want = _steady_state_outputs(x, trace)
    np.testing.assert_allclose(out, want, rtol=0.0, atol=1e-5 * float(np.std(want)))


def test_health_names_fit_the_health_report_frame() -> None:
    # the firmware sends each counter as a 0x82 frame whose name field holds 24 bytes: a longer
    # name arrives cut and no longer matches the host loop's (monitor_bias_instability_high did)
    from gyrodrift.imu import contract

    assert all(len(k) <= 24 for k in contract.HEALTH_KEYS), contract.HEALTH_KEYS


def test_loop_check_config_reads_the_monitor_section(loop_bin: Path, tmp_path: Path) -> None:
    _, on = _configs(tmp_path)
    r = subprocess.run([str(loop_bin), "--check-config", str(on)], capture_output=True,
                       text=True, timeout=20)
    assert r.returncode == 0, r.stderr
    bad = tmp_path / "bad.toml"
    bad.write_text(on.read_text().replace("octaves = 10", "octaves = 25"))
    r = subprocess.run([str(loop_bin), "--check-config", str(bad)], capture_output=True,
                       text=True, timeout=20)
    assert r.returncode == 2 and "monitor.octaves: expected 2..24, got 25" in r.stderr
    with pytest.raises(ConfigError, match=r"^monitor\.octaves: expected 2\.\.24, got 25$"):
        parse_config(bad.read_text())


def test_loop_json_is_strict(loop_bin: Path, tmp_path: Path, rng: np.random.Generator) -> None:
    _, on = _configs(tmp_path)
    frames, _ = _monitor_records(rng, 500)
    _, stats = _run_loop(loop_bin, on, frames, 500)
    json.dumps(stats, allow_nan=False)


def test_run_monitor_is_the_composition_of_its_parts(rng: np.random.Generator) -> None:
    # the monitor = the health alarms (gyrodrift.stability.health) fed the samples the monitor
    # uses (stuck, saturated and non-finite ones as missing) with the processor's flags, and
    # the noise estimates read from that curve: the same bits at every report, the same
    # trips, the same estimates (double state, the same operations: 1e-12 relative)
    from gyrodrift.stability.health import HealthAlarms, HealthAlarmSettings

    y = _faulty_record(rng)
    y[30_000:] *= 3.0  # ARW up 3x: the arw alarm trips
    drift = (1.2, -0.3, 1e-10, 1e-8, 2e-3)
    ref = reference_from_model(drift, RATE_HZ, 12)
    settings = MonitorConfig(octaves=12, stuck_alarm_s=0.5, saturated_alarm_s=0.05)
    tr = run_monitor(y, RATE_HZ, ref, settings=settings, report_every_s=20.0, saturation=0.1,
                     stuck_samples=5)
    stuck, sat = _stuck_saturated_by_hand(y, 0.1, 5)
    ha = HealthAlarms(RATE_HZ, ref.avar, HealthAlarmSettings(stuck_samples=200,
                                                             saturated_samples=20),
                      edf_per_term=ref.edf_per_term)
    bits = ha.run(np.where(stuck | sat, np.nan, y), stuck, sat)
    np.testing.assert_array_equal(tr.health, bits[8000 - 1::8000])
    assert set(tr.trips) == set(ha.trips) and "arw_high" in tr.trips and "stuck" in tr.trips
    for name, trip in ha.trips.items():
        assert tr.trips[name]["t_s"] == trip.sample / RATE_HZ
        assert tr.trips[name]["statistic"] == pytest.approx(trip.statistic, rel=1e-12)
    est = ha.estimate_noise(settings.coverage)
    assert tr.n[-1] == pytest.approx(est.n.value, rel=1e-12)
    assert tr.n_hi[-1] == pytest.approx(est.n.hi, rel=1e-12)
