"""Health alarms (include/gyrodrift/imu/health_alarms.hpp, gyrodrift.stability.health) and the
model Allan variance (include/gyrodrift/stability/model_allan.hpp,
gyrodrift.stability.model_allan): the C++ (double, float) against the numpy references, the
model curve against the autocovariance sums, a long simulation and allantools; false alarms
on stationary simulated records, detection delays, stuck/saturated, latching, counts, trips."""

from __future__ import annotations

import dataclasses

import allantools
import numpy as np
import pytest
import scipy.signal
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.reference import health as ref
from gyrodrift.simulation.presets import PRESETS, simulate_preset
from gyrodrift.stability.health import (
    HEALTH_ALARMS,
    HealthAlarms,
    HealthAlarmSettings,
    alarm_names,
)
from gyrodrift.stability.model_allan import ar2_white_avar, ar2_white_edf_per_term, ieee952_avar

RATE_HZ = 400.0
PAPER_PAIRS = [(-0.0340, 0.0252), (0.6868, -0.0213), (0.2297, 0.1638), (-0.0069, 0.0113)]
# a slow drift: double root 0.995 (correlation time about 200 samples, 0.5 s at 400 Hz)
SLOW = (1.99, -0.990025, 1e-5, 1.0)


def simulate_ar2_white(rng: np.random.Generator, a1: float, a2: float, q: np.ndarray | float,
                       r: np.ndarray | float, n: int, burn: int = 20_000) -> np.ndarray:
    """AR(2) drift + white noise; q and r may vary per sample (a change)."""
    qs = np.broadcast_to(np.asarray(q, dtype=float), (n,))
    rs = np.broadcast_to(np.asarray(r, dtype=float), (n,))
    w = rng.standard_normal(n + burn)
    w[burn:] *= np.sqrt(qs)
    w[:burn] *= np.sqrt(qs[0])
    x = scipy.signal.lfilter([1.0], [1.0, -a1, -a2], w)[burn:]
    return x + np.sqrt(rs) * rng.standard_normal(n) + 3.0


def first_trip_delay(ha: HealthAlarms, name: str, t0: int) -> int:
    trip = ha.trips[name]
    return trip.sample - t0


# ---------------------------------------------------------------- model Allan variance

@pytest.mark.parametrize("model", [(a1, a2, 0.25, 0.09) for a1, a2 in PAPER_PAIRS]
                         + [(1.6, -0.8, 0.25, 0.09), SLOW, (0.999, 0.0, 1e-3, 0.0)])
def test_model_avar_equals_autocovariance_sums(model: tuple[float, float, float, float]) -> None:
    # Doubling recursion (C++) against direct sums of the autocovariance (numpy): 1e-9
    # relative (the drift part is a difference of two sums near m^2 g0 for a smooth drift,
    # which costs digits in both; 1e-12 for the fast models).
    a1, a2, q, r = model
    got = ar2_white_avar(a1, a2, q, r, 14)
    want = ref.ar2_white_avar(a1, a2, q, r, 14)
    rel = 1e-12 if abs(a1) < 1.7 else 1e-9
    np.testing.assert_allclose(got, want, rtol=rel, atol=0.0)


def test_model_avar_against_simulation_and_allantools() -> None:
    # A long AR(2) + white record (2^21 samples): allantools' non-overlapped Allan deviation
    # at the octave taus lies within 4 of its own chi-square standard errors (edf from the
    # white/random-walk bound n/2 .. n) of the model curve at every octave up to 2^12.
    a1, a2, q, r = SLOW
    rng = np.random.default_rng(42)
    y = simulate_ar2_white(rng, a1, a2, q, r, 1 << 21)
    model = ar2_white_avar(a1, a2, q, r, 13)
    taus = 2.0 ** np.arange(13) / RATE_HZ
    t, adev, _, ns = allantools.adev(y, rate=RATE_HZ, data_type="freq", taus=taus)
    np.testing.assert_allclose(t, taus, rtol=1e-12)
    terms = np.asarray(ns, dtype=float)
    for k in range(13):
        edf = terms[k] / 2.0  # the smallest edf of the noise types (conservative)
        z = (adev[k] ** 2 / model[k] - 1.0) / np.sqrt(2.0 / edf)
        assert abs(z) < 4.0, (k, adev[k] ** 2, model[k])


@pytest.mark.parametrize("model", [(*PAPER_PAIRS[1], 0.25, 0.09), (1.6, -0.8, 0.25, 0.09), SLOW])
def test_model_edf_equals_reference(model: tuple[float, float, float, float]) -> None:
    # Doubling recursion and fourth differences of D (C++) against the covariances of the
    # cluster sums summed pair by pair (numpy): 1e-7 relative (both difference large sums).
    got = ar2_white_edf_per_term(*model, 10, n=32)
    want = ref.ar2_white_edf_per_term(*model, 10, 32)
    np.testing.assert_allclose(got, want, rtol=1e-7)
    assert np.all((got > 0.0) & (got <= 1.0))


def test_model_edf_against_simulation() -> None:
    # SLOW model: the blocks of 64 squared differences at octaves 3 .. 6 (on the rising side
    # of the drift's hump: strongly correlated differences) have the edf per term of the
    # model: sample 2 mean^2 / var / 64 over 2^22 samples within 20 % (its standard error is
    # about 5 % at 4000 blocks, 8 % at 1000).
    a1, a2, q, r = SLOW
    e = ar2_white_edf_per_term(a1, a2, q, r, 7, n=64)
    y = simulate_ar2_white(np.random.default_rng(3), a1, a2, q, r, 1 << 22)
    for k in range(3, 7):
        m = 1 << k
        c = len(y) // m
        d2 = np.diff(y[:c * m].reshape(c, m).mean(axis=1)) ** 2
        nb = len(d2) // 64
        b = d2[:nb * 64].reshape(nb, 64).mean(axis=1)
        sample = 2.0 * b.mean() ** 2 / b.var() / 64
        assert e[k] == pytest.approx(sample, rel=0.2), k
    assert e[5] < 0.5  # far fewer than the white noise's 2/3 per term


def test_ieee952_avar_and_errors() -> None:
    tau = np.array([0.5, 2.0])
    want = ref.ieee952_avar(tau, q_angle=0.1, n=0.3, b=0.2, k=0.05)
    np.testing.assert_allclose(ieee952_avar(tau, q_angle=0.1, n=0.3, b=0.2, k=0.05), want,
                               rtol=1e-15)
    with pytest.raises(GyrodriftValueError):
        ar2_white_avar(1.0, 0.5, 1.0, 1.0, 4)  # not stationary
    with pytest.raises(GyrodriftValueError):
        ar2_white_avar(0.5, 0.0, 0.0, 0.0, 4)  # q + r == 0
    with pytest.raises(GyrodriftValueError):
        ieee952_avar([0.0], n=1.0)


# ---------------------------------------------------------------- C++ = reference

def change_record(seed: int, n: int = 60_000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """AR(2) + white with the white noise doubled (2x ARW) after 2/3 of the record, a stuck
    run of 30 and a saturated run of 12 samples."""
    a1, a2, q, r = SLOW
    rng = np.random.default_rng(seed)
    rr = np.full(n, r)
    rr[2 * n // 3:] = 4.0 * r
    y = simulate_ar2_white(rng, a1, a2, q, rr, n)
    stuck = np.zeros(n, dtype=bool)
    stuck[10_000:10_030] = True
    sat = np.zeros(n, dtype=bool)
    sat[20_000:20_012] = True
    sat[30_000:30_005] = True
    return y, stuck, sat


@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("block_terms,model_edf", [(16, False), (64, True)])
def test_double_and_float_equal_reference(seed: int, block_terms: int, model_edf: bool) -> None:
    a1, a2, q, r = SLOW
    y, stuck, sat = change_record(seed)
    reference = ar2_white_avar(a1, a2, q, r, 12)
    edf = ar2_white_edf_per_term(a1, a2, q, r, 12, n=block_terms) if model_edf else None
    kw = dict(arw_factor=1.5, bias_instability_factor=1.5, rate_random_walk_factor=1.5,
              false_alarm_probability=1e-4, stuck_samples=25, saturated_samples=10,
              block_terms=block_terms)
    want = ref.health_alarms(y, RATE_HZ, reference, stuck=stuck, saturated=sat,
                             edf_per_term=edf, **kw)
    assert want.raised[0] == 1 and want.raised[3] == 1 and want.raised[4] == 1
    for dtype, rel in ((np.float64, 1e-12), (np.float32, 1e-5)):
        ha = HealthAlarms(RATE_HZ, reference, HealthAlarmSettings(**kw), edf_per_term=edf,
                          dtype=dtype)
        bits = ha.run(y, stuck, sat)
        assert ha.octave_alarms == [alarm_names(b)[0] for b in ref.octave_alarms(reference)]
        # the same tests on the same terms: identical decisions (no test of these records
        # lies within float rounding of its threshold; a change would show here)
        np.testing.assert_array_equal(bits, want.bits)
        assert [ha.raised[n] for n in HEALTH_ALARMS] == want.raised
        assert [ha.exceedances[n] for n in HEALTH_ALARMS] == want.exceedances
        for i, name in enumerate(HEALTH_ALARMS):
            if not want.raised[i]:
                assert name not in ha.trips
                continue
            trip = ha.trips[name]
            stat, thr, tau, sample = want.trips[i]
            assert trip.sample == sample
            assert trip.statistic == pytest.approx(stat, rel=rel)
            assert trip.threshold == pytest.approx(thr, rel=rel)
            assert trip.tau_s == pytest.approx(tau, rel=1e-7)


def test_reports_every_and_chunks_equal_one_run() -> None:
    a1, a2, q, r = SLOW
    y, stuck, sat = change_record(3)
    reference = ar2_white_avar(a1, a2, q, r, 12)
    s = HealthAlarmSettings(arw_factor=1.5, stuck_samples=25)
    one = HealthAlarms(RATE_HZ, reference, s).run(y, stuck, sat)
    ha = HealthAlarms(RATE_HZ, reference, s)
    parts = [ha.run(y[i:i + 7000], stuck[i:i + 7000], sat[i:i + 7000])
             for i in range(0, len(y), 7000)]
    np.testing.assert_array_equal(np.concatenate(parts), one)
    every = HealthAlarms(RATE_HZ, reference, s).run(y, stuck, sat, every=1000)
    np.testing.assert_array_equal(every, one[999::1000])


# ---------------------------------------------------------------- behaviour

def test_stuck_and_saturated_latched_counted_with_trip() -> None:
    ref_avar = 1.0 / 2.0 ** np.arange(8)
    s = HealthAlarmSettings(stuck_samples=5, saturated_samples=3)
    ha = HealthAlarms(100.0, ref_avar, s)
    y = np.random.default_rng(0).standard_normal(100)
    stuck = np.zeros(100, dtype=bool)
    stuck[10:14] = True  # 4 in a row: below the limit
    stuck[40:47] = True  # 7 in a row: raised at the 5th (sample 45), 3 exceedances
    sat = np.zeros(100, dtype=bool)
    sat[60:63] = True  # raised at sample 63
    sat[80:84] = True  # again: counted, the trip stays the first one
    bits = ha.run(y, stuck, sat)
    assert bits[43] == 0 and bits[44] == 8  # sample 45 (index 44)
    assert bits[61] == 8 and bits[62] == 8 | 16
    assert bits[-1] == 8 | 16  # latched
    assert ha.latched == ["stuck", "saturated"]
    assert ha.raised["stuck"] == 1 and ha.exceedances["stuck"] == 3
    assert ha.raised["saturated"] == 1 and ha.exceedances["saturated"] == 1 + 2
    t = ha.trips["stuck"]
    assert (t.statistic, t.threshold, t.tau_s, t.sample) == (5.0, 5.0, 0.0, 45)
    assert ha.trips["saturated"].sample == 63
    ha.unlatch()
    assert ha.latched == []
    bits = ha.run(y[:10], saturated=np.ones(10, dtype=bool))
    assert bits[1] == 0 and bits[2] == 16  # raised again after unlatch: a new trip
    assert ha.raised["saturated"] == 2 and ha.trips["saturated"].sample == 103
    ha.reset()
    assert ha.latched == [] and ha.raised["stuck"] == 0 and ha.samples == 0


def test_arw_alarm_latches_after_the_change_ends_and_trip_statistic() -> None:
    # White noise of variance 1 (reference exact), 3x the standard deviation for 2000 samples,
    # then back: arw_high stays latched; its trip is the block of octave 0 that first held the
    # change, statistic sqrt(block variance / reference) recomputed here from the samples.
    rng = np.random.default_rng(5)
    y = rng.standard_normal(20_000)
    y[8000:10_000] *= 3.0
    ref_avar = 1.0 / 2.0 ** np.arange(10)
    ha = HealthAlarms(100.0, ref_avar, HealthAlarmSettings(block_terms=64))
    bits = ha.run(y)
    assert not bits[:8000].any() and bits[-1] == 1
    trip = ha.trips["arw_high"]
    assert 8000 < trip.sample <= 8000 + 2 * 64 + 2
    assert trip.tau_s == pytest.approx(0.01)
    # octave 0: term t arrives with sample t + 1; the block ends at the trip sample
    t_end = trip.sample - 1
    d2 = np.diff(y[:trip.sample]) ** 2
    block = d2[t_end - 64:t_end]
    assert trip.statistic == pytest.approx(np.sqrt(block.mean() / 2.0 / ref_avar[0]), rel=1e-12)
    assert trip.threshold == pytest.approx(2.0, rel=1e-12)  # the factor, above the chi2 bound
    assert ha.exceedances["arw_high"] > 1


def test_octave_classes_of_an_ieee952_reference() -> None:
    # N, B, K: the falling octaves are arw_high, the floor bias_instability_high, the rising
    # ones rate_random_walk_high
    tau = 2.0 ** np.arange(20) / RATE_HZ
    avar = ref.ieee952_avar(tau, n=0.05, b=0.01, k=1e-3)
    ha = HealthAlarms(RATE_HZ, avar)
    classes = ha.octave_alarms
    assert classes[:6] == ["arw_high"] * 6
    assert "bias_instability_high" in classes
    assert classes[-1] == "rate_random_walk_high"
    order = [HEALTH_ALARMS.index(c) for c in classes]
    assert order == sorted(order)


def test_bad_settings_and_reference() -> None:
    with pytest.raises(GyrodriftValueError):
        HealthAlarmSettings(arw_factor=0.5)
    with pytest.raises(GyrodriftValueError):
        HealthAlarmSettings(false_alarm_probability=0.0)
    with pytest.raises(GyrodriftValueError):
        HealthAlarmSettings(block_terms=2)
    with pytest.raises(GyrodriftValueError):
        HealthAlarms(RATE_HZ, [1.0, -1.0])
    with pytest.raises(GyrodriftValueError):
        HealthAlarms(RATE_HZ, np.ones(41))
    ha = HealthAlarms(RATE_HZ, [1.0, 0.5])
    with pytest.raises(GyrodriftValueError):
        ha.run(np.zeros(4), stuck=np.zeros(3, dtype=bool))


def test_settings_defaults_equal_the_cpp_struct() -> None:
    from gyrodrift._native import core
    native = core("allan").HealthAlarmSettings()
    py = HealthAlarmSettings()
    for f in dataclasses.fields(py):
        assert getattr(native, f.name) == pytest.approx(getattr(py, f.name), rel=1e-15), f.name


# ---------------------------------------------------------------- false alarms, delays

def test_false_alarm_calibration_without_the_factor() -> None:
    # factor 1 leaves the chi-square bound alone: on white noise with the exact reference
    # the tests fail at about p each. 20 records of 40000 samples (block_terms 64): count
    # the tests (start-up and block tests per octave) and require the failure fraction to
    # lie below 3 p (the moment-matched chi-square and Wilson-Hilferty are conservative or
    # close in the upper tail; a factor 2 mistake in the edf or the variance would fail).
    p = 1e-2
    n, octaves, block = 40_000, 10, 64
    ref_avar = 1.0 / 2.0 ** np.arange(octaves)
    s = HealthAlarmSettings(arw_factor=1.0, bias_instability_factor=1.0,
                            rate_random_walk_factor=1.0, false_alarm_probability=p,
                            block_terms=block)
    tests = fails = 0
    rng = np.random.default_rng(99)
    for _ in range(20):
        ha = HealthAlarms(100.0, ref_avar, s)
        ha.run(rng.standard_normal(n))
        fails += sum(ha.exceedances.values())
        for k in range(octaves):
            terms = n // 2 ** k - 1
            tests += min(terms, block - 1) + terms // block
    assert 0.2 * p < fails / tests < 3.0 * p


@pytest.mark.parametrize("model", [(*PAPER_PAIRS[1], 0.25, 0.09), SLOW])
def test_no_false_alarm_on_stationary_ar2_white(model: tuple[float, float, float, float]) -> None:
    # 4 records of 30 min at 400 Hz (2 h) with the model's exact reference and edf, default
    # settings:
    # no alarm (the Monte Carlo script measures the rate over many more hours).
    a1, a2, q, r = model
    reference = ar2_white_avar(a1, a2, q, r, 18)
    edf = ar2_white_edf_per_term(a1, a2, q, r, 18)
    rng = np.random.default_rng(17)
    for _ in range(4):
        ha = HealthAlarms(RATE_HZ, reference, edf_per_term=edf, dtype=np.float32)
        bits = ha.run(simulate_ar2_white(rng, a1, a2, q, r, 720_000).astype(np.float32),
                      every=720_000)
        assert bits[-1] == 0, ha.trips


@pytest.mark.parametrize("name", ["consumer-mems", "navigation-fog"])
def test_no_false_alarm_on_stationary_presets(name: str) -> None:
    # The presets without their warm-up (a real drift of the bias, not stationary), their
    # exact expected Allan variance as the reference: no alarm in 2 records of 2 h at 100 Hz
    # (consumer) or 20 h at 10 Hz (navigation), default settings.
    preset = dataclasses.replace(PRESETS[name], warmup=None)
    n = 720_000
    for seed in (1, 2):
        rec = simulate_preset(preset, n, seed=seed)
        octaves = 16
        reference = rec.truth.avar_m(2 ** np.arange(octaves))
        ha = HealthAlarms(rec.rate_hz, reference)
        bits = ha.run(rec.gyro_deg_h, every=n)
        assert bits[-1] == 0, ha.trips


def test_detection_delay_2x_arw() -> None:
    # SLOW model, white noise doubled (2x ARW) at t0, default settings: arw_high within 1 s
    # (block of 64 terms at octave 0 is 0.16 s at 400 Hz) in each of 5 records, first of the
    # alarms (the octaves around the drift's hump, where the white noise is still a large
    # part of the reference, may follow: the alarms compare whole variances, not terms).
    a1, a2, q, r = SLOW
    reference = ar2_white_avar(a1, a2, q, r, 18)
    edf = ar2_white_edf_per_term(a1, a2, q, r, 18)
    rng = np.random.default_rng(8)
    n, t0 = 400_000, 200_000
    for _ in range(5):
        rr = np.full(n, r)
        rr[t0:] = 4.0 * r
        ha = HealthAlarms(RATE_HZ, reference, edf_per_term=edf, dtype=np.float32)
        ha.run(simulate_ar2_white(rng, a1, a2, q, rr, n).astype(np.float32), every=n)
        assert "arw_high" in ha.latched
        delay = first_trip_delay(ha, "arw_high", t0)
        assert 0 < delay <= 1.0 * RATE_HZ
        assert all(t.sample - t0 >= delay for t in ha.trips.values())


def test_detection_delay_2x_bias_instability() -> None:
    # SLOW model, the drift's driving noise doubled in standard deviation (its Allan variance
    # around the hump up 4x) at t0, bias_instability_factor 1.5, the model's edf:
    # bias_instability_high within
    # 60 s in each of 5 records, and no arw_high.
    a1, a2, q, r = SLOW
    reference = ar2_white_avar(a1, a2, q, r, 18)
    edf = ar2_white_edf_per_term(a1, a2, q, r, 18)
    s = HealthAlarmSettings(bias_instability_factor=1.5)
    rng = np.random.default_rng(9)
    n, t0 = 400_000, 200_000
    for _ in range(5):
        qq = np.full(n, q)
        qq[t0:] = 4.0 * q
        ha = HealthAlarms(RATE_HZ, reference, s, edf_per_term=edf, dtype=np.float32)
        ha.run(simulate_ar2_white(rng, a1, a2, qq, r, n).astype(np.float32), every=n)
        assert "bias_instability_high" in ha.latched and "arw_high" not in ha.latched
        assert 0 < first_trip_delay(ha, "bias_instability_high", t0) <= 60 * RATE_HZ
