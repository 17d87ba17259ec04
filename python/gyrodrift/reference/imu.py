"""numpy reference of the six-channel IMU processor (include/gyrodrift/imu/imu_processor.hpp).

Written from the processor's definition, in two plain passes: (1) a per-sample loop over
sequence numbers, timestamps and values that decides which frames are accepted and which
values are bad (NaN/Inf, saturated, stuck), and (2) the per-channel filters run over each
channel's accepted series with bad values replaced by NaN, using the reference filters of
gyrodrift.reference (AR(2)-Kalman: reference.ar2.kalman_filter, predict-only on NaN;
real-time wavelet: reference.wavelet.realtime_wavelet, skip-and-hold on NaN). Pass-through
and bias channels hold their last output over bad values (0 before the first good one).
This is what the replay harness compares the loop's outputs against.
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from gyrodrift.filters.ar2 import Ar2Model
from gyrodrift.imu.contract import (
    CHANNELS,
    FLAG_DUPLICATE,
    FLAG_FILTER_FAULT,
    FLAG_NON_FINITE,
    FLAG_OUT_OF_ORDER,
    FLAG_REJECTED,
    FLAG_RESYNC,
    FLAG_SATURATED,
    FLAG_SEQ_GAP,
    FLAG_STUCK,
    FLAG_TIME_JUMP,
    HEALTH_KEYS,
    RESYNC_AFTER,
)
from gyrodrift.imu.processor import ImuChannelConfig, ImuConfig, ImuResult, WaveletSettings

if TYPE_CHECKING:
    from gyrodrift.imu.config import ProcessorConfig

__all__ = ["WaveletSettings", "process_imu"]


def _stage(
    kind: str, z: np.ndarray, cc: ImuChannelConfig, good: np.ndarray,
    wavelet: WaveletSettings | None,
) -> np.ndarray:
    """One stage over a channel's accepted series; z is NaN where the input is missing."""
    if kind == "ar2_kalman":
        from gyrodrift.reference.ar2 import kalman_filter

        model = Ar2Model(a1=cc.a1, a2=cc.a2, sigma2=cc.sigma2, mean=cc.mean, r=cc.r)
        return kalman_filter(z, model, q=cc.q, r=cc.r, p0=cc.p0, steady_state=cc.steady_state)
    if kind == "wavelet":
        ws = cc.wavelet or wavelet
        if ws is None:
            raise ValueError("a channel uses the wavelet stage: pass wavelet=WaveletSettings(...)")
        from gyrodrift.reference.wavelet import realtime_wavelet

        return realtime_wavelet(z, ws.wavelet, ws.window, ws.level, ws.threshold)
    bias = cc.bias if kind == "bias_removal" else 0.0
    out = np.empty_like(z)
    last = 0.0
    for k in range(z.size):
        if good[k]:
            last = z[k] - bias
        out[k] = last
    return out


def _channel_filter(
    x: np.ndarray, cc: ImuChannelConfig, good: np.ndarray, wavelet: WaveletSettings | None
) -> np.ndarray:
    """One channel's chain over its accepted series: `filter`, then `filter2` unless it is
    pass_through; a missing input stays missing for the second stage; without a
    bias_removal stage the bias is subtracted at the end."""
    y = _stage(cc.filter, np.where(good, x, np.nan), cc, good, wavelet)
    if cc.filter2 != "pass_through":
        y = _stage(cc.filter2, np.where(good, y, np.nan), cc, good, wavelet)
    if "bias_removal" not in (cc.filter, cc.filter2):
        y = y - cc.bias
    return y


def process_imu(
    seq: npt.ArrayLike,
    t_us: npt.ArrayLike,
    values: npt.ArrayLike,
    config: ImuConfig | ProcessorConfig | str | os.PathLike[str],
    *,
    wavelet: WaveletSettings | None = None,
) -> ImuResult:
    """Reference processor over a whole record (float64). Rows that are rejected
    (duplicate / out-of-order seq) get NaN values and FLAG_REJECTED, as in the binding.
    `config` may be a configuration file (or gyrodrift.imu.config.ProcessorConfig).

    Examples
    --------
    >>> from gyrodrift.imu.processor import ImuChannelConfig, ImuConfig
    >>> cfg = ImuConfig(channels=[ImuChannelConfig() for _ in range(6)])  # pass-through
    >>> out = process_imu(np.array([0, 1, 1]), np.array([0, 2500, 2500]), np.ones((3, 6)), cfg)
    >>> out.values[:, 0], out.health["samples_in"]  # the repeated sample is rejected (NaN)
    (array([ 1.,  1., nan]), 3)
    """
    if not isinstance(config, ImuConfig):
        config = ImuConfig.from_processor_config(config)
    config.validate()
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != CHANNELS:
        raise ValueError(f"values: expected shape (n, 6), got {v.shape}")
    n = v.shape[0]
    seqs = [int(s) for s in np.asarray(seq).reshape(-1)]
    times = [int(t) for t in np.asarray(t_us).reshape(-1)]
    if len(seqs) != n or len(times) != n:
        raise ValueError(f"seq and t_us: expected {n} entries each")
    health = dict.fromkeys(HEALTH_KEYS, 0)
    flags = np.zeros(n, dtype=np.uint16)
    good = np.ones((n, CHANNELS), dtype=bool)
    accepted = np.zeros(n, dtype=bool)

    # Pass 1: sequence/timestamp logic and per-value health, sample by sample.
    last_seq: int | None = None
    last_t = 0
    rejects = 0
    last_raw: list[float | None] = [None] * CHANNELS
    run = [0] * CHANNELS
    for k in range(n):
        health["samples_in"] += 1
        f = 0
        if last_seq is not None:
            d = (seqs[k] - last_seq) % 65536
            if d == 0 or d >= 0x8000:
                rejects += 1
                if rejects < RESYNC_AFTER:
                    key, bit = (
                        ("duplicates", FLAG_DUPLICATE)
                        if d == 0
                        else (
                            "out_of_order",
                            FLAG_OUT_OF_ORDER,
                        )
                    )
                    health[key] += 1
                    flags[k] = bit | FLAG_REJECTED
                    continue
                health["seq_resyncs"] += 1
                f |= FLAG_RESYNC
            else:
                if d > 1:
                    health["seq_gaps"] += 1
                    health["missing_samples"] += d - 1
                    f |= FLAG_SEQ_GAP
                if config.time_tolerance_us != 0:
                    expected = d * config.period_us
                    if (
                        times[k] < last_t
                        or abs((times[k] - last_t) - expected) > config.time_tolerance_us
                    ):
                        health["time_jumps"] += 1
                        f |= FLAG_TIME_JUMP
        rejects = 0
        last_seq = seqs[k]
        last_t = times[k]
        health["samples_accepted"] += 1
        accepted[k] = True
        any_non_finite = False
        for c, cc in enumerate(config.channels):
            x = v[k, c]
            if not math.isfinite(x):
                any_non_finite = True
                health["non_finite_values"] += 1
                good[k, c] = False
                continue
            run[c] = run[c] + 1 if last_raw[c] is not None and x == last_raw[c] else 1
            last_raw[c] = x
            if abs(x) >= cc.saturation:
                health["saturated_values"] += 1
                f |= FLAG_SATURATED
                good[k, c] = False
            if cc.stuck_samples and run[c] >= cc.stuck_samples:
                health["stuck_values"] += 1
                f |= FLAG_STUCK
                good[k, c] = False
        if any_non_finite:
            health["non_finite_samples"] += 1
            f |= FLAG_NON_FINITE
        flags[k] = f

    # Pass 2: the filters over each channel's accepted series.
    out = np.full((n, CHANNELS), np.nan)
    for c, cc in enumerate(config.channels):
        out[accepted, c] = _channel_filter(v[accepted, c], cc, good[accepted, c], wavelet)
    # The reference Kalman filter has no "rejected update" path: with finite inputs and a
    # valid model its updates are finite, so filter faults stay 0 (flag kept for symmetry).
    assert not np.any(flags & FLAG_FILTER_FAULT)
    return ImuResult(values=out, flags=flags, health=health)
