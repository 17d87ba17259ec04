"""The processor configuration file (issue 12): one file read by the Python reader, the C++
loop (`gyrodrift-loop --config`), the Python ImuProcessor and the numpy reference processor.

Round trip: a configuration with a different chain on every channel is written, read back by
Python (equal) and by the loop, and the loop's outputs over a record with faults equal the
Python float32 ImuProcessor's (same C++ code: bit-identical) and the double reference within
float tolerance. Every malformed configuration is refused by both readers with the key named.
Expected values come from the reference processor or from the fault put in, never from the code
under test.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.codecs.wire import decode_stream, encode_frames, make_samples
from gyrodrift.imu.config import (
    Ar2KalmanStage,
    BiasRemoval,
    ChannelConfig,
    ConfigError,
    PassThrough,
    ProcessorConfig,
    Timing,
    WaveletStage,
    default_config,
    dumps_config,
    load_config,
    parse_config,
    write_config,
)
from gyrodrift.imu.contract import FLAG_REJECTED
from gyrodrift.imu.processor import ImuConfig, ImuProcessor
from gyrodrift.reference.imu import process_imu
from test_loop_program import Loop, loop_bin  # noqa: F401 (fixture)

MODEL = {"a1": 0.6868, "a2": -0.0213, "q": 1e-6, "r": 4e-6}  # paper 002 model, rad/s units


def mixed_config() -> ProcessorConfig:
    """A different chain on every channel (both wavelets, all modes, both Kalman forms)."""
    ar = Ar2KalmanStage(mean=0.002, sigma2=1e-6, **MODEL)
    chans = (
        ChannelConfig("gx", (WaveletStage("db4", 256, 5, "forced"),
                             Ar2KalmanStage(mean=0.002, steady_state=True, **MODEL)),
                      saturation=8.0, stuck_samples=20),
        ChannelConfig("gy", (WaveletStage("db8", 256, 4, "soft"), ar), saturation=8.0),
        ChannelConfig("gz", (ar, BiasRemoval(0.001)), saturation=8.0),
        ChannelConfig("ax", (BiasRemoval(0.05),), saturation=160.0),
        ChannelConfig("ay", (PassThrough(),)),
        ChannelConfig("az", (WaveletStage("db4", 256, 3, "hard"),), saturation=160.0),
    )
    return ProcessorConfig(channels=chans, timing=Timing(400.0, 1250, 1000.0),
                           meta=(("written_by", "test_config_file"),))


def record(n: int = 700) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """seq, t_us, values (float32-exact) with faults: NaN, Inf, saturation, a stuck run, a
    duplicate and a gap."""
    rng = np.random.default_rng(12)
    t = np.arange(n) / 400.0
    gyro = 0.002 + np.cumsum(rng.normal(0, 2e-4, (n, 3)), 0) * 0.05 + rng.normal(0, 1e-3, (n, 3))
    accel = np.array([0.05, -0.1, 9.81]) + rng.normal(0, 0.01, (n, 3))
    s = make_samples(t, gyro, accel)
    v = s.channels.astype(np.float32).copy()
    v[300, 0] = np.nan
    v[320, 1] = np.inf
    v[340, 2] = 50.0  # saturated (8 rad/s)
    v[360:390, 0] = v[360, 0]  # stuck: 20th identical value on
    v[400, 3] = 500.0  # saturated accel
    seq = s.seq.astype(np.int64)
    t_us = s.t_us.astype(np.int64)
    keep = np.ones(n, bool)
    keep[450:453] = False  # a gap of 3 samples
    seq, t_us, v = seq[keep], t_us[keep], v[keep]
    dup = 500
    seq = np.insert(seq, dup, seq[dup - 1])  # a duplicate (rejected)
    t_us = np.insert(t_us, dup, t_us[dup - 1])
    v = np.insert(v, dup, v[dup - 1], axis=0)
    return seq, t_us, v


def test_python_round_trip_is_identity(tmp_path: Path) -> None:
    for cfg in (default_config(), mixed_config()):
        path = write_config(cfg, tmp_path / "c.toml")
        assert load_config(path) == cfg
        assert parse_config(dumps_config(cfg)) == cfg


def run_loop(binary: Path, cfg_path: Path | None, seq: np.ndarray, t_us: np.ndarray,
             v: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    """The record through the loop with the configuration file (None: without --config, the
    loop's built-in default configuration)."""
    s = make_samples(np.zeros(len(seq)), np.zeros((len(seq), 3)), np.zeros((len(seq), 3)))
    s.seq[:] = seq.astype(np.uint16)
    s.t_us[:] = t_us.astype(np.uint64)
    s.channels[:] = v
    data = encode_frames(s).tobytes()
    config = [] if cfg_path is None else ["--config", str(cfg_path)]
    loop = Loop(binary, "--serial", *config, "--no-rt")
    loop.write(data)
    got = loop.read_until(42 * (len(seq) - 1), timeout_s=10.0)
    stats = loop.finish()
    dec = decode_stream(got)
    return dec.samples.channels.astype(np.float64), dec.samples.seq, stats


def test_loop_reads_the_same_file_and_matches_python_and_reference(
        loop_bin: Path, tmp_path: Path) -> None:  # noqa: F811
    cfg = mixed_config()
    path = write_config(cfg, tmp_path / "mixed.toml")
    seq, t_us, v = record()
    out, out_seq, stats = run_loop(loop_bin, path, seq, t_us, v)
    # The Python float32 processor: the same C++ code with the same float32 parameters.
    py = ImuProcessor(ImuConfig.from_processor_config(path, float32=True), dtype=np.float32)
    res = py.process(seq, t_us, v)
    acc = (res.flags & FLAG_REJECTED) == 0
    assert stats["frames_in"] == len(seq)
    assert stats["frames_out"] == acc.sum() == len(seq) - 1  # one duplicate rejected
    np.testing.assert_array_equal(out_seq, seq[acc].astype(np.uint16))
    np.testing.assert_array_equal(out, res.values[acc].astype(np.float32).astype(np.float64))
    # The double reference on the float32-rounded configuration, within float tolerance.
    ref = process_imu(seq, t_us, v, ImuConfig.from_processor_config(path, float32=True))
    scale = np.nanmax(np.abs(ref.values[acc]), axis=0)
    err = np.nanmax(np.abs(out - ref.values[acc]), axis=0)
    assert np.all(err <= 1e-5 * np.maximum(scale, 1.0)), (err, scale)
    # The health the loop reports is the reference's.
    for k in ("samples_accepted", "seq_gaps", "missing_samples", "non_finite_values",
              "saturated_values", "stuck_values", "duplicates"):
        assert stats["health"][k] == ref.health[k], k
    assert ref.health["stuck_values"] > 0 and ref.health["saturated_values"] == 2


def test_loop_without_config_runs_the_shipped_default(loop_bin: Path,  # noqa: F811
                                                     tmp_path: Path) -> None:
    """Without --config the loop runs its built-in default configuration (the generated
    config_schema.hpp's text, through the same reader): the same outputs as --config with the
    file `gyrodrift config write-default` writes, and as the Python float32 processor."""
    path = write_config(default_config(), tmp_path / "default.toml")
    seq, t_us, v = record()
    out, out_seq, stats = run_loop(loop_bin, None, seq, t_us, v)
    out_file, out_seq_file, stats_file = run_loop(loop_bin, path, seq, t_us, v)
    np.testing.assert_array_equal(out, out_file)
    np.testing.assert_array_equal(out_seq, out_seq_file)
    assert stats["health"] == stats_file["health"]
    assert stats["config"] == "built-in default configuration"
    assert stats_file["config"] == str(path)
    timing = default_config().timing
    assert stats["sample_rate_hz"] == timing.sample_rate_hz
    assert stats["loop_rate_hz"] == timing.loop_hz
    py = ImuProcessor(ImuConfig.from_processor_config(default_config(), float32=True),
                      dtype=np.float32)
    res = py.process(seq, t_us, v)
    acc = (res.flags & FLAG_REJECTED) == 0
    np.testing.assert_array_equal(out, res.values[acc].astype(np.float32).astype(np.float64))
    # the default's saturation limits (8 rad/s, 160 m/s^2) caught the two values put in
    assert stats["health"]["saturated_values"] == res.health["saturated_values"] == 2


def test_check_config_gives_the_loop_readers_verdict(loop_bin: Path,  # noqa: F811
                                                     tmp_path: Path) -> None:
    """`gyrodrift-loop --check-config FILE`: "FILE: ok" and exit 0, or the one-line error
    naming the key and exit 2, without a device."""
    good = write_config(mixed_config(), tmp_path / "mixed.toml")
    r = subprocess.run([str(loop_bin), "--check-config", str(good)], capture_output=True,
                       text=True, timeout=10)
    assert (r.returncode, r.stdout, r.stderr) == (0, f"{good}: ok\n", "")
    bad = tmp_path / "bad.toml"
    bad.write_text(good.read_text().replace("stuck_samples = 20", "stuck_samples = -1"))
    r = subprocess.run([str(loop_bin), "--check-config", str(bad)], capture_output=True,
                       text=True, timeout=10)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == (f"gyrodrift-loop: error: {bad}: channels.gx.stuck_samples: expected "
                        "0..4294967295, got -1\n")


# (description, transformation of the canonical default text, key the error must name)
def _sub(old: str, new: str, count: int = 1) -> Callable[[str], str]:
    def f(text: str) -> str:
        assert old in text, old
        return text.replace(old, new, count)
    return f


BAD = [
    ("unknown key", _sub("sample_rate_hz", "sample_rte_hz = 400.0\nsample_rate_hz"),
     "timing.sample_rte_hz"),
    ("unknown stage key", _sub("threshold = \"forced\"", "threshold = \"forced\"\nlevels = 4"),
     "channels.gx.stages[0].levels"),
    ("missing value", _sub("level = 5\n", ""), "channels.gx.stages[0].level"),
    ("missing channel", lambda t: t[: t.index("[channels.az]")], "channels.az"),
    ("wrong units (accel key on a gyro)", _sub("saturation_rad_s", "saturation_m_s2"),
     "channels.gx.saturation_m_s2"),
    ("wrong units (deg/h)", _sub("mean_rad_s", "mean_deg_h"), "channels.gx.stages[1].mean_deg_h"),
    ("wrong units (gyro key on an accel)", _sub("bias_m_s2", "bias_rad_s"),
     "channels.ax.stages[0].bias_rad_s"),
    ("non-stationary model", _sub("a1 = 1.0", "a1 = 1.3"), "channels.gx.stages[1].a1"),
    ("non-stationary a2", _sub("a2 = -0.25", "a2 = -1.0"), "channels.gx.stages[1].a1"),
    ("negative q", _sub("q = 1e-10", "q = -1e-10"), "channels.gx.stages[1].q"),
    ("zero r", _sub("r = 1e-08", "r = 0.0"), "channels.gx.stages[1].r"),
    ("bad wavelet", _sub("db4", "db6"), "channels.gx.stages[0].wavelet"),
    ("level too deep", _sub("level = 5", "level = 9"), "channels.gx.stages[0].level"),
    ("bad threshold", _sub("\"forced\"", "\"medium\""), "channels.gx.stages[0].threshold"),
    ("bad stage type", _sub("\"bias_removal\"", "\"bias\""), "channels.ax.stages[0].type"),
    ("three stages", _sub("[[channels.ax.stages]]",
                          "[[channels.ax.stages]]\ntype = \"pass_through\"\n\n"
                          "[[channels.ax.stages]]\ntype = \"pass_through\"\n\n"
                          "[[channels.ax.stages]]"), "channels.ax.stages"),
    ("negative saturation", _sub("saturation_m_s2 = 160.0", "saturation_m_s2 = -1.0"),
     "channels.ax.saturation_m_s2"),
    ("wrong type", _sub("stuck_samples = 50", "stuck_samples = \"many\""),
     "channels.gx.stuck_samples"),
    ("bad version", _sub("version = 1", "version = 2"), "version"),
    ("bad schema", _sub("\"gyrodrift.processor\"", "\"other\""), "schema"),
    ("missing rate", _sub("sample_rate_hz = 400.0\n", ""), "timing.sample_rate_hz"),
]


@pytest.mark.parametrize("name,edit,key", BAD, ids=[b[0] for b in BAD])
def test_malformed_configuration_names_the_key(
        name: str, edit: Callable[[str], str], key: str, loop_bin: Path,  # noqa: F811
        tmp_path: Path) -> None:
    text = edit(dumps_config(default_config()))
    with pytest.raises(ConfigError) as info:
        parse_config(text)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(key + ":"), (name, msg)
    # The loop's reader refuses the same file, naming the same key, in one line, exit 2.
    path = tmp_path / "bad.toml"
    path.write_text(text)
    r = subprocess.run([str(loop_bin), "--serial", "fd:0", "--config", str(path)],
                       capture_output=True, timeout=10)
    err = r.stderr.decode().strip()
    assert r.returncode == 2, (name, err)
    assert err.count("\n") == 0 and f"{path}: {key}:" in err, (name, err)


def test_cli_config_commands(tmp_path: Path) -> None:
    from gyrodrift.cli import main

    out = tmp_path / "d.toml"
    assert main(["config", "write-default", "-o", str(out)]) == 0
    assert load_config(out) == default_config()
    assert main(["config", "validate", str(out)]) == 0
    bad = tmp_path / "bad.toml"
    bad.write_text(out.read_text().replace("a1 = 1.0", "a1 = 1.3", 1))
    assert main(["config", "validate", str(bad)]) == 2
    hpp = tmp_path / "c.hpp"
    assert main(["config", str(out), "--emit-cpp", str(hpp)]) == 0
    text = hpp.read_text()
    assert "kImuConfig" in text and "kTaps_db4_n256_j5[256]" in text
    assert main(["config", "emit-cpp", str(out), "-o", str(tmp_path / "no" / "c.hpp")]) == 2


def test_emitted_taps_are_the_forced_fir_of_the_reference() -> None:
    """The flash taps (oldest first, as FirPrefilter takes them) equal the reference forced FIR
    (PyWavelets, per unit window; newest first) reversed, in float32."""
    from gyrodrift.imu.firmware_header import emit_cpp
    from gyrodrift.reference.wavelet import forced_fir_taps

    text = emit_cpp(default_config())
    body = text[text.index("kTaps_db4_n256_j5[256] = {") :].split("};")[0]
    taps = np.array([float(x.rstrip("f")) for x in body.split("{")[1].replace("\n", " ")
                     .split(",") if x.strip()])
    ref = forced_fir_taps("db4", 256, 5)[::-1]
    assert taps.size == 256
    np.testing.assert_allclose(taps, ref, rtol=0, atol=1e-7 * np.abs(ref).max())
    assert math.isclose(taps.sum(), 1.0, rel_tol=1e-5)


@pytest.mark.parametrize("identifier", ["lag", "recursive"])
def test_emitted_monitor_header_builds_the_configured_identifier(identifier: str,
                                                                  tmp_path: Path) -> None:
    """emit-cpp with the monitor's re-identification on three gyros: the processor type holds
    the identifier the file names, the settings carry it with fit_delay_s in samples (15 s
    at 400 Hz: 6000) and restart_after_fit; the header compiles on the host with the
    firmware's flags and the processor accepts the settings (start_monitor: three gyros x
    6000 samples within the 60 s x 400 Hz cadence)."""
    import shutil

    from gyrodrift.imu.firmware_header import emit_cpp

    cfg = default_config()
    for ch in ("gx", "gy", "gz"):
        st = Ar2KalmanStage(mean=0.0, steady_state=True, **MODEL)
        cfg = cfg.with_channel(ch, ChannelConfig(ch, (st,), saturation=8.0))
    cfg = cfg.with_monitor(enabled=True, reidentify=True, identifier=identifier,
                           fit_delay_s=15.0, retune_s=60.0, restart_after_fit=True)
    text = emit_cpp(cfg)
    shared = {"lag": "LagDriftIdentifier", "recursive": "SharedDriftIdentifier"}[identifier]
    assert f"using MonitorIdentifier = gyrodrift::{shared}<float, kMonitorSlots>;" in text
    assert f"  s.identifier = gyrodrift::DriftIdentifierKind::{identifier};" in text
    assert "  s.lag.fit_delay_samples = 6000U;" in text
    assert "  s.lag.restart_after_fit = true;" in text
    (tmp_path / "imu_config.hpp").write_text(text)
    (tmp_path / "main.cpp").write_text(
        '#include "imu_config.hpp"\n'
        "namespace c = gyrodrift_config;\n"
        f"static_assert(c::Processor::kMonitorIdentifierKind == "
        f"gyrodrift::DriftIdentifierKind::{identifier});\n"
        "static c::Processor processor(c::kImuConfig, c::make_wavelet);\n"
        "int main() {\n"
        "  if (!c::start_monitor(processor)) return 1;\n"
        "  processor.defer_monitor_fits(true);  // what an image does with the lag one\n"
        "  return processor.monitor_fit_pending() ? 2 : 0;\n"
        "}\n")
    cxx = shutil.which("g++")
    assert cxx is not None, "host g++ not found"
    root = Path(__file__).resolve().parents[1]
    build = subprocess.run(
        [cxx, "-std=c++17", "-O0", "-fno-exceptions", "-fno-rtti", "-Wall", "-Wextra",
         "-Wpedantic", "-Wconversion", "-Werror", "-isystem", "/usr/include/eigen3", "-I",
         str(root / "include"), "main.cpp", "-o", "main"], cwd=tmp_path, capture_output=True,
        text=True, timeout=120)
    assert build.returncode == 0, build.stderr[-3000:]
    run = subprocess.run([str(tmp_path / "main")], capture_output=True, timeout=30)
    assert run.returncode == 0


def test_committed_cortex_m_header_is_generated(tmp_path: Path) -> None:
    """cpp/cortex_m/generated/gyrodrift_budget_config.hpp is what emit-cpp writes from
    cpp/cortex_m/budget_config.toml (regenerate it after changing the file or the generator)."""
    from gyrodrift.imu.firmware_header import emit_cpp

    root = Path(__file__).resolve().parents[1] / "cpp" / "cortex_m"
    cfg = load_config(root / "budget_config.toml")
    want = emit_cpp(cfg, "budget_config", source="budget_config.toml")
    assert (root / "generated" / "gyrodrift_budget_config.hpp").read_text() == want


def test_replay_with_config_passes(tmp_path: Path) -> None:
    """`gyrodrift replay --config` gives the file to the loop (--config) and the reference."""
    import json as _json

    from gyrodrift.cli import main

    path = write_config(default_config(), tmp_path / "d.toml")
    out = tmp_path / "rep"
    code = main(["replay", "--config", str(path), "--fast", "--no-rt", "--duration-s", "1.5",
                 "--fault-drop", "0.02", "--fault-duplicate", "0.02", "--out-dir", str(out)])
    report = _json.loads((out / "report.json").read_text())
    assert code == 0, report.get("checks")
    assert report["processor"]["config"]["channels"]["gx"]["stages"][0]["type"] == "wavelet"
    bad = tmp_path / "r.toml"
    bad.write_text(path.read_text().replace("sample_rate_hz = 400.0", "sample_rate_hz = 100.0"))
    assert main(["replay", "--config", str(bad), "--rate-hz", "400", "--fast",
                 "--out-dir", str(out)]) == 2  # contradicting rates: refused


def test_real_record_chain_from_a_fitted_configuration(cpp_build_dir: Path) -> None:
    """The real laser-gyro record (30 s at 100 Hz): an AR(2) model fitted per gyro axis goes
    into a configuration file (wavelet db4 N=256 J=5 forced -> steady-state AR(2)-Kalman on
    the gyros, bias removal on the accelerometers), which the loop (replay over a pty) and the
    reference both run; they agree within 1e-5 and the chain reduces the gyro noise."""
    import gyrodrift
    from conftest import SHARED_DATA, skip_unless_ci
    from gyrodrift.replay.harness import LOOP_RELATIVE, ReplayOptions, run_replay

    path = SHARED_DATA / "lasergyro.imu"
    if not path.exists():
        skip_unless_ci(f"real record not present at {path}")
    with path.open() as f:
        lines = [ln for ln in f if ln.strip() and not ln.startswith("%")]
    counts = np.loadtxt(lines[3:3003])
    arcsec = np.pi / 180 / 3600
    gyro = counts[:, :3] * 0.1 * arcsec / 0.01
    accel = counts[:, 3:] * 125e-6 * 9.780327 / 0.01
    chans = []
    for c, name in enumerate(("gx", "gy", "gz")):
        m = gyrodrift.fit_ar2(gyro[:, c])
        chans.append(ChannelConfig(name, (
            WaveletStage("db4", 256, 5, "forced"),
            Ar2KalmanStage(a1=m.a1, a2=m.a2, mean=m.mean, q=m.sigma2,
                           r=m.measurement_variance, sigma2=m.sigma2, steady_state=True))))
    chans += [ChannelConfig(n, (BiasRemoval(0.0),)) for n in ("ax", "ay", "az")]
    cfg = ProcessorConfig(channels=tuple(chans), timing=Timing(100.0))
    samples = make_samples(np.arange(len(counts)) * 0.01, gyro, accel)
    res = run_replay(samples, ReplayOptions(
        transport="serial", speed=0.0, loop_binary=str(cpp_build_dir / LOOP_RELATIVE),
        processor=cfg.with_timing(loop_rate_hz=1000.0)))
    rep = res.report
    assert rep["ok"], ({k: v for k, v in rep["checks"].items() if not v}, rep["comparison"])
    assert max(rep["comparison"]["max_abs_error"]) <= 1e-5
    out = process_imu(samples.seq.astype(np.int64), samples.t_us.astype(np.int64),
                      samples.channels.astype(np.float64),
                      ImuConfig.from_processor_config(cfg, float32=True))
    raw_std = samples.channels[256:, :3].astype(np.float64).std(axis=0)
    filt_std = out.values[256:, :3].std(axis=0)
    # measured: 1.61e-3 -> 1.10e-3, 2.75e-3 -> 2.15e-3, 1.24e-3 -> 0.63e-3 rad/s (a disturbed
    # vehicle record: part of the variance is motion, which the filters must keep)
    assert np.all(filt_std < 0.85 * raw_std), (raw_std, filt_std)
    print(f"\nreal record, gyro std rad/s raw {raw_std} -> chain {filt_std}")


def test_fit_output_is_read_by_both_readers(loop_bin: Path, tmp_path: Path) -> None:  # noqa: F811
    """`gyrodrift fit -o x.toml` writes the format by its own hand-written text: both readers
    accept it, and the loop runs the fitted model as the Python processor does."""
    from gyrodrift.cli import main
    from scipy.signal import lfilter

    rng = np.random.default_rng(3)
    drift = lfilter([1.0], [1.0, -0.6868, 0.0213], rng.normal(0, 0.5, 3000))
    rec = tmp_path / "drift.npy"
    np.save(rec, 9.7 + drift + rng.normal(0, 0.3, 3000))
    path = tmp_path / "fit.toml"
    assert main(["fit", str(rec), "--rate-hz", "100", "--gyro-units", "deg/h", "-o",
                 str(path)]) == 0
    cfg = load_config(path)
    assert [c.stages[0].type for c in cfg.channels] == ["ar2_kalman"] + ["pass_through"] * 5
    assert parse_config(dumps_config(cfg)) == cfg
    seq, t_us, v = record()
    out, _, stats = run_loop(loop_bin, path, seq, t_us, v)
    res = ImuProcessor(ImuConfig.from_processor_config(path, float32=True),
                       dtype=np.float32).process(seq, t_us, v)
    acc = (res.flags & FLAG_REJECTED) == 0
    assert stats["frames_out"] == acc.sum()
    np.testing.assert_array_equal(out, res.values[acc].astype(np.float64))
    assert np.nanmax(np.abs(out[:, 0] - v[acc][:, 0])) > 1e-5  # the Kalman stage ran on gx


def test_config_show_json_round_trips_an_unlimited_value(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]
                                                          ) -> None:
    # JSON has no infinity: `config show --json` writes saturation_rad_s = inf as null, and
    # config_from_dict refused that document ("expected a number, got None")
    from gyrodrift.cli import main as cli_main
    from gyrodrift.imu.config import config_from_dict, default_config, dumps_config

    text = re.sub(r"(?m)^saturation_rad_s = .*$", "saturation_rad_s = inf",
                  dumps_config(default_config()))
    path = tmp_path / "c.toml"
    path.write_text(text)
    assert cli_main(["config", "show", str(path), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["channels"]["gx"]["saturation_rad_s"] is None
    cfg = config_from_dict(doc)
    assert math.isinf(cfg.channel("gx").saturation)
    assert dumps_config(cfg) == text
