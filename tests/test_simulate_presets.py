"""The realistic preset simulator: Kasdin flicker (Allan slope against allantools' pink
noise as an oracle, level against the analytic IEEE Std 952 floor), the exact truth curve
against the closed forms and against the mean of simulated records, reproducibility."""

from __future__ import annotations

import math

import allantools
import numpy as np
import pytest
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.simulation import PRESETS, SensorPreset, simulate_preset
from gyrodrift.simulation.presets import kasdin_flicker
from gyrodrift.stability.allan import oadev

FLOOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # IEEE Std 952: flat floor / B


def _slope(tau: np.ndarray, adev: np.ndarray, lo: float, hi: float) -> float:
    sel = (tau >= lo) & (tau <= hi)
    return float(np.polyfit(np.log(tau[sel]), np.log(adev[sel]), 1)[0])


def test_kasdin_flicker_is_flat_like_allantools_generators() -> None:
    # Oracles: allantools' own Kasdin generator (noise_kasdin.Noise with phase exponent
    # b = -1, i.e. samples with a 1/f spectrum, read here as rate samples) and its
    # Voss-McCartney pink noise (noise.pink), whose spectrum is 1/f only over a few octaves:
    # its Allan deviation is flat for m <= 64 and falls beyond (measured), so the Voss slope is
    # compared over 2 <= m <= 32 only. Averaged over 6 records of 2^15 samples the slope of a
    # flicker Allan deviation is 0 within about +-0.05 (Monte Carlo spread at these edf);
    # white noise would give -0.5, a random walk +0.5, so +-0.1 separates them clearly.
    n = 1 << 15
    ours, kasdin, voss = [], [], []
    for seed in range(6):
        r = oadev(kasdin_flicker(np.random.default_rng(seed), 1.0, n), 1.0, progress=False)
        ours.append(r.adev**2)
        np.random.seed(seed)  # noqa: NPY002 (allantools draws from numpy's legacy global state)
        gen = allantools.noise_kasdin.Noise(nr=n, qd=1.0, b=-1)
        gen.generateNoise()
        kasdin.append(oadev(np.asarray(gen.time_series), 1.0, progress=False).adev ** 2)
        voss.append(oadev(np.asarray(allantools.noise.pink(n)), 1.0, progress=False).adev ** 2)
    tau = r.tau_s
    s_ours = _slope(tau, np.sqrt(np.mean(ours, axis=0)), 8, 512)
    s_kasdin = _slope(tau, np.sqrt(np.mean(kasdin, axis=0)), 8, 512)
    assert abs(s_ours) < 0.1
    assert abs(s_kasdin) < 0.1
    assert abs(s_ours - s_kasdin) < 0.1
    s_ours_short = _slope(tau, np.sqrt(np.mean(ours, axis=0)), 2, 32)
    s_voss = _slope(tau, np.sqrt(np.mean(voss, axis=0)), 2, 32)
    assert abs(s_voss) < 0.1
    assert abs(s_ours_short - s_voss) < 0.1


def test_flicker_truth_is_the_ieee952_floor() -> None:
    # Exact expected Allan deviation of the Kasdin process (filter truncated at n): within
    # 1.5 % of 0.664 B for 8 dt <= tau <= T / 100 (the sampled spectrum lifts it near dt,
    # the truncation lowers it near T); at tau = dt it is above the floor.
    p = SensorPreset(name="flicker", description="flicker only", rate_hz=1.0, b_deg_h=2.0)
    t = simulate_preset(p, 1 << 16, seed=0).truth
    m = np.array([8, 32, 128, 655])
    np.testing.assert_allclose(t.adev(m.astype(float)), FLOOR * 2.0, rtol=0.015)
    assert t.adev(1.0)[0] > 1.05 * FLOOR * 2.0


def test_flicker_level_matches_truth_by_simulation() -> None:
    # Mean Allan variance of 16 records of 2^14 samples at m = 16: about 16 * 1e3 / 16 ~ 1000
    # differences each, relative sd of one estimate ~ 0.1 (flicker edf), of the mean ~ 0.03:
    # 4 sigma = 12 %.
    p = SensorPreset(name="flicker", description="flicker only", rate_hz=1.0, b_deg_h=1.0)
    n = 1 << 14
    avars = [oadev(kasdin_flicker(np.random.default_rng(s), 1.0, n), 1.0, taus=[16.0],
                   progress=False).adev[0] ** 2 for s in range(16)]
    truth = simulate_preset(p, n, seed=0).truth.adev(16.0)[0] ** 2
    assert np.mean(avars) == pytest.approx(truth, rel=0.12)


def test_white_and_quantization_truth_closed_forms() -> None:
    # 1e-12: the structure-function path is exact for white noise (sums of a delta).
    p = SensorPreset(name="w", description="white + quantization", rate_hz=100.0,
                     n_deg_rt_h=0.5, q_arcsec=2.0)
    t = simulate_preset(p, 4096, seed=0).truth
    tau = np.array([0.01, 0.1, 1.0, 10.0])
    tau_h = tau / 3600.0
    expected = np.sqrt(0.5**2 / tau_h + 3.0 * (2.0 / 3600.0) ** 2 / tau_h**2)
    np.testing.assert_allclose(t.adev(tau), expected, rtol=1e-12)


@pytest.mark.parametrize("name", list(PRESETS))
def test_preset_records_average_to_the_truth(name: str) -> None:
    # Mean Allan variance of 6 records against the exact curve at taus with >= 500 edf in
    # one record: relative sd of the mean <= sqrt(2 / 500 / 6) ~ 2.6 %; 4 sigma = 11 %.
    p = PRESETS[name]
    n = 1 << 15
    runs = []
    for seed in range(6):
        rec = simulate_preset(name, n, seed)
        r = oadev(rec.gyro_deg_h, rec.rate_hz, progress=False)
        runs.append(r.adev**2)
    sel = r.edf >= 500
    assert np.count_nonzero(sel) >= 5
    truth = rec.truth.adev(r.tau_s[sel]) ** 2
    np.testing.assert_allclose(np.mean(runs, axis=0)[sel], truth, rtol=0.11)
    assert rec.rate_hz == p.rate_hz


def test_read_off_and_reproducibility() -> None:
    a = simulate_preset("consumer-mems", 40_000, seed=3)
    b = simulate_preset("consumer-mems", 40_000, seed=3)
    c = simulate_preset("consumer-mems", 40_000, seed=4)
    np.testing.assert_array_equal(a.gyro_deg_h, b.gyro_deg_h)
    assert not np.array_equal(a.gyro_deg_h, c.gyro_deg_h)
    t = a.truth
    assert t.b_min_deg_h == pytest.approx(float(t.adev(t.tau_b_min_s)[0]) / FLOOR, rel=1e-12)
    grid = np.arange(1, 4000) / a.rate_hz
    assert float(np.min(t.adev(grid))) >= t.b_min_deg_h * FLOOR * (1 - 1e-3)
    three = simulate_preset("consumer-mems", 4096, seed=1, axes=3)
    assert three.gyro_deg_h.shape == (4096, 3)


def test_bad_input() -> None:
    with pytest.raises(GyrodriftValueError, match="unknown preset"):
        simulate_preset("no-such", 1000, 0)
    with pytest.raises(GyrodriftValueError, match="n_samples"):
        simulate_preset("tactical-mems", 3, 0)
    with pytest.raises(GyrodriftValueError, match="vibration"):
        SensorPreset(name="x", description="x", rate_hz=10.0, vibration=((1.0, 6.0),))


def test_output_filter_truth_closed_form() -> None:
    # White noise through the FIR g: sigma^2(dt) = r(0) - r(1) with r(j) = s^2 sum g_k g_{k+j}
    # (exact; 1e-12 relative). The filter lowers the short-tau deviation below the N line.
    import scipy.signal

    p = SensorPreset(name="w", description="filtered white", rate_hz=100.0, n_deg_rt_h=1.0,
                     bandwidth_hz=20.0, filter_taps=15)
    t = simulate_preset(p, 4096, seed=0).truth
    g = scipy.signal.firwin(15, 20.0, fs=100.0)
    s2 = 1.0 / (0.01 / 3600.0)
    expected = s2 * (np.sum(g * g) - np.sum(g[:-1] * g[1:]))
    assert t.adev(0.01)[0] ** 2 == pytest.approx(expected, rel=1e-12)
    assert t.adev(0.01)[0] < 0.7 * 60.0 / math.sqrt(0.01)
