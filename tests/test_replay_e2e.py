"""End-to-end: the real gyrodrift-loop on a pty, driven by the replay harness over serial and
SLCAN (python-can's slcan interface), at real time and as fast as possible, clean and with
each fault kind. Every run must balance its accounting exactly (every frame sent is an
output, a link rejection or a processor rejection), the loop's own counters must agree, and
every output must equal the reference processor (gyrodrift.reference.imu) run offline on
what the loop received: float32 loop vs float64 reference within 1e-5 absolute (the values
are at most ~10 m/s^2, so float32 rounding is ~1e-6; the gyro Kalman outputs ~1e-3 rad/s).
"""

from __future__ import annotations

import json
import os
import subprocess
import tty
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.codecs.wire import Samples, make_samples
from gyrodrift.imu.config import (
    Ar2KalmanStage,
    ChannelConfig,
    PassThrough,
    ProcessorConfig,
    Timing,
    write_config,
)
from gyrodrift.replay.faults import FAULT_KINDS, FaultSpec, plan_transmission
from gyrodrift.replay.harness import LOOP_RELATIVE, ReplayOptions, ReplayResult, run_replay
from gyrodrift.replay.processor import ProcessorSettings
from gyrodrift.simulation.records import NoiseTerms, simulate_imu


@pytest.fixture(scope="module")
def loop_bin(cpp_build_dir: Path) -> str:
    path = cpp_build_dir / LOOP_RELATIVE
    assert path.is_file(), f"gyrodrift-loop not built at {path}"
    return str(path)


def _record(n: int, rate_hz: float, seed: int = 5) -> Samples:
    # A static IMU with an AR(2) gyro drift (the process the processor's Kalman filter models).
    rec = simulate_imu(n=n, rate_hz=rate_hz, seed=seed, vrw_m_s_rt_h=0.02,
                       gyro=NoiseTerms(n_deg_rt_h=0.01, b_deg_h=0.01, ar2=(1.0, -0.25, 0.5)))
    return make_samples(np.arange(n) / rate_hz, rec.gyro_rad_s, rec.accel_m_s2)


def _settings(rate_hz: float) -> ProcessorSettings:
    # AR(2)-Kalman on the gyros with the simulated drift's model, pass-through accelerometers.
    sigma2 = (0.5 * np.pi / 180 / 3600) ** 2
    return ProcessorSettings(a1=1.0, a2=-0.25, sigma2=sigma2, q=sigma2, r=1e-10,
                             sample_rate_hz=rate_hz)


def _config(rate_hz: float, loop_rate_hz: float) -> ProcessorConfig:
    """_settings(rate_hz) as a configuration file's processor, the loop at `loop_rate_hz`."""
    sigma2 = (0.5 * np.pi / 180 / 3600) ** 2
    gyro = (Ar2KalmanStage(a1=1.0, a2=-0.25, mean=0.0, q=sigma2, r=1e-10, sigma2=sigma2),)
    chans = [ChannelConfig(ch, gyro) for ch in ("gx", "gy", "gz")]
    chans += [ChannelConfig(ch, (PassThrough(),)) for ch in ("ax", "ay", "az")]
    return ProcessorConfig(channels=tuple(chans),
                           timing=Timing(rate_hz, loop_rate_hz=loop_rate_hz))


def _assert_exact(result: ReplayResult) -> None:
    rep = result.report
    failed = {k: v for k, v in rep["checks"].items() if not v}
    assert not failed, (failed, rep["accounting"], rep["comparison"],
                        rep["loop"] and rep["loop"]["rejected"])
    acc = rep["accounting"]
    assert acc["unaccounted"] == 0
    assert acc["outputs_received"] == acc["outputs_expected"] > 0
    assert all(e <= 1e-5 for e in rep["comparison"]["max_abs_error"])


@pytest.mark.parametrize("transport", ["serial", "slcan"])
def test_clean_as_fast_as_possible(loop_bin: str, transport: str) -> None:
    n = 3000 if transport == "serial" else 1500
    res = run_replay(_record(n, 400.0), ReplayOptions(
        transport=transport, speed=0.0, loop_rate_hz=1000.0, loop_binary=loop_bin,
        processor=_settings(400.0)))
    _assert_exact(res)
    assert res.report["accounting"]["outputs_received"] == n
    assert res.loop_stats is not None and res.loop_stats["end_reason"] == "end_of_input"


def test_serial_real_time_2khz(loop_bin: str) -> None:
    rate = 2000.0
    res = run_replay(_record(3000, rate), ReplayOptions(
        transport="serial", speed=1.0, loop_rate_hz=2000.0, loop_binary=loop_bin,
        processor=_settings(rate)))
    _assert_exact(res)
    # Paced at 1x: 3000 samples take 1.5 s (link pacing adds < 0.5 ms per frame, not
    # cumulative); loose bounds for a shared machine.
    send_s = res.report["throughput"]["send_s"]
    assert 1.45 < send_s < 3.0
    # Latency: one loop period (0.5 ms) plus scheduling; p50 well under 20 ms even when
    # the machine is busy.
    assert res.report["latency_us"]["p50"] < 20_000
    loop = res.loop_stats
    assert loop is not None
    # Overruns (a cycle that started late) are counted, never lost data (_assert_exact
    # above). How many depends on the machine's load, not on the code: a fresh-clone CI run
    # on the loaded 2-core machine saw 157 of 2895 (5.4 %) where a quiet one sees ~0, so this
    # bound only catches a loop that cannot keep its 0.5 ms period at all (then nearly every
    # cycle overruns). The loop's timing on a quiet machine is the benchmark's business.
    assert 0 <= loop["overruns"] <= 0.5 * loop["cycles"]


def test_slcan_real_time_400hz(loop_bin: str) -> None:
    rate = 400.0
    res = run_replay(_record(800, rate), ReplayOptions(
        transport="slcan", speed=1.0, loop_rate_hz=1000.0, can_bitrate=500000,
        loop_binary=loop_bin, processor=_settings(rate)))
    _assert_exact(res)
    assert 1.9 < res.report["throughput"]["send_s"] < 5.0  # 800 samples at 400 Hz = 2 s


@pytest.mark.parametrize("transport", ["serial", "slcan"])
@pytest.mark.parametrize("kind", FAULT_KINDS)
def test_each_fault_kind(loop_bin: str, transport: str, kind: str) -> None:
    n = 2000 if transport == "serial" else 1000
    record = _record(n, 400.0, seed=11)
    spec = FaultSpec(**{kind: 0.03}, seed=100 + FAULT_KINDS.index(kind))
    res = run_replay(record, ReplayOptions(
        transport=transport, speed=0.0, loop_rate_hz=1000.0, loop_binary=loop_bin,
        faults=spec, processor=_settings(400.0)))
    _assert_exact(res)
    acc = res.report["accounting"]
    assert acc["injected"][kind] > 0
    loop = res.loop_stats
    assert loop is not None
    rej = loop["rejected"]
    n_kind = acc["injected"][kind]
    # What each fault must do to the loop's counters (independent of the reference):
    if kind == "drop":
        assert acc["sent"] == n - n_kind
        # A gap is only visible between two received samples: drops before the first or
        # after the last sent sample are not "missing" to the loop.
        sent = sorted(u.index for u in plan_transmission(record.t_s, spec).units)
        inner = sum(1 for k in range(sent[0], sent[-1] + 1) if k not in set(sent))
        assert loop["health"]["missing_samples"] == inner
    elif kind == "corrupt":
        assert rej["crc" if transport == "serial" else "can_incomplete"] == n_kind
        assert loop["frames_out"] == n - n_kind
    elif kind == "duplicate":
        assert rej["duplicate"] == n_kind
        assert loop["frames_out"] == n
    elif kind == "reorder":
        # Each swap: the later sample arrives first (a gap of one), then the earlier one is
        # out of order and rejected.
        assert rej["out_of_order"] == n_kind
        assert loop["frames_out"] == n - n_kind
    elif kind == "delay":
        # A sample delayed by 20 ms (8 periods) arrives after 8 later ones: out of order.
        assert rej["out_of_order"] == n_kind
        assert loop["frames_out"] == n - n_kind


def test_all_faults_together_at_real_time(loop_bin: str) -> None:
    spec = FaultSpec(drop=0.01, corrupt=0.01, duplicate=0.01, reorder=0.01, delay=0.01, seed=4)
    res = run_replay(_record(1600, 800.0), ReplayOptions(
        transport="serial", speed=1.0, loop_rate_hz=2000.0, loop_binary=loop_bin, faults=spec,
        processor=_settings(800.0)))
    _assert_exact(res)
    assert sum(res.report["accounting"]["injected"].values()) > 40


def test_attach_to_a_running_target(loop_bin: str, tmp_path: Path) -> None:
    # A target already running on a serial device (here: the loop on a pty we made, as a
    # navigation computer on /dev/ttyUSB0 would be); the harness only opens the device path.
    rate = 400.0
    cfg = _config(rate, loop_rate_hz=1000.0)
    settings = ProcessorSettings.from_config(cfg)
    master, slave = os.openpty()
    tty.setraw(slave)
    proc = subprocess.Popen([loop_bin, "--serial", f"fd:{master}", "--no-rt",
                             "--config", str(write_config(cfg, tmp_path / "target.toml"))],
                            pass_fds=[master], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    os.close(master)
    assert proc.stderr is not None and b"ready" in proc.stderr.readline()
    spec = FaultSpec(duplicate=0.02, corrupt=0.02, seed=8)
    try:
        res = run_replay(_record(1000, rate), ReplayOptions(
            transport="serial", speed=0.0, attach=os.ttyname(slave), faults=spec,
            processor=settings))
    finally:
        os.close(slave)  # the target sees end of input and prints its statistics
        out, _ = proc.communicate(timeout=10)
    _assert_exact(res)
    assert res.loop_stats is None and res.report["checks"]["loop_stats_available"]
    loop = json.loads(out)
    acc = res.report["accounting"]
    assert loop["frames_out"] == acc["outputs_received"]
    assert loop["rejected"]["crc"] == acc["injected"]["corrupt"]
    assert loop["rejected"]["duplicate"] == acc["injected"]["duplicate"]


@pytest.mark.parametrize("interrupt", [KeyboardInterrupt, RuntimeError])
def test_interrupt_during_loop_start_up_ends_the_child(
        loop_bin: str, interrupt: type[BaseException], monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C (or any failure) while the harness waits for the loop's ready line: before,
    the start-up ran outside run_replay's try/finally and the gyrodrift-loop child was left
    running (issue 13)."""
    from gyrodrift.replay import harness

    started: list[subprocess.Popen[bytes]] = []

    def wait_ready(self: harness._Target, ready: object, timeout_s: float) -> bool:
        assert self.proc is not None
        started.append(self.proc)
        raise interrupt("during the ready wait")

    monkeypatch.setattr(harness._Target, "_wait_ready", wait_ready)
    with pytest.raises(interrupt, match="during the ready wait"):
        run_replay(_record(50, 400.0), ReplayOptions(
            transport="serial", speed=0.0, loop_binary=loop_bin, processor=_settings(400.0)))
    assert len(started) == 1
    proc = started[0]
    try:
        # stop() has returned: the child has exited and been reaped, nothing to wait for
        assert proc.poll() is not None, "gyrodrift-loop still running after the interrupt"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
