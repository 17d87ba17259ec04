"""`gyrodrift filter` on a long memory-mapped .npy record filters it in pieces (ar, kalman,
realtime-wavelet: the AR(2) model fitted in passes over the pieces (`fit_ar2_chunks`), the
C++ filter's state carried from piece to piece; wavelet, wpacket: from windows of the record,
`gyrodrift.filters.wavelet_file`), the output written piece by piece and the
printed standard deviations taken piece by piece; the memory does not grow with the record
(tests/test_peak_memory.py).

Tolerances: the filter over pieces is the one-call filter with the same model bit for bit
(the same sequential C++ recursion, its state carried; exact comparison). The model from the
pieces is `fit_ar2`'s with numpy's sums in another order than the core's sequential loop:
1e-11 relative on 1e4-2e5 samples (rounding of such sums is ~1e-13; a lost or doubled
sample at a piece boundary changes the lag sums by ~1e-4 of their value). The standard
deviations: numpy.std's to 1e-12 (a pairwise update of exact-to-rounding sums)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import gyrodrift
import gyrodrift.cli as cli
import numpy as np
import pytest
import scipy.signal
from cli_units import with_units
from gyrodrift.cli import filter as filter_cli
from gyrodrift.filters.ar2 import Ar2FitError, fit_ar2_chunks

N = 10_007
PIECE = 1000  # not a divisor of N: pieces of unequal length


def _record(n: int = N, seed: int = 4) -> np.ndarray:
    e = np.random.default_rng(seed).standard_normal(n)
    return scipy.signal.lfilter([1.0], [1.0, -0.6868, 0.0213], e) * 0.5 + 3.0


def _pieces(x: np.ndarray, piece: int):
    return lambda: (x[i:i + piece] for i in range(0, x.size, piece))


@pytest.mark.parametrize("method", ["yule-walker", "burg", "ls"])
def test_fit_over_pieces_is_the_whole_record_fit(method: str) -> None:
    x = _record(200_001)
    ref = gyrodrift.fit_ar2(x, method)
    for piece in (4096, 300_000):
        got = fit_ar2_chunks(_pieces(x, piece), method)
        assert (got.method, got.n) == (ref.method, ref.n)
        for k in ("a1", "a2", "sigma2", "mean", "r"):
            assert math.isclose(getattr(got, k), getattr(ref, k), rel_tol=1e-11), (piece, k)
    # short pieces
    ref = gyrodrift.fit_ar2(x[:3000], method)
    for piece in (1, 2, 7):
        got = fit_ar2_chunks(_pieces(x[:3000], piece), method)
        assert (got.method, got.n) == (ref.method, ref.n)
        for k in ("a1", "a2", "sigma2", "mean", "r"):
            assert math.isclose(getattr(got, k), getattr(ref, k), rel_tol=1e-11), (piece, k)


def test_fit_over_pieces_refuses_as_the_core_does() -> None:
    for x, cause in ((np.ones(50), "constant"), (np.arange(5.0), "too_short"),
                     (np.r_[_record(100), np.nan], "non_finite")):
        with pytest.raises(Ar2FitError) as ref:
            gyrodrift.fit_ar2(x)
        with pytest.raises(Ar2FitError) as got:
            fit_ar2_chunks(_pieces(x, 7))
        assert got.value.cause == ref.value.cause == cause
        assert str(got.value) == str(ref.value)


def _run(argv: list[object], capsys: pytest.CaptureFixture[str]) -> dict:
    code = cli.main(with_units([*argv, "--json"]))
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)


@pytest.mark.parametrize("extra", [
    ["--filter", "kalman"],
    ["--filter", "kalman", "--steady-state", "--ar-method", "burg"],
    ["--filter", "kalman", "--core", "float", "--kalman-q", "0.05"],
    ["--filter", "ar", "--ar-method", "ls"],
    ["--filter", "ar", "--core", "float"],
    ["--filter", "realtime-wavelet", "--wavelet", "db4", "--window", "64", "--level", "3"],
    ["--filter", "realtime-wavelet", "--wavelet", "db4", "--window", "64", "--level", "3",
     "--core", "float"],
    ["--filter", "wavelet", "--wavelet", "db4", "--level", "3", "--threshold", "hard"],
    ["--filter", "wavelet", "--wavelet", "db4", "--level", "3", "--threshold", "hard",
     "--core", "float"],
    ["--filter", "wpacket", "--level", "3"],
])
def test_filter_of_a_mapped_record_in_pieces_is_the_one_call_filter(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        extra: list[str]) -> None:
    x = _record()
    np.save(tmp_path / "r.npy", x)
    monkeypatch.setattr(filter_cli, "FILE_BACKED_MIN", 4096)
    monkeypatch.setattr(filter_cli, "_PIECE", PIECE)
    calls: list[int] = []
    real = filter_cli._run_piecewise
    monkeypatch.setattr(filter_cli, "_run_piecewise",
                        lambda *a: calls.append(1) or real(*a))  # type: ignore[func-returns-value]
    out = _run(["filter", tmp_path / "r.npy", "--rate-hz", 100, "-o", tmp_path / "f.npy",
                *extra], capsys)
    assert calls == [1]  # the piece path ran
    y = np.load(tmp_path / "f.npy")
    method = extra[1]
    f32 = "float" in extra
    dtype = np.float32 if f32 else np.float64
    if method == "realtime-wavelet":
        expected = gyrodrift.RealtimeWavelet("db4", window=64, level=3, dtype=dtype).filter(x)
    elif method == "wavelet":
        expected = gyrodrift.wavelet_denoise(x, "db4", 3, "hard", dtype=dtype)
        if f32:  # float32 windows: 1e-5 of the scale (tests/test_wavelet_file.py)
            np.testing.assert_allclose(y, expected, rtol=0, atol=1e-5 * np.max(np.abs(x)))
            expected = y
    elif method == "wpacket":
        # PyWavelets' reconstruction near a window's edge sums in another order: 1e-15
        # absolute on O(1) values (tests/test_wavelet_file.py)
        expected = gyrodrift.wavelet_packet_denoise(x, "bior3.7", 3)
        np.testing.assert_allclose(y, expected, rtol=0, atol=1e-12 * np.max(np.abs(x)))
        expected = y
    else:
        model = fit_ar2_chunks(_pieces(x, PIECE), extra[extra.index("--ar-method") + 1]
                               if "--ar-method" in extra else "yule-walker")
        assert out["filter"]["ar2"]["a1"] == model.a1
        if method == "ar":
            expected = gyrodrift.ar_filter(x.astype(dtype), model)
        else:
            expected = gyrodrift.kalman_filter(x.astype(dtype), model,
                                               q=0.05 if "--kalman-q" in extra else None,
                                               steady_state="--steady-state" in extra)
    assert y.dtype == np.float64 and y.shape == x.shape
    np.testing.assert_array_equal(y, np.asarray(expected).astype(np.float64))
    assert math.isclose(out["std_in_deg_h"], float(np.std(x)), rel_tol=1e-12)
    assert math.isclose(out["std_out_deg_h"], float(np.std(y)), rel_tol=1e-12)
    assert out["std_out_deg_h"] < out["std_in_deg_h"]


def test_filter_in_pieces_writes_the_csv_the_whole_record_path_writes(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    x = _record(5003)
    np.save(tmp_path / "r.npy", x)
    # the whole-record path with the model of the pieces: the same numbers, so the same text
    monkeypatch.setattr(filter_cli, "_PIECE", 700)
    monkeypatch.setattr(filter_cli, "FILE_BACKED_MIN", 1 << 30)
    monkeypatch.setattr(gyrodrift, "fit_ar2",
                        lambda a, method: fit_ar2_chunks(_pieces(np.asarray(a), 700), method))
    _run(["filter", tmp_path / "r.npy", "--rate-hz", 3, "-o", tmp_path / "whole.csv"], capsys)
    monkeypatch.setattr(filter_cli, "FILE_BACKED_MIN", 1000)
    _run(["filter", tmp_path / "r.npy", "--rate-hz", 3, "-o", tmp_path / "pieces.csv"], capsys)
    text = (tmp_path / "pieces.csv").read_text()
    assert text == (tmp_path / "whole.csv").read_text()
    assert text.splitlines()[2].startswith(f"{1 / 3!r},") and text.count("\n") == 5004


def test_filter_in_pieces_refuses_a_record_with_nan(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    x = _record()
    x[5000] = np.nan
    np.save(tmp_path / "r.npy", x)
    monkeypatch.setattr(filter_cli, "FILE_BACKED_MIN", 4096)
    code = cli.main(with_units(["filter", str(tmp_path / "r.npy"), "--rate-hz", "100", "-o",
                                str(tmp_path / "f.npy")]))
    err = capsys.readouterr().err
    assert code == 2 and "error:" in err and "Traceback" not in err
    assert not (tmp_path / "f.npy").exists()


@pytest.mark.parametrize("piece_path", [True, False])
def test_wpacket_refuses_the_float_core_in_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch, piece_path: bool) -> None:
    """wpacket has no float core (PyWavelets, float64): --core float is refused with one
    line on the piece path as on the in-memory one, and nothing is written."""
    np.save(tmp_path / "r.npy", _record())
    monkeypatch.setattr(filter_cli, "FILE_BACKED_MIN", 4096 if piece_path else 1 << 30)
    code = cli.main(with_units(["filter", str(tmp_path / "r.npy"), "--rate-hz", "100", "-o",
                                str(tmp_path / "f.npy"), "--filter", "wpacket", "--core",
                                "float"]))
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.strip().splitlines() == [
        "gyrodrift filter: error: wpacket runs in Python (PyWavelets, float64) only; drop "
        "--core float"]
    assert not (tmp_path / "f.npy").exists()


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("method", ["ar", "kalman"])
def test_float_pieces_refuse_a_value_beyond_float32_with_its_index_in_the_record(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        method: str) -> None:
    """In pieces too, --core float refuses a finite value float32 cannot hold, naming its
    index in the whole record (a later piece's), with no numpy warning and no output; before,
    each piece was cast to float32 and the value became Inf."""
    x = _record()
    x[2345] = -1e39
    np.save(tmp_path / "r.npy", x)
    monkeypatch.setattr(filter_cli, "FILE_BACKED_MIN", 4096)
    monkeypatch.setattr(filter_cli, "_PIECE", PIECE)
    code = cli.main(with_units(["filter", tmp_path / "r.npy", "--rate-hz", 100, "--filter",
                                method, "--core", "float", "-o", tmp_path / "f.npy"]))
    err = capsys.readouterr().err
    assert code == 2, err
    assert "-1e+39 at index 2345" in err and "float32" in err, err
    assert len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "f.npy").exists()
