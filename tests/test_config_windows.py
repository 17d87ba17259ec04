"""Every wavelet window the configuration format allows (issue 12): a power of two in 16..4096,
in the loop program (a real process, `--config`) and in the binding (Python ImuProcessor, float32
and float64), alone and in the chain wavelet -> AR(2)-Kalman, for db4 and db8 and the forced,
soft and hard thresholds, at the deepest level each window allows.

Expected values come from the numpy/PyWavelets reference processor (gyrodrift.reference.imu),
never from the code under test. Tolerances: float32 C++ vs the double reference 1e-5 of the
channel's scale (float rounding over a window of up to 4096 taps and the Kalman recursion:
<= 5e-7 observed); float64 C++ vs the reference 1e-12 relative (lifting vs pywt convolution,
~1e-15 observed); the loop and the Python float32 processor run the same C++ code with the same
float32 parameters, so they are compared bit for bit.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest
from gyrodrift import _core
from gyrodrift.codecs.wire import make_samples
from gyrodrift.imu.config import (
    Ar2KalmanStage,
    BiasRemoval,
    ChannelConfig,
    ConfigError,
    ProcessorConfig,
    Timing,
    WaveletStage,
    dumps_config,
    load_config,
    max_wavelet_level,
    parse_config,
    write_config,
)
from gyrodrift.imu.contract import FLAG_REJECTED
from gyrodrift.imu.processor import ImuChannelConfig, ImuConfig, ImuProcessor, WaveletSettings
from gyrodrift.reference.imu import process_imu
from test_config_file import MODEL, run_loop
from test_loop_program import loop_bin  # noqa: F401 (fixture)

WINDOWS = (16, 64, 512, 4096)
AFTER = 160  # samples after the window has filled (every output there is filtered)


def window_config(n: int) -> ProcessorConfig:
    """Window n on four channels: both wavelets, all thresholds, the deepest level allowed
    (and one level less), two of them chained into an AR(2)-Kalman."""
    j4, j8 = max_wavelet_level(n, "db4"), max_wavelet_level(n, "db8")
    chans = (
        ChannelConfig("gx", (WaveletStage("db4", n, j4, "forced"),
                             Ar2KalmanStage(mean=0.002, steady_state=True, **MODEL)),
                      saturation=8.0, stuck_samples=20),
        ChannelConfig("gy", (WaveletStage("db8", n, j8, "soft"),
                             Ar2KalmanStage(mean=0.002, sigma2=1e-6, **MODEL)), saturation=8.0),
        ChannelConfig("gz", (WaveletStage("db8", n, max(1, j8 - 1), "forced"),), saturation=8.0),
        ChannelConfig("ax", (WaveletStage("db4", n, max(1, j4 - 1), "soft"),), saturation=160.0),
        ChannelConfig("ay", (BiasRemoval(0.05),)),
        ChannelConfig("az", (WaveletStage("db4", n, j4, "hard"),), saturation=160.0),
    )
    return ProcessorConfig(channels=chans, timing=Timing(400.0, 1250, 1000.0),
                           meta=(("written_by", "test_config_windows"),))


def window_record(window: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """seq, t_us, float32-exact values, window + AFTER samples, with faults after the window
    has filled: NaN, Inf, saturation, a stuck run, a gap and a duplicate."""
    n = window + AFTER
    rng = np.random.default_rng(window)
    t = np.arange(n) / 400.0
    gyro = 0.002 + np.cumsum(rng.normal(0, 2e-4, (n, 3)), 0) * 0.05 + rng.normal(0, 1e-3, (n, 3))
    accel = np.array([0.05, -0.1, 9.81]) + rng.normal(0, 0.01, (n, 3))
    s = make_samples(t, gyro, accel)
    v = s.channels.astype(np.float32).copy()
    w = window
    v[w + 10, 0] = np.nan
    v[w + 15, 3] = np.inf
    v[w + 20, 2] = 50.0  # saturated (8 rad/s)
    v[w + 30:w + 60, 0] = v[w + 30, 0]  # stuck: the 20th identical value on
    v[w + 40, 5] = 500.0  # saturated accel
    seq = s.seq.astype(np.int64)
    t_us = s.t_us.astype(np.int64)
    keep = np.ones(n, bool)
    keep[w + 70:w + 73] = False  # a gap of 3 samples
    seq, t_us, v = seq[keep], t_us[keep], v[keep]
    dup = w + 100
    seq = np.insert(seq, dup, seq[dup - 1])  # a duplicate (rejected)
    t_us = np.insert(t_us, dup, t_us[dup - 1])
    v = np.insert(v, dup, v[dup - 1], axis=0)
    return seq, t_us, v


def rel_err(got: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Per-channel max |got - ref| relative to the channel's max |ref| (NaN rows must agree)."""
    assert np.array_equal(np.isnan(got), np.isnan(ref))
    ok = ~np.isnan(ref)
    err = np.where(ok, np.abs(got - ref), 0.0).max(axis=0)
    return err / np.where(ok, np.abs(ref), 0.0).max(axis=0)


@pytest.mark.parametrize("window", WINDOWS)
def test_loop_and_binding_run_every_window(window: int, loop_bin: Path,  # noqa: F811
                                           tmp_path: Path) -> None:
    cfg = window_config(window)
    path = write_config(cfg, tmp_path / f"w{window}.toml")
    assert load_config(path) == cfg  # the round trip of a non-256 window
    seq, t_us, v = window_record(window)
    ref32 = process_imu(seq, t_us, v, ImuConfig.from_processor_config(path, float32=True))
    acc = (ref32.flags & FLAG_REJECTED) == 0
    assert acc.sum() == len(seq) - 1  # the duplicate
    assert ref32.health["stuck_values"] > 0 and ref32.health["saturated_values"] == 2

    # The loop (a real process reading the file) ...
    out, out_seq, stats = run_loop(loop_bin, path, seq, t_us, v)
    assert stats["frames_out"] == acc.sum()
    np.testing.assert_array_equal(out_seq, seq[acc].astype(np.uint16))
    err = rel_err(out, ref32.values[acc])
    assert np.all(err <= 1e-5), err
    for k in ("samples_accepted", "seq_gaps", "missing_samples", "non_finite_values",
              "saturated_values", "stuck_values", "duplicates", "filter_faults"):
        assert stats["health"][k] == ref32.health[k], k
    # ... equals the binding's float32 processor (same C++ code, same float32 parameters).
    py32 = ImuProcessor(ImuConfig.from_processor_config(path, float32=True), dtype=np.float32)
    got32 = py32.process(seq, t_us, v)
    np.testing.assert_array_equal(out, got32.values[acc].astype(np.float64))
    assert got32.health == ref32.health

    # The float64 binding against the double reference on the file's own values.
    ref64 = process_imu(seq, t_us, v, path)
    got64 = ImuProcessor(path).process(seq, t_us, v)
    assert rel_err(got64.values, ref64.values).max() <= 1e-12
    assert got64.health == ref64.health
    # The filters really ran: filtered outputs differ from the inputs after the window filled.
    tail = slice(-AFTER // 2, None)
    for c in (0, 1, 2, 3, 5):
        assert np.nanmax(np.abs(got64.values[tail, c] - v[tail, c])) > 1e-5, c


# (window, level, wavelet, the message both readers give after the key)
BAD_WINDOWS = [
    (100, 3, "db4", "expected a power of two in 16..4096, got 100"),
    (8, 1, "db4", "expected a power of two in 16..4096, got 8"),
    (8192, 5, "db4", "expected a power of two in 16..4096, got 8192"),
    (0, 1, "db4", "expected a power of two in 16..4096, got 0"),
    (-256, 5, "db4", "expected a power of two in 16..4096, got -256"),
]
BAD_LEVELS = [
    (16, 3, "db4", "expected 1..2 for db4 with window 16, got 3"),
    (16, 2, "db8", "expected 1..1 for db8 with window 16, got 2"),
    (512, 8, "db4", "expected 1..7 for db4 with window 512, got 8"),
    (4096, 9, "db8", "expected 1..8 for db8 with window 4096, got 9"),
]


@pytest.mark.parametrize("window,level,wavelet,message", BAD_WINDOWS + BAD_LEVELS)
def test_window_and_level_errors_name_the_key_in_both_readers(
        window: int, level: int, wavelet: str, message: str, loop_bin: Path,  # noqa: F811
        tmp_path: Path) -> None:
    good = window_config(64)
    text = dumps_config(good).replace(
        f'wavelet = "db4"\nwindow = 64\nlevel = {max_wavelet_level(64, "db4")}\n',
        f'wavelet = "{wavelet}"\nwindow = {window}\nlevel = {level}\n', 1)
    assert text != dumps_config(good)
    key = "channels.gx.stages[0].level" if (window, level, wavelet, message) in BAD_LEVELS \
        else "channels.gx.stages[0].window"
    with pytest.raises(ConfigError) as info:
        parse_config(text)
    assert str(info.value) == f"{key}: {message}"
    path = tmp_path / "bad.toml"
    path.write_text(text)
    r = subprocess.run([str(loop_bin), "--serial", "fd:0", "--config", str(path)],
                       capture_output=True, timeout=10)
    err = r.stderr.decode()
    assert r.returncode == 2, err
    assert err == f"gyrodrift-loop: error: {path}: {key}: {message}\n"


def test_binding_window_argument_and_errors() -> None:
    """The low-level binding takes the window per channel (_core.ImuWaveletSettings); a window
    outside the format or a level too deep for it is a one-line ValueError naming the field."""
    wav = [ImuChannelConfig(filter="wavelet")] * 6
    ws = WaveletSettings("db8", 32, 1, "soft")
    p = ImuProcessor(ImuConfig(channels=list(wav)), wavelet=ws)
    n = 40
    x = np.random.default_rng(5).normal(size=(n, 1)) * np.ones((1, 6))
    got = p.process(np.arange(n), np.arange(n) * 2500, x)
    ref = process_imu(np.arange(n), np.arange(n) * 2500, x, ImuConfig(channels=list(wav)),
                      wavelet=ws)
    assert rel_err(got.values, ref.values).max() <= 1e-12
    assert np.abs(got.values[31:] - x[31:]).min() > 1e-3  # filtered from sample 32 on
    for bad, match in ((WaveletSettings("db8", 48, 1, "soft"),
                        r"^channels\[0\]\.wavelet\.window: expected a power of two in 16\.\.4096, "
                        r"got 48$"),
                       (WaveletSettings("db8", 32, 3, "soft"),
                        r"^channels\[0\]\.wavelet\.level: expected 1\.\.2 for db8 with window 32, "
                        r"got 3$")):
        with pytest.raises(ValueError, match=match):
            ImuProcessor(ImuConfig(channels=list(wav)), wavelet=bad)

    def settings(*stages: _core.ImuWaveletSettings | None) -> _core.ImuProcessorSettings:
        chans = [_core.ImuChannelSettings(filter="wavelet", wavelet=w) for w in stages]
        return _core.ImuProcessorSettings(channels=chans)

    soft32 = _core.ImuWaveletSettings(wavelet="db8", window=32, level=1, threshold="soft")
    for cls in (_core.ImuProcessor, _core.ImuProcessorF32):
        assert cls(settings(*[soft32] * 6)).status == "ok"
        with pytest.raises(ValueError, match=r"^window: expected a power of two in 16\.\.4096, "
                                             r"got 48$"):
            _core.ImuWaveletSettings(wavelet="db8", window=48, level=1, threshold="soft")
        with pytest.raises(ValueError, match=r"^level: expected 1\.\.2 for db8 with window 32, "
                                             r"got 3$"):
            _core.ImuWaveletSettings(wavelet="db8", window=32, level=3, threshold="soft")
        # fields are writable: checked again, naming the channel, when the processor is built
        # (nested values are copies: change them and assign them back)
        s = settings(*[soft32] * 6)
        chans, stage = s.channels, _core.ImuWaveletSettings(wavelet="db4", window=16, level=1)
        stage.window = 5000
        chans[2].wavelet = stage
        s.channels = chans
        with pytest.raises(ValueError, match=r"^channels\[2\]\.wavelet\.window: expected a power "
                                             r"of two in 16\.\.4096, got 5000$"):
            cls(s)
        mixed = cls(settings(_core.ImuWaveletSettings(wavelet="db4", window=16, level=2), soft32,
                             _core.ImuWaveletSettings(wavelet="db8", window=4096, level=8,
                                                      threshold="hard"), soft32, soft32, soft32))
        assert mixed.status == "ok"
        # a wavelet channel without a stage: the processor says so, as the C++ one does
        assert cls(settings(soft32, None, soft32, soft32, soft32, soft32)).status == (
            "wavelet unavailable")


def test_pass_through_channels_do_not_need_a_wavelet_window() -> None:
    """Sanity of the chosen instance: a processor whose only wavelet channel uses window 16
    leaves the pass-through channels untouched (bit for bit)."""
    chans = [ImuChannelConfig(filter="wavelet", wavelet=WaveletSettings("db4", 16, 2, "forced"))]
    chans += [ImuChannelConfig() for _ in range(5)]
    cfg = ImuConfig(channels=chans)
    x = np.random.default_rng(1).normal(size=(50, 6))
    got = ImuProcessor(cfg).process(np.arange(50), np.arange(50) * 2500, x)
    np.testing.assert_array_equal(got.values[:, 1:], x[:, 1:])
    ref = process_imu(np.arange(50), np.arange(50) * 2500, x, cfg)
    assert rel_err(got.values, ref.values).max() <= 1e-12

