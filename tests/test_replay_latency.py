"""Replay latency is measured from the moment the input's first byte leaves the harness:
it can never be negative, even when the harness thread is preempted right after a write
(the loop has answered by the time the write call returns). The preemption is made
deterministic here by a link whose write/send sleeps after the bytes have gone out."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.replay import transport
from gyrodrift.replay.harness import LOOP_RELATIVE, ReplayOptions, run_replay
from gyrodrift.replay.processor import ProcessorSettings
from gyrodrift.replay.wire import make_samples

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
        transport=transport_name, speed=speed, loop_rate_hz=1000.0, batch_frames=1,
        loop_binary=str(cpp_build_dir / LOOP_RELATIVE),
        processor=ProcessorSettings(sample_rate_hz=rate)))
    assert res.report["accounting"]["outputs_received"] == n
    assert res.latency_us.size == n
    assert float(np.min(res.latency_us)) >= 0.0, np.sort(res.latency_us)[:5]
    assert res.report["latency_us"]["min"] >= 0.0
