"""IMU error model for the alignment study: the foundation simulator's IEEE Std 952 gyro terms
(`gyrodrift.simulation.records.simulate`) plus the effects the alignment study adds on top of
the truth increments.

Gyro (rad per sample): constant drift (per axis, deg/h), ARW N, bias instability B, IEEE
quantization Q (white angle error, from the foundation simulator), optional dither residue
(an angle oscillation A sin(2 pi f t + phase) per axis, differenced into the increments, so it
has zero mean and bounded integral), and optional pulse quantization of the output (the
cumulative angle is counted in LSB steps, as a ring-laser gyro's pulse counter does: the
quantization error of the angle stays bounded by one LSB and never accumulates).
Accelerometer (m/s per sample): constant bias (per axis), velocity random walk (white specific
force), optional pulse quantization (LSB in m/s), and an optional gyro-accelerometer timing
offset (the accelerometer increments delayed by a fraction of a sample by linear
interpolation between neighbouring increments).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gyrodrift.errors import GyrodriftValueError
from gyrodrift.simulation.records import simulate
from gyrodrift.units import ARCSEC, DPH, DPSH, UG

__all__ = [
    "ImuErrors",
    "add_imu_errors",
    "kf_noise_from_samples",
    "kf_noise_from_spec",
]


@dataclass(frozen=True)
class ImuErrors:
    """IMU error model of the alignment study (biases in deg/h and micro-g, noise densities,
    quantization, dither residue).

    Examples
    --------
    >>> ImuErrors(arw_deg_rt_h=0.002).arw_deg_rt_h
    0.002
    """
    gyro_bias_deg_h: tuple[float, float, float] = (0.01, 0.01, 0.01)
    arw_deg_rt_h: float = 0.001  # N, deg/sqrt(h)
    bias_instability_deg_h: float = 0.0  # B, deg/h
    q_deg: float = 0.0  # IEEE quantization coefficient (white angle error), deg
    gyro_lsb_arcsec: float = 0.0  # pulse quantization of the output (0 = off)
    dither_residue_arcsec: float = 0.0  # angle amplitude of the dither residue
    dither_hz: tuple[float, float, float] = (87.0, 93.0, 101.0)  # aliased residue frequencies
    accel_bias_ug: tuple[float, float, float] = (100.0, 100.0, 100.0)
    vrw_ug_rt_hz: float = 10.0  # accelerometer white noise density, ug/sqrt(Hz)
    accel_lsb_m_s: float = 0.0  # pulse quantization of the velocity increments (0 = off)
    timing_offset_samples: float = 0.0  # accelerometer lag behind the gyro, samples in [0, 1]


def _pulse_quantize(inc: np.ndarray, lsb: float) -> np.ndarray:
    """Counted output of a pulse-integrating sensor: floor of the cumulative value in LSBs,
    differenced (the residual carries to the next sample)."""
    counts = np.floor(np.cumsum(inc, axis=0) / lsb)
    return np.diff(counts, axis=0, prepend=np.zeros((1, inc.shape[1]))) * lsb


def add_imu_errors(dtheta: np.ndarray, dv: np.ndarray, dt_s: float, err: ImuErrors,
                   seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Return erroneous copies of the truth increments (n, 3) for one Monte Carlo run.

    Examples
    --------
    >>> from gyrodrift.nav import imu_increments, scenario
    >>> dth, dv = imu_increments(scenario("static"), 100, 0.01)
    >>> g, a = add_imu_errors(dth, dv, 0.01, ImuErrors(), seed=1)
    >>> g.shape == dth.shape and not np.array_equal(g, dth)
    True
    """
    n = dtheta.shape[0]
    rate_hz = 1.0 / dt_s
    ss = np.random.SeedSequence(seed)
    s_gyro, s_acc, s_phase = ss.spawn(3)
    gyro_seed = int(s_gyro.generate_state(1)[0] & 0x7FFFFFFF)
    rec = simulate(n=n, rate_hz=rate_hz, q_deg=err.q_deg, n_deg_rt_h=err.arw_deg_rt_h,
                   b_deg_h=err.bias_instability_deg_h, axes=3, seed=gyro_seed)
    rate_rad_s = rec.rate_deg_h * DPH + np.asarray(err.gyro_bias_deg_h) * DPH
    g = dtheta + rate_rad_s * dt_s
    rng_phase = np.random.default_rng(s_phase)
    if err.dither_residue_arcsec > 0.0:
        t = dt_s * np.arange(n + 1)
        ph = rng_phase.uniform(0, 2 * np.pi, 3)
        ang = err.dither_residue_arcsec * ARCSEC * np.sin(
            2 * np.pi * np.asarray(err.dither_hz)[None, :] * t[:, None] + ph[None, :])
        g = g + np.diff(ang, axis=0)
    if err.gyro_lsb_arcsec > 0.0:
        g = _pulse_quantize(g, err.gyro_lsb_arcsec * ARCSEC)
    rng = np.random.default_rng(s_acc)
    a = dv + np.asarray(err.accel_bias_ug) * UG * dt_s
    if err.vrw_ug_rt_hz > 0.0:
        a = a + err.vrw_ug_rt_hz * UG * np.sqrt(dt_s) * rng.standard_normal((n, 3))
    if err.timing_offset_samples > 0.0:
        f = err.timing_offset_samples
        if f > 1.0:
            raise GyrodriftValueError("timing_offset_samples must be in [0, 1]")
        prev = np.vstack([a[:1], a[:-1]])
        a = (1.0 - f) * a + f * prev
    if err.accel_lsb_m_s > 0.0:
        a = _pulse_quantize(a, err.accel_lsb_m_s)
    return g, a


def kf_noise_from_spec(err: ImuErrors) -> tuple[float, float]:
    """(ARW rad/sqrt(s), VRW m/s/sqrt(s)) for the KF process noise from the specification.

    Examples
    --------
    >>> arw, vrw = kf_noise_from_spec(ImuErrors(arw_deg_rt_h=0.001))
    >>> round(arw / DPSH, 6)
    0.001
    """
    return err.arw_deg_rt_h * DPSH, max(err.vrw_ug_rt_hz, 1e-3) * UG


def kf_noise_from_samples(dtheta: np.ndarray, dv: np.ndarray, dt_s: float) -> tuple[float, float]:
    """(ARW, VRW) as a practitioner would take them from the raw per-sample scatter of a record
    (std of the increments about a moving mean, divided by sqrt(dt)): every high-frequency
    component (quantization, dither residue, vibration) is then read as white rate noise.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> dth = 1e-6 * rng.standard_normal((4000, 3))
    >>> arw, vrw = kf_noise_from_samples(dth, np.zeros((4000, 3)), 0.01)
    >>> bool(arw > 0.0)
    True
    """
    def scatter(x: np.ndarray) -> float:
        m = 64
        k = (x.shape[0] // m) * m
        blocks = x[:k].reshape(-1, m, 3)
        return float(np.sqrt(np.mean(np.var(blocks, axis=1))))

    return scatter(dtheta) / np.sqrt(dt_s), scatter(dv) / np.sqrt(dt_s)


