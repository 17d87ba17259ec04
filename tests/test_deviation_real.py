"""The deviation family and the per-tau noise identification on the real laser-gyro record
(PSINS lasergyro.imu, gyro z, 100 Hz; README issue 11 gives the full table from
scripts/deviation_real_record.py)."""

from __future__ import annotations

import math
from pathlib import Path

import allantools
import gyrodrift
import numpy as np
import pytest
from gyrodrift.io.psins import read_psins_imu


@pytest.fixture(scope="module")
def gyro_z_deg_h(lasergyro_path: Path) -> np.ndarray:
    rec = read_psins_imu(lasergyro_path)
    return rec.dtheta[:, 2] / rec.dt_s * (180.0 / math.pi * 3600.0)


def test_acf_reads_white_or_flicker_pm_where_the_slope_rule_says_random_walk(
        gyro_z_deg_h: np.ndarray) -> None:
    acf = gyrodrift.oadev(gyro_z_deg_h, 100.0)
    slope = gyrodrift.oadev(gyro_z_deg_h, 100.0, alpha="slope")
    # the old default: random-walk FM from 0.04 s on (after the vibration hump)
    assert np.all(slope.alpha[slope.tau_s >= 0.04] == -2)
    band = (acf.tau_s >= 0.16) & (acf.tau_s <= 41.0)
    assert band.sum() == 9 and np.all(acf.noise_id[band] == "acf")
    assert np.all(np.isin(acf.alpha[band], (1, 2)))  # quantization / vehicle motion: PM types
    ratio = acf.edf[band] / slope.edf[band]
    assert 40.0 < ratio.max() < 80.0  # the "up to 60x"
    # beyond the ACF range (fewer than 30 averages) the slope value is used and shown
    assert np.all(acf.noise_id[n_avg_below_30(gyro_z_deg_h.size, acf.m)] == "slope")
    # intervals contain the estimate and are narrower with the ACF edf in the band
    assert np.all((acf.ci_low <= acf.adev) & (acf.adev <= acf.ci_high))
    assert np.all((acf.ci_high - acf.ci_low)[band] < (slope.ci_high - slope.ci_low)[band])


def n_avg_below_30(n: int, m: np.ndarray) -> np.ndarray:
    return n // m < 30


@pytest.mark.parametrize("name", ["mdev", "tdev", "hdev", "ohdev", "totdev"])
def test_every_deviation_equals_allantools_on_the_real_record(gyro_z_deg_h: np.ndarray,
                                                             name: str) -> None:
    res = gyrodrift.deviation(gyro_z_deg_h, 100.0, name, alpha=0)
    taus, dev, _, ns = getattr(allantools, name)(gyro_z_deg_h, rate=100.0, data_type="freq",
                                                 taus="octave")
    np.testing.assert_array_equal(res.tau_s, taus)
    np.testing.assert_array_equal(res.terms, ns)
    np.testing.assert_allclose(res.adev, dev, rtol=1e-9, atol=0)
