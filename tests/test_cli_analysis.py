"""End-to-end runs of `gyrodrift simulate|filter|allan|psd|compare` on small records: files
written, numbers checked against the library (and allantools), clear errors."""

from __future__ import annotations

import json
from pathlib import Path

import allantools
import gyrodrift
import gyrodrift.cli as cli
import numpy as np
import pytest
from cli_units import with_units
from gyrodrift.stability import allan

MINE = ["simulate", "filter", "allan", "psd", "compare"]


@pytest.fixture(autouse=True)
def only_analysis_subcommands(monkeypatch: pytest.MonkeyPatch) -> None:
    # The real gyrodrift.cli.main, restricted to this area's subcommands so that another
    # area's unfinished module cannot break these tests.
    monkeypatch.setattr(cli, "SUBCOMMAND_MODULES", MINE)


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = cli.main(with_units(argv))
    out, err = capsys.readouterr()
    return code, out, err


def run_json(argv: list[str], capsys: pytest.CaptureFixture[str]) -> dict:
    code, out, err = run([*argv, "--json"], capsys)
    assert code == 0, err
    return json.loads(out)


def test_simulate_npy_then_allan_matches_allantools(tmp_path: Path, capsys) -> None:
    rec_path = tmp_path / "r.npy"
    info = run_json(["simulate", "-o", rec_path, "--samples", 20000, "--rate-hz", 50,
                     "--arw-deg-rt-h", 0.02,
                     "--quant-arcsec", 0.36, "--seed", 5], capsys)
    assert info["n"] == 20000 and rec_path.exists()
    x = np.load(rec_path)
    ref = gyrodrift.simulate(n=20000, rate_hz=50.0, n_deg_rt_h=0.02, q_deg=0.36 / 3600.0, seed=5)
    np.testing.assert_array_equal(x, ref.rate_deg_h)  # the file holds the simulator's record

    png, csv_path = tmp_path / "a.png", tmp_path / "a.csv"
    out = run_json(["allan", rec_path, "--rate-hz", 50, "--png", png, "--csv", csv_path], capsys)
    _, dev, _, _ = allantools.oadev(x, rate=50.0, data_type="freq", taus="octave")
    np.testing.assert_allclose(out["allan"]["adev"], dev, rtol=1e-9)
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    table = np.loadtxt(csv_path, delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, 2], dev, rtol=1e-9)
    # identified terms near the simulated ones (2e4 samples: N to 5 %, Q to 15 %)
    assert out["ieee952"]["n_deg_rt_h"] == pytest.approx(0.02, rel=0.05)
    assert out["ieee952"]["q_deg"] == pytest.approx(1e-4, rel=0.15)
    assert out["record"]["n_used"] == 20000

    code, text, _ = run(["allan", rec_path, "--rate-hz", 50], capsys)
    assert code == 0 and "IEEE 952 fit" in text and "paper 2006 eq. 8 fit" in text
    acf = run_json(["allan", rec_path, "--rate-hz", 50, "--noise-id", "acf"], capsys)
    assert acf["allan"]["alpha"] == allan.oadev(x, 50.0, alpha="acf").alpha.tolist()
    np.testing.assert_array_equal(acf["allan"]["adev"], out["allan"]["adev"])


def test_csv_column_choice_and_rate_from_time(tmp_path: Path, capsys) -> None:
    path = tmp_path / "r.csv"
    run_json(["simulate", "-o", path, "--samples", 4000, "--rate-hz", 20, "--arw-deg-rt-h", 0.05],
             capsys)
    out = run_json(["allan", path, "--column", "rate_deg_h"], capsys)
    assert out["record"]["rate_hz"] == pytest.approx(20.0, rel=1e-9)
    x = np.loadtxt(path, delimiter=",", skiprows=1)[:, 1]
    _, dev, _, _ = allantools.oadev(x, rate=20.0, data_type="freq", taus="octave")
    np.testing.assert_allclose(out["allan"]["adev"], dev, rtol=1e-9)
    code, _, err = run(["allan", path, "--column", "nope"], capsys)
    assert code == 2 and "no column 'nope'" in err and "rate_deg_h" in err


def test_units_conversion(tmp_path: Path, capsys) -> None:
    rng = np.random.default_rng(3)
    x_deg_h = rng.normal(0.0, 10.0, 5000)
    np.save(tmp_path / "dps.npy", x_deg_h / 3600.0)
    np.save(tmp_path / "inc.npy", x_deg_h / 10.0)  # arcsec per sample at 10 Hz = deg/h / 10
    a = run_json(["allan", tmp_path / "dps.npy", "--rate-hz", 10, "--gyro-units", "deg/s"], capsys)
    b = run_json(["allan", tmp_path / "inc.npy", "--rate-hz", 10, "--gyro-units", "arcsec"], capsys)
    _, dev, _, _ = allantools.oadev(x_deg_h, rate=10.0, data_type="freq", taus="octave")
    np.testing.assert_allclose(a["allan"]["adev"], dev, rtol=1e-9)
    np.testing.assert_allclose(b["allan"]["adev"], dev, rtol=1e-9)


def test_errors_missing_file_short_record_nan(tmp_path: Path, capsys) -> None:
    code, _, err = run(["allan", tmp_path / "none.npy", "--rate-hz", 1], capsys)
    assert code == 2 and "no such file" in err
    np.save(tmp_path / "short.npy", np.ones(2))
    code, _, err = run(["allan", tmp_path / "short.npy", "--rate-hz", 1], capsys)
    assert code == 2 and "too short" in err
    np.save(tmp_path / "ok.npy", np.random.default_rng(0).normal(size=100))
    code, _, err = run(["allan", tmp_path / "ok.npy"], capsys)
    assert code == 2 and "--rate-hz" in err

    x = np.random.default_rng(1).normal(size=3000)
    x[[10, 20, 30]] = np.nan
    np.save(tmp_path / "nan.npy", x)
    code, _, err = run(["allan", tmp_path / "nan.npy", "--rate-hz", 1], capsys)
    assert code == 2 and "3 of 3000 samples are NaN/Inf" in err and "--drop-nan" in err
    out = run_json(["allan", tmp_path / "nan.npy", "--rate-hz", 1, "--drop-nan"], capsys)
    assert out["record"]["n_dropped_nonfinite"] == 3 and out["record"]["n_used"] == 2997
    kept = x[np.isfinite(x)]
    _, dev, _, _ = allantools.oadev(kept, rate=1.0, data_type="freq", taus="octave")
    np.testing.assert_allclose(out["allan"]["adev"], dev, rtol=1e-9)


def test_progress_bar_always(tmp_path: Path, capsys) -> None:
    np.save(tmp_path / "r.npy", np.random.default_rng(2).normal(size=10_000))
    code, _, err = run(["allan", tmp_path / "r.npy", "--rate-hz", 1, "--progress", "always"],
                       capsys)
    assert code == 0 and "Allan" in err and "term" in err


def test_psd_cli(tmp_path: Path, capsys) -> None:
    path = tmp_path / "r.npy"
    run_json(["simulate", "-o", path, "--samples", 100_000, "--rate-hz", 100,
              "--arw-deg-rt-h", 0.05, "--seed", 2], capsys)
    png, csv_path = tmp_path / "p.png", tmp_path / "p.csv"
    out = run_json(["psd", path, "--rate-hz", 100, "--png", png, "--csv", csv_path], capsys)
    assert png.read_bytes()[:4] == b"\x89PNG"
    # white rate: N from the upper-band median level. The median of a chi2 with ~50 edf is
    # 1.3 % below the mean; 4096-bin median scatter < 1 %: 5 %.
    assert out["n_arw_deg_rt_h"] == pytest.approx(0.05, rel=0.05)
    f, p = np.loadtxt(csv_path, delimiter=",", skiprows=1, unpack=True)
    assert out["variance_from_psd_deg_h_sq"] == pytest.approx(np.var(np.load(path)), rel=0.03)
    assert f.size == p.size == out["n_bins"]


@pytest.mark.parametrize("method", ["ar", "kalman", "wavelet", "wpacket", "realtime-wavelet"])
def test_filter_cli_matches_library(tmp_path: Path, capsys, method: str) -> None:
    rec = gyrodrift.simulate(n=8192, rate_hz=100.0, n_deg_rt_h=0.01,
                             ar2=(0.6868, -0.0213, 0.5), seed=4)
    np.save(tmp_path / "r.npy", rec.rate_deg_h)
    out_path = tmp_path / "f.npy"
    out = run_json(["filter", tmp_path / "r.npy", "--rate-hz", 100, "--filter", method, "-o",
                    out_path], capsys)
    y = np.load(out_path)
    x = rec.rate_deg_h
    model = gyrodrift.fit_ar2(x)
    expected = {
        "ar": lambda: gyrodrift.ar_filter(x, model),
        "kalman": lambda: gyrodrift.kalman_filter(x, model),
        "wavelet": lambda: gyrodrift.wavelet_denoise(x, wavelet="db8", level=5),
        "wpacket": lambda: gyrodrift.wavelet_packet_denoise(x, wavelet="bior3.7", level=4),
        "realtime-wavelet": lambda: gyrodrift.RealtimeWavelet("db8", window=256,
                                                              level=5).filter(x),
    }[method]()
    np.testing.assert_array_equal(y, expected)
    assert out["std_out_deg_h"] < out["std_in_deg_h"]


@pytest.mark.parametrize("extra", [
    ["--filter", "kalman", "--kalman-q", "0.05", "--kalman-r", "2.0"],
    ["--filter", "wavelet", "--wavelet", "db4", "--level", "4", "--threshold", "hard"],
    ["--filter", "realtime-wavelet", "--wavelet", "db4", "--window", "64", "--level", "3",
     "--threshold", "soft"],
    ["--filter", "wpacket", "--threshold", "hard"],
])
def test_filter_cli_options_reach_the_library(tmp_path: Path, capsys, extra: list[str]) -> None:
    """issue 9: filter has the Kalman variances, the wavelet choice and the threshold mode."""
    rec = gyrodrift.simulate(n=4096, rate_hz=100.0, n_deg_rt_h=0.01,
                             ar2=(0.6868, -0.0213, 0.5), seed=5)
    np.save(tmp_path / "r.npy", rec.rate_deg_h)
    out = run_json(["filter", tmp_path / "r.npy", "--rate-hz", 100, "-o", tmp_path / "f.npy",
                    *extra], capsys)
    x, y = rec.rate_deg_h, np.load(tmp_path / "f.npy")
    method = extra[1]
    if method == "kalman":
        expected = gyrodrift.kalman_filter(x, gyrodrift.fit_ar2(x), q=0.05, r=2.0)
        assert out["filter"]["kalman"] == {"q": 0.05, "r": 2.0, "steady_state": False}
    elif method == "wavelet":
        expected = gyrodrift.wavelet_denoise(x, wavelet="db4", level=4, mode="hard")
    elif method == "realtime-wavelet":
        expected = gyrodrift.RealtimeWavelet("db4", window=64, level=3, mode="soft").filter(x)
    else:
        expected = gyrodrift.wavelet_packet_denoise(x, wavelet="bior3.7", level=4, mode="hard")
    np.testing.assert_array_equal(y, expected)
    code, _, err = run(["filter", tmp_path / "r.npy", "--rate-hz", 100, "-o",
                        tmp_path / "g.npy", "--filter", "wavelet", "--threshold", "forced"],
                       capsys)
    assert code == 2 and "realtime-wavelet" in err


def test_csv_outputs_carry_every_digit(tmp_path: Path, capsys) -> None:
    """issue 9: allan --csv wrote integers as 1.000000000000000000e+00; filter -o x.csv wrote
    rounded times. Floats now read back bit for bit, integers are integers."""
    rec = gyrodrift.simulate(n=3000, rate_hz=3.0, n_deg_rt_h=0.01, seed=6)
    np.save(tmp_path / "r.npy", rec.rate_deg_h)
    out = run_json(["allan", tmp_path / "r.npy", "--rate-hz", 3, "--csv", tmp_path / "a.csv"],
                   capsys)
    lines = (tmp_path / "a.csv").read_text().splitlines()
    assert lines[0] == ("tau_s,m,adev_deg_h,ci_low_deg_h,ci_high_deg_h,edf,terms,"
                        "fit_adev_deg_h,fit_used,fit_ratio,fit_passed")
    first = lines[1].split(",")
    assert first[1] == "1" and first[6] == str(out["allan"]["terms"][0])  # integers
    table = np.loadtxt(tmp_path / "a.csv", delimiter=",", skiprows=1)
    assert table[:, 2].tolist() == out["allan"]["adev"]  # exact round trip
    run_json(["filter", tmp_path / "r.npy", "--rate-hz", 3, "-o", tmp_path / "f.csv"], capsys)
    t_s, y = np.loadtxt(tmp_path / "f.csv", delimiter=",", skiprows=1, unpack=True)
    assert t_s[1] == 1 / 3 and (tmp_path / "f.csv").read_text().splitlines()[2].startswith(
        f"{1 / 3!r},")
    np.testing.assert_array_equal(y, gyrodrift.kalman_filter(rec.rate_deg_h,
                                                             gyrodrift.fit_ar2(rec.rate_deg_h)))


def test_filter_float_core_close_to_double(tmp_path: Path, capsys) -> None:
    rec = gyrodrift.simulate(n=4096, rate_hz=100.0, ar2=(0.6868, -0.0213, 0.5), seed=9)
    np.save(tmp_path / "r.npy", rec.rate_deg_h)
    run_json(["filter", tmp_path / "r.npy", "--rate-hz", 100, "-o", tmp_path / "d.npy"], capsys)
    run_json(["filter", tmp_path / "r.npy", "--rate-hz", 100, "--core", "float", "-o",
              tmp_path / "f.csv"], capsys)
    d = np.load(tmp_path / "d.npy")
    f = np.loadtxt(tmp_path / "f.csv", delimiter=",", skiprows=1)[:, 1]
    # float32 Kalman on O(1) deg/h data: ~1e-6 absolute per step, stable filter: 1e-4.
    np.testing.assert_allclose(f, d, atol=1e-4 * max(1.0, float(np.max(np.abs(d)))))


@pytest.mark.parametrize("suffix", [".bin", ".log", ".asc", ".blf"])
def test_simulate_imu_logs_read_back(tmp_path: Path, capsys, suffix: str) -> None:
    from gyrodrift.io.imu_log import read_imu_log

    path = tmp_path / f"imu{suffix}"
    info = run_json(["simulate", "-o", path, "--samples", 300, "--rate-hz", 100,
                     "--arw-deg-rt-h", 0.01, "--seed", 3], capsys)
    assert info["n"] == 300
    samples = read_imu_log(path)
    ref = gyrodrift.simulate_imu(n=300, rate_hz=100.0,
                                 gyro=gyrodrift.NoiseTerms(n_deg_rt_h=0.01), seed=3)
    # the wire carries float32
    np.testing.assert_array_equal(samples.channels[:, :3],
                                  ref.gyro_rad_s.astype(np.float32))
    out = run_json(["allan", path, "--column", "z"], capsys)
    assert out["record"]["rate_hz"] == pytest.approx(100.0, rel=1e-6)
    assert out["record"]["n_used"] == 300


def test_simulate_format_flag_and_bad_suffix(tmp_path: Path, capsys) -> None:
    path = tmp_path / "frames.gdf"
    run_json(["simulate", "-o", path, "--samples", 50, "--rate-hz", 100, "--format", "bin"], capsys)
    assert path.stat().st_size == 50 * 42  # 42-byte serial frames
    code, _, err = run(["simulate", "-o", tmp_path / "x.txt", "--samples", 50], capsys)
    assert code == 2 and "cannot tell" in err


def test_compare_cli_default_record(tmp_path: Path, capsys) -> None:
    out_dir = tmp_path / "cmp"
    code, text, err = run(["compare", "--out-dir", out_dir, "--json", "--progress", "always"],
                          capsys)
    assert code == 0 and "compare" in err  # the tqdm bar over the five signals, forced on
    out = json.loads(text)
    rows = {r["signal"]: r for r in out["rows"]}
    assert set(rows) == {"original", "db8 wavelet", "bior3.7 wavelet packet", "AR model",
                         "AR(2)-Kalman"}
    for name in ("compare.md", "compare.csv", "compare_allan.png", "compare_psd.png",
                 "compare.json"):
        assert (out_dir / name).stat().st_size > 0
    md = (out_dir / "compare.md").read_text()
    assert "paper (published)" in md and "ours (measured)" in md
    assert rows["original"]["published"]["std_deg_h"] == 0.0962
    # the default record matches the published raw STD (5 %, 6.5e4 samples: sd of the
    # sample std 0.3 %; the rate was solved for it) and N (10 %: Allan fit of 16 octaves)
    assert rows["original"]["measured"]["std_deg_h"] == pytest.approx(0.0962, rel=0.05)
    assert rows["original"]["measured"]["n_deg_rt_h"] == pytest.approx(0.0012, rel=0.10)
    # every filter lowers the deviation
    for name, row in rows.items():
        if name != "original":
            assert row["measured"]["std_deg_h"] < rows["original"]["measured"]["std_deg_h"]


def test_compare_cli_with_input(tmp_path: Path, capsys) -> None:
    rec = gyrodrift.simulate(n=8192, rate_hz=1.0, n_deg_rt_h=0.0012, seed=1)
    np.save(tmp_path / "r.npy", rec.rate_deg_h)
    code, text, err = run(["compare", tmp_path / "r.npy", "--rate-hz", 1, "--out-dir",
                           tmp_path / "o"], capsys)
    assert code == 0, err
    assert err == ""  # --progress auto: stderr is not a terminal here, so no bar
    assert "| original | ours (measured) |" in text
    code, _, err = run(["compare", tmp_path / "missing.npy", "--rate-hz", 1], capsys)
    assert code == 2 and "no such file" in err
