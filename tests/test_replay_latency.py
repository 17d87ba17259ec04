"""Replay latency is measured from the moment the input's first byte leaves the harness:
it can never be negative, even when the harness thread is preempted right after a write
(the loop has answered by the time the write call returns). The preemption is made
deterministic here by a link whose write/send sleeps after the bytes have gone out."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.codecs.wire import make_samples
from gyrodrift.imu.config import default_config
from gyrodrift.replay import transport
from gyrodrift.replay.harness import LOOP_RELATIVE, ReplayOptions, run_replay

PREEMPT_S = 0.004  # longer than the loop's period (1 ms) plus its reply time


@pytest.mark.parametrize("transport_name", ["serial", "slcan"])
@pytest.mark.parametrize("speed", [1.0, 0.0])
def test_latency_never_negative_when_the_sender_is_preempted(
        monkeypatch: pytest.MonkeyPatch, cpp_build_dir: Path, transport_name: str,
        speed: float) -> None:
    if transport_name == "serial":
        orig_write = transport.SerialLink.write

        def write(self: transport.SerialLink, data: bytes) -> None:
            orig_write(self, data)
            time.sleep(PREEMPT_S)

        monkeypatch.setattr(transport.SerialLink, "write", write)
    else:
        orig_send = transport.CanLink.send

        def send(self: transport.CanLink, msg: object) -> None:
            orig_send(self, msg)
            if msg.arbitration_id == 0x103:  # after the sample's last frame
                time.sleep(PREEMPT_S)

        monkeypatch.setattr(transport.CanLink, "send", send)
    n, rate = 60, 100.0
    rng = np.random.default_rng(4)
    samples = make_samples(np.arange(n) / rate, rng.normal(0, 1e-4, (n, 3)),
                           rng.normal(0, 1e-2, (n, 3)))
    res = run_replay(samples, ReplayOptions(
        transport=transport_name, speed=speed, batch_frames=1,
        loop_binary=str(cpp_build_dir / LOOP_RELATIVE),
        processor=default_config(sample_rate_hz=rate).with_timing(loop_rate_hz=1000.0)))
    assert res.report["accounting"]["outputs_received"] == n
    assert res.latency_us.size == n
    assert float(np.min(res.latency_us)) >= 0.0, np.sort(res.latency_us)[:5]
    assert res.report["latency_us"]["min"] >= 0.0


def _fifo_permitted() -> bool:
    """Whether this process may make a thread SCHED_FIFO (probed on a throw-away thread)."""
    import threading

    from gyrodrift.replay.transport import set_thread_realtime

    out: list[str] = []
    t = threading.Thread(target=lambda: out.append(set_thread_realtime(70)))
    t.start()
    t.join()
    return out[0].startswith("SCHED_FIFO")


@pytest.mark.parametrize("transport_name", ["serial", "slcan"])
def test_harness_threads_get_realtime_or_say_why_not(cpp_build_dir: Path,
                                                     transport_name: str) -> None:
    import os

    n, rate = 40, 400.0
    samples = make_samples(np.arange(n) / rate, np.zeros((n, 3)), np.zeros((n, 3)))
    opt = ReplayOptions(transport=transport_name, speed=0.0,
                        loop_binary=str(cpp_build_dir / LOOP_RELATIVE),
                        processor=default_config(sample_rate_hz=rate).with_timing(loop_rate_hz=1000.0))
    assert opt.harness_realtime  # the default, like the loop's
    policy_before = os.sched_getscheduler(0)
    rt = run_replay(samples, opt).report["harness_realtime"]
    want = "SCHED_FIFO 70" if _fifo_permitted() else "refused: "
    assert rt["sender"].startswith(want) and rt["receiver"].startswith(want), rt
    assert os.sched_getscheduler(0) == policy_before  # the caller's thread is given back
    off = run_replay(samples, ReplayOptions(**{**opt.__dict__, "harness_realtime": False}))
    assert off.report["harness_realtime"] == {"sender": "not requested",
                                              "receiver": "not requested"}


def test_refused_realtime_is_reported(monkeypatch: pytest.MonkeyPatch,
                                      cpp_build_dir: Path) -> None:
    import os

    def refuse(*_: object) -> None:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    n, rate = 40, 400.0
    samples = make_samples(np.arange(n) / rate, np.zeros((n, 3)), np.zeros((n, 3)))
    res = run_replay(samples, ReplayOptions(
        transport="serial", speed=0.0, loop_realtime=False,
        loop_binary=str(cpp_build_dir / LOOP_RELATIVE),
        processor=default_config(sample_rate_hz=rate).with_timing(loop_rate_hz=1000.0)))
    rt = res.report["harness_realtime"]
    assert rt["sender"].startswith("refused: ") and "not permitted" in rt["sender"], rt
    assert rt["receiver"].startswith("refused: "), rt
    assert res.ok


def test_socketpair_local_link(cpp_build_dir: Path) -> None:
    # The diagnostic link of bench_replay --stress-cpu: the same replay without a tty.
    n, rate = 300, 400.0
    rng = np.random.default_rng(9)
    samples = make_samples(np.arange(n) / rate, rng.normal(0, 1e-4, (n, 3)),
                           rng.normal(0, 1e-2, (n, 3)))
    res = run_replay(samples, ReplayOptions(
        transport="serial", speed=4.0, local_link="socketpair",
        loop_binary=str(cpp_build_dir / LOOP_RELATIVE),
        processor=default_config(sample_rate_hz=rate).with_timing(loop_rate_hz=2000.0)))
    assert res.ok, {k: v for k, v in res.report["checks"].items() if not v}
    assert res.report["device"].startswith("socketpair fd:")
    assert res.report["accounting"]["outputs_received"] == n
    with pytest.raises(ValueError, match="serial transport only"):
        ReplayOptions(transport="slcan", local_link="socketpair")
