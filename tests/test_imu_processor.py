"""ImuProcessor (C++, float64 and float32) against the numpy reference gyrodrift.reference.imu,
health counters against hand-counted fault scenarios, determinism, and argument errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import SHARED_DATA, skip_unless_ci
from gyrodrift import _core, fit_ar2, simulate_imu
from gyrodrift.imu.contract import (
    FLAG_CONFIG_ERROR,
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
    describe_flags,
)
from gyrodrift.imu.processor import ImuChannelConfig, ImuConfig, ImuProcessor, WaveletSettings
from gyrodrift.reference.imu import process_imu
from gyrodrift.simulation.records import NoiseTerms

N = 3000
PERIOD_US = 2500


def simulated_record(seed: int = 5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """400 Hz static IMU: gyros with an AR(2) drift (papers 000/002), angle random walk and a
    constant bias; accelerometers with bias and velocity random walk."""
    rec = simulate_imu(
        n=N,
        rate_hz=400.0,
        gyro=NoiseTerms(n_deg_rt_h=0.0005, bias_deg_h=2.0, ar2=(1.6, -0.65, 0.1)),
        accel_bias_m_s2=0.02,
        vrw_m_s_rt_h=0.05,
        seed=seed,
    )
    values = np.column_stack([rec.gyro_rad_s, rec.accel_m_s2])
    seq = np.arange(N) % 65536
    t_us = 1_000_000 + np.arange(N, dtype=np.uint64) * PERIOD_US
    return seq, t_us, values


def config_for(values: np.ndarray) -> ImuConfig:
    """AR(2)-Kalman gyros identified from the record itself (gyrodrift.fit_ar2), a bias-removal
    accelerometer pair and one pass-through accelerometer."""
    models = [fit_ar2(values[:, c]) for c in range(3)]
    channels = [ImuChannelConfig.ar2_kalman(m) for m in models]
    channels += [
        ImuChannelConfig(filter="bias_removal", bias=0.02),
        ImuChannelConfig(filter="bias_removal", bias=0.02),
        ImuChannelConfig(),
    ]
    return ImuConfig(channels=channels, period_us=PERIOD_US, time_tolerance_us=PERIOD_US // 2)


def rel_err(got: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Per-channel max |got - ref| relative to the channel's max |ref| (NaN rows must agree)."""
    assert np.array_equal(np.isnan(got), np.isnan(ref))
    ok = ~np.isnan(ref)
    err = np.where(ok, np.abs(got - ref), 0.0).max(axis=0)
    return err / np.where(ok, np.abs(ref), 0.0).max(axis=0)


def test_double_matches_reference_on_simulated_imu() -> None:
    seq, t_us, values = simulated_record()
    cfg = config_for(values)
    ref = process_imu(seq, t_us, values, cfg)
    got = ImuProcessor(cfg).process(seq, t_us, values)
    # Same recursions in a different operation order (scalar C++ vs numpy matrix products):
    # rounding of a few ulps per step, not amplified by the stable filter -> 1e-12 relative.
    assert rel_err(got.values, ref.values).max() <= 1e-12
    assert np.array_equal(got.flags, ref.flags)
    assert got.health == ref.health
    assert got.health["samples_accepted"] == N


def test_float_matches_reference_on_simulated_imu() -> None:
    seq, t_us, values = simulated_record(6)
    v32 = values.astype(np.float32)
    cfg = config_for(values)
    ref = process_imu(seq, t_us, v32.astype(np.float64), cfg)
    got = ImuProcessor(cfg, dtype=np.float32).process(seq, t_us, v32)
    assert got.values.dtype == np.float32
    # float32 arithmetic (eps 6e-8) through a stable filter: ~1e-7 relative observed;
    # 1e-5 is the project's float tolerance.
    assert rel_err(got.values.astype(np.float64), ref.values).max() <= 1e-5
    assert got.health == ref.health


def test_filters_do_something() -> None:
    """The Kalman channels smooth (lower sample-to-sample spread than the input), the bias
    channels are shifted exactly, the pass-through channel is the input."""
    seq, t_us, values = simulated_record()
    got = ImuProcessor(config_for(values)).process(seq, t_us, values).values
    for c in range(3):
        assert np.std(np.diff(got[500:, c])) < 0.7 * np.std(np.diff(values[500:, c]))
    assert np.array_equal(got[:, 3], values[:, 3] - 0.02)
    assert np.array_equal(got[:, 5], values[:, 5])


def fault_scenario() -> tuple[np.ndarray, np.ndarray, np.ndarray, ImuConfig]:
    """400 frames with one of each fault; the expected counts are worked out by hand below."""
    _, _, clean = simulated_record()
    idx = list(range(450))  # which clean sample each received frame carries
    idx.insert(150, idx[149])  # frame 150 repeats frame 149: duplicate
    del idx[200]  # one sample lost: seq gap of 1 at frame 200
    idx.insert(250, idx[240])  # an old frame arrives late at 250: out of order
    idx = idx[:300]
    seq = [i % 65536 for i in idx] + list(range(100))  # the source restarts at frame 300
    t_us = [1_000_000 + i * PERIOD_US for i in idx] + [
        1_000_000 + k * PERIOD_US for k in range(100)
    ]
    t_us[100] += 2000  # 2 ms off the grid (tolerance 1.25 ms): jumps at 100 and 101
    values = np.vstack([clean[idx], clean[:100]])
    cfg = config_for(clean)
    cfg.channels[3].saturation = 1.0  # accel x saturates at 1 m/s^2
    cfg.channels[4].stuck_samples = 5  # accel y: the 5th identical value in a row is stuck
    values[50, 0] = np.nan  # gyro x NaN
    values[60, 1] = np.inf  # gyro y Inf
    values[60, 2] = -np.inf  # gyro z -Inf (same sample: 1 sample, 2 values)
    values[70, 3] = 5.0  # saturated
    values[80:87, 4] = values[80, 4]  # 7 identical values -> values 84, 85, 86 stuck
    return np.array(seq), np.array(t_us, dtype=np.uint64), values, cfg


def test_every_health_counter_is_triggered_and_counted_exactly() -> None:
    seq, t_us, values, cfg = fault_scenario()
    got = ImuProcessor(cfg).process(seq, t_us, values)
    ref = process_imu(seq, t_us, values, cfg)
    h = got.health
    expected = {
        "samples_in": 400,
        "duplicates": 1,
        "out_of_order": 1 + 7,  # the late frame, then 7 restart frames before the resync
        "config_rejected": 0,
        "seq_gaps": 1,
        "missing_samples": 1,
        "seq_resyncs": 1,
        "time_jumps": 2,  # 100 is late, 101 is early relative to 100
        "non_finite_samples": 2,
        "non_finite_values": 3,
        "saturated_values": 1,
        "stuck_values": 3,
        "filter_faults": 0,
    }
    assert {k: h[k] for k in expected} == expected
    assert h["samples_accepted"] == 400 - 1 - 8
    assert ref.health == h
    assert np.array_equal(ref.flags, got.flags)
    f = got.flags
    assert f[50] == FLAG_NON_FINITE and f[60] == FLAG_NON_FINITE
    assert f[70] == FLAG_SATURATED
    assert [bool(x & FLAG_STUCK) for x in f[80:88]] == [False] * 4 + [True] * 3 + [False]
    assert f[100] & FLAG_TIME_JUMP and f[101] & FLAG_TIME_JUMP
    assert f[150] == FLAG_DUPLICATE | FLAG_REJECTED
    assert f[200] == FLAG_SEQ_GAP
    assert f[250] == FLAG_OUT_OF_ORDER | FLAG_REJECTED
    assert all(x == FLAG_OUT_OF_ORDER | FLAG_REJECTED for x in f[300:307])
    assert f[307] == FLAG_RESYNC
    assert describe_flags(int(f[250])) == ["out_of_order", "rejected"]
    # Rejected rows have no output; everything else is finite (bad values never reach state).
    assert np.isnan(got.values[got.flags & FLAG_REJECTED != 0]).all()
    assert np.isfinite(got.values[got.accepted]).all()
    assert rel_err(got.values, ref.values).max() <= 1e-12


def test_rejected_frames_leave_no_trace() -> None:
    """A duplicate or late frame carrying garbage changes nothing for the other samples."""
    seq, t_us, values = simulated_record()
    cfg = config_for(values)
    clean = ImuProcessor(cfg).process(seq[:200], t_us[:200], values[:200])
    s = np.insert(seq[:200], [100, 150], [seq[99], seq[20]])
    t = np.insert(t_us[:200], [100, 150], [t_us[99], t_us[20]])
    v = np.insert(values[:200], [100, 150], [[1e30] * 6, [np.nan] * 6], axis=0)
    dirty = ImuProcessor(cfg).process(s, t, v)
    keep = np.ones(202, dtype=bool)
    keep[[100, 151]] = False
    assert not dirty.accepted[[100, 151]].any()
    assert np.array_equal(dirty.values[keep], clean.values)  # bit for bit


def test_bad_values_are_predict_only_for_kalman_and_hold_for_pass_through() -> None:
    seq, t_us, values = simulated_record()
    cfg = config_for(values)
    v = values[:300].copy()
    v[100:110, :] = np.nan
    got = ImuProcessor(cfg).process(seq[:300], t_us[:300], v)
    ref = process_imu(seq[:300], t_us[:300], v, cfg)
    assert rel_err(got.values, ref.values).max() <= 1e-12
    # pass-through / bias channels hold their last output over the gap
    assert np.all(got.values[100:110, 5] == got.values[99, 5])
    assert np.all(got.values[100:110, 3] == got.values[99, 3])
    # Kalman channels follow the AR(2) prediction (not constant, finite)
    assert np.isfinite(got.values[100:110, :3]).all()


def test_filter_fault_on_overflowing_float_input() -> None:
    """float32: +-3.4e38 in a row overflows the innovation; the filter rejects the update,
    the processor counts it, and the state stays finite."""
    seq, t_us, values = simulated_record()
    v = values[:200].astype(np.float32)
    v[100, 0] = 3.4e38
    v[101, 0] = -3.4e38
    cfg = config_for(values)
    got = ImuProcessor(cfg, dtype=np.float32).process(seq[:200], t_us[:200], v)
    assert got.health["filter_faults"] >= 1
    assert any(f & FLAG_FILTER_FAULT for f in got.flags[100:102])
    assert np.isfinite(got.values[105:, 0]).all()


def test_deterministic_bit_identical_runs_and_reset() -> None:
    seq, t_us, values, cfg = fault_scenario()
    for dtype in (np.float64, np.float32):
        p1 = ImuProcessor(cfg, dtype=dtype)
        a = p1.process(seq, t_us, values)
        b = ImuProcessor(cfg, dtype=dtype).process(seq, t_us, values)
        p1.reset()
        c = p1.process(seq, t_us, values)
        assert a.values.tobytes() == b.values.tobytes() == c.values.tobytes()
        assert a.flags.tobytes() == b.flags.tobytes() == c.flags.tobytes()
        assert a.health == b.health == c.health


def test_state_carries_across_calls() -> None:
    seq, t_us, values = simulated_record()
    cfg = config_for(values)
    whole = ImuProcessor(cfg).process(seq, t_us, values)
    p = ImuProcessor(cfg)
    parts = [
        p.process(seq[i : i + 700], t_us[i : i + 700], values[i : i + 700])
        for i in range(0, N, 700)
    ]
    assert np.array_equal(np.vstack([r.values for r in parts]), whole.values)


@pytest.mark.parametrize("mode,level", [("forced", 5), ("soft", 4), ("hard", 3)])
def test_wavelet_channels_match_reference(mode: str, level: int) -> None:
    seq, t_us, values = simulated_record()
    n = 700
    cfg = config_for(values)
    for c in (0, 4):
        cfg.channels[c] = ImuChannelConfig(filter="wavelet", bias=0.001 * c)
    v = values[:n].copy()
    v[400, 0] = np.nan
    ws = WaveletSettings(wavelet="db8", window=256, level=level, threshold=mode)
    got = ImuProcessor(cfg, wavelet=ws).process(seq[:n], t_us[:n], v)
    ref = process_imu(seq[:n], t_us[:n], v, cfg, wavelet=ws)
    # lifting transform vs pywt convolution: ~1e-15 observed -> 1e-12 relative.
    assert rel_err(got.values, ref.values).max() <= 1e-12
    assert got.health == ref.health
    got32 = ImuProcessor(cfg, dtype=np.float32, wavelet=ws).process(
        seq[:n], t_us[:n], v.astype(np.float32)
    )
    ref32 = process_imu(seq[:n], t_us[:n], v.astype(np.float32).astype(np.float64), cfg, wavelet=ws)
    assert rel_err(got32.values.astype(np.float64), ref32.values).max() <= 1e-5


def test_argument_and_configuration_errors() -> None:
    seq, t_us, values = simulated_record()
    cfg = config_for(values)
    p = ImuProcessor(cfg)
    with pytest.raises(TypeError):  # wrong dtype is not silently converted by the binding
        p._proc.process(seq[:10].astype(np.uint16), t_us[:10], values[:10].astype(np.float32))
    with pytest.raises(ValueError, match=r"\(n, 6\)"):
        p.process(seq[:10], t_us[:10], values[:10, :5])
    with pytest.raises(ValueError, match="seq and t_us"):
        p.process(seq[:9], t_us[:10], values[:10])
    with pytest.raises(ValueError, match=r"0\.\.65535"):
        p.process(seq[:10] + 70000, t_us[:10], values[:10])
    with pytest.raises(TypeError, match="integer"):
        p.process(seq[:10].astype(float), t_us[:10], values[:10])
    with pytest.raises(ValueError, match=r"^channels\.gx: "):
        ImuProcessor(ImuConfig())  # gyro AR(2) models not supplied
    with pytest.raises(ValueError, match="wavelet"):
        ImuProcessor(ImuConfig(channels=[ImuChannelConfig(filter="wavelet")] * 6))
    bad = config_for(values)
    bad.channels[1].a1, bad.channels[1].a2 = 1.5, 0.6  # non-stationary model
    with pytest.raises(ValueError, match=r"^channels\.gy: "):
        ImuProcessor(bad)
    with pytest.raises(ValueError, match="filter"):
        ImuProcessor(ImuConfig(channels=[ImuChannelConfig(filter="median")] * 6))
    timing = config_for(values)
    timing.period_us = 0
    with pytest.raises(ValueError, match="period_us is 0"):
        ImuProcessor(timing)
    with pytest.raises(TypeError, match="float64 or float32"):
        ImuProcessor(cfg, dtype=np.int32)


def test_unconfigured_cpp_processor_rejects_everything() -> None:
    """Built directly (bypassing the Python check), an invalid configuration rejects every
    sample with FLAG_CONFIG_ERROR instead of passing data through."""
    raw = _core.ImuProcessor(settings=_core.ImuProcessorSettings())  # gyro models unset (NaN)
    assert raw.status == "bad channel config" and raw.bad_channel == 0
    out, flags = raw.process(
        np.arange(5, dtype=np.uint16), np.arange(5, dtype=np.uint64), np.zeros((5, 6))
    )
    assert np.all(flags == FLAG_CONFIG_ERROR | FLAG_REJECTED)
    assert np.isnan(out).all()
    assert raw.health()["config_rejected"] == 5


def read_lasergyro(n: int) -> np.ndarray | None:
    path = SHARED_DATA / "lasergyro.imu"
    if not path.exists():
        return None
    rows: list[list[float]] = []
    header = 0
    with path.open() as f:
        for line in f:
            if line.startswith("%") or not line.strip():
                continue
            header += 1
            if header <= 3:
                continue
            rows.append([float(x) for x in line.split()[:6]])
            if len(rows) == n:
                break
    counts = np.array(rows)
    dt_s = 0.01
    gyro = counts[:, :3] * 0.1 / 3600.0 * math.pi / 180.0 / dt_s  # arcsec/count -> rad/s
    accel = counts[:, 3:] * 125e-6 * 9.780327 / dt_s  # ug*s/count -> m/s^2
    return np.column_stack([gyro, accel])


def test_real_laser_gyro_record_float_matches_reference() -> None:
    values = read_lasergyro(20_000)
    if values is None:
        skip_unless_ci("shared record lasergyro.imu not present (optional real-data case)")
    n = values.shape[0]
    seq = np.arange(n) % 65536
    t_us = np.arange(n, dtype=np.uint64) * 10_000
    cfg = config_for(values)
    cfg.period_us, cfg.time_tolerance_us = 10_000, 5_000
    for c in range(6):
        cfg.channels[c].stuck_samples = 200  # quantised data repeats; 2 s unchanged is stuck
    v32 = values.astype(np.float32)
    got = ImuProcessor(cfg, dtype=np.float32).process(seq, t_us, v32)
    ref = process_imu(seq, t_us, v32.astype(np.float64), cfg)
    assert got.health == ref.health
    assert rel_err(got.values.astype(np.float64), ref.values).max() <= 1e-5


@pytest.mark.parametrize(
    "values",
    [
        np.zeros((4, 6), dtype=np.complex128) + 1j,  # imaginary part was silently dropped
        np.full((4, 6), "0.5"),  # strings were parsed
        np.full((4, 6), b"1"),
        np.full((4, 6), None, dtype=object),
    ],
)
def test_process_refuses_complex_and_string_values(values: np.ndarray) -> None:
    """issue 13: ImuProcessor.process accepted complex and string arrays."""
    cfg = ImuConfig(channels=[ImuChannelConfig() for _ in range(6)])
    seq = np.arange(4)
    t_us = np.arange(4) * 2500
    with pytest.raises(TypeError, match="real numeric"):
        ImuProcessor(cfg).process(seq, t_us, values)
