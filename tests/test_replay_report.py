"""replay.report.write_png on degenerate but valid runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from gyrodrift.replay import ReplayResult
from gyrodrift.report.replay import write_png


@pytest.mark.parametrize("latency_us", [np.full(50, 300.0), np.linspace(250.0, 400.0, 50)])
def test_png_of_outputs_at_an_exactly_constant_spacing(tmp_path: Path,
                                                        latency_us: np.ndarray) -> None:
    """Regression: outputs exactly 2.5 ms apart (a simulated or perfectly paced run) made
    numpy refuse 100 bins for a span of rounding noise ('Too many bins for data range')."""
    arrival_s = np.arange(50) * 0.0025
    res = ReplayResult({"ok": True, "transport": "serial", "speed": "1x"},
                       latency_us, arrival_s, None)
    out = write_png(res, tmp_path / "report.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out.stat().st_size > 10_000
