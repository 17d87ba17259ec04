"""`gyrodrift wavelet-response`: PNG + JSON of the forced prefilter's response."""

from __future__ import annotations

import json

import numpy as np
import pytest
from gyrodrift.cli import main
from gyrodrift.reference import wavelet as ref


def test_json_and_png(tmp_path, capsys) -> None:
    png = tmp_path / "resp.png"
    rc = main(
        [
            "wavelet-response",
            "--png",
            str(png),
            "--json",
            "--rate-hz",
            "400",
            "--window",
            "64",
            "--level",
            "3",
            "--n-freqs",
            "256",
        ]
    )
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    b = np.array(out["taps_newest_first"])
    # Taps from the pywt recompute reference by linearity (oldest first -> reversed).
    np.testing.assert_allclose(b, ref.forced_fir_taps("db4", 64, 3), rtol=0, atol=1e-12)
    assert out["dc_gain"] == pytest.approx(1.0, abs=1e-12)
    # DC group delay of an FIR is its centroid sum(k b_k) / sum(b_k) samples.
    centroid_s = float(np.sum(np.arange(64) * b) / np.sum(b)) / 400.0
    assert out["group_delay_dc_s"] == pytest.approx(centroid_s, rel=1e-9)
    assert out["magnitude"][0] == pytest.approx(1.0, abs=1e-12)
    assert len(out["f_hz"]) == 256 and out["f_hz"][-1] < 200.0
    assert 0.0 < out["cutoff_3db_hz"] < 200.0


def test_text_output_default_rate(tmp_path, capsys) -> None:
    png = tmp_path / "r.png"
    assert main(["wavelet-response", "--png", str(png)]) == 0
    text = capsys.readouterr().out
    assert "forced db4 J=5 N=256 at 400 Hz" in text and png.exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--window", "100"], "power of two"),
        (["--level", "9"], "out of range"),
        (["--rate-hz", "0"], "rate-hz"),
        (["--n-freqs", "2"], "n-freqs"),
    ],
)
def test_bad_arguments_exit_2(argv: list[str], message: str, tmp_path, capsys) -> None:
    assert main(["wavelet-response", "--png", str(tmp_path / "x.png"), *argv]) == 2
    assert message in capsys.readouterr().err
