"""`gyrodrift characterize`: Kalibr export against hand-computed conversions, the self-check
on the allan_variance_ros simulator settings, and the HTML report in a real headless browser."""

from __future__ import annotations

import math
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.io.imu_data import CHANNELS, ImuData
from gyrodrift.workflows.characterize import (
    characterize,
    kalibr_values,
    kalibr_yaml,
    self_check,
)

# allan_variance_ros's published simulator settings (its README / imu simulator config).
GYRO_N = 1.888339e-4  # rad/s/sqrt(Hz)
GYRO_K = 2.556531e-6  # rad/s^2/sqrt(Hz)
ACC_N = 2.501993e-3  # m/s^2/sqrt(Hz)
ACC_K = 6.972435e-5  # m/s^3/sqrt(Hz)


def _white_rw(n: int, rate: float, nd: float, rw: float, seed: int) -> np.ndarray:
    """White noise of density nd plus a random walk of density rw, written from the
    discrete-time relations (independent of the simulator): sample std nd / sqrt(dt), walk step
    std rw * sqrt(dt)."""
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate
    return (nd / math.sqrt(dt)) * rng.standard_normal(n) + np.cumsum(
        (rw * math.sqrt(dt)) * rng.standard_normal(n))


@pytest.fixture(scope="module")
def avr_result():
    """3 h at 200 Hz, six channels with the allan_variance_ros settings; 95 % intervals."""
    n, rate = 3 * 3600 * 200, 200.0
    cols = {}
    for j, name in enumerate(CHANNELS):
        nd, rw = (GYRO_N, GYRO_K) if j < 3 else (ACC_N, ACC_K)
        cols[name] = _white_rw(n, rate, nd, rw, seed=100 + j)
    rec = ImuData(cols, rate, "allan_variance_ros settings", "simulated", n)
    return characterize(rec, ci=0.95)


@pytest.mark.xdist_group("characterize_avr")
def test_kalibr_values_recover_allan_variance_ros_settings(avr_result) -> None:
    vals = kalibr_values(avr_result)
    truth = {"gyroscope_noise_density": (GYRO_N, 0.10), "gyroscope_random_walk": (GYRO_K, 0.25),
             "accelerometer_noise_density": (ACC_N, 0.10),
             "accelerometer_random_walk": (ACC_K, 0.25)}
    for key, (true, tol) in truth.items():
        value, _, term = vals[key]
        assert term.contains(true), (key, term, true)
        assert abs(value / true - 1.0) <= tol, (key, value, true)
    # Every axis's interval holds the setting too.
    for c in avr_result.channels:
        nd, rw = (GYRO_N, GYRO_K) if c.sensor == "gyro" else (ACC_N, ACC_K)
        assert c.terms["N"].contains(nd), c.channel
        assert c.terms["K"].contains(rw), c.channel


@pytest.mark.xdist_group("characterize_avr")
def test_self_check_recovers_identified_terms(avr_result) -> None:
    sc = self_check(avr_result, seed=11)
    assert len(sc.rows) == 6 * 5
    assert sc.all_inside, [r for r in sc.rows if not r["inside"]]


def test_kalibr_yaml_round_trip_against_hand_conversions(tmp_path: Path) -> None:
    """Terms of a known Allan curve -> imu.yaml -> parsed back, against conversions by hand:
    sigma^2(tau) = N^2/tau + K^2 tau/3 for a white density N and a random-walk density K."""
    import yaml

    rate, n = 100.0, 400_000
    n_dph_rt_h = 0.05  # deg/sqrt(h), a gyro's ARW datasheet value
    k_dph_rt_h = 30.0  # deg/h/sqrt(h) (crossing the white noise near 10 s)
    # Hand conversions: N [rad/s/sqrt(Hz)] = N [deg/sqrt(h)] * (pi/180) / 60;
    # K [rad/s^2/sqrt(Hz)] = K [deg/h/sqrt(h)] * (pi/180) / 3600 / 60.
    gn = n_dph_rt_h * math.pi / 180.0 / 60.0
    gk = k_dph_rt_h * math.pi / 180.0 / 3600.0 / 60.0
    # Accelerometer VRW 0.02 m/s/sqrt(h) -> 0.02/60 m/s^2/sqrt(Hz); bias walk given in SI.
    an, ak = 0.02 / 60.0, 6e-5
    cols = {}
    for j, name in enumerate(CHANNELS):
        nd, rw = (gn, gk) if j < 3 else (an, ak)
        cols[name] = _white_rw(n, rate, nd, rw, seed=7 + j)
    res = characterize(ImuData(cols, rate, "hand", "simulated", n), terms=("N", "K"))
    text = kalibr_yaml(res, axis="y")
    doc = yaml.safe_load(text)
    assert doc["update_rate"] == rate
    assert doc["rostopic"] == "/imu0"
    assert "# axis: y (chosen)" in text
    assert "sigma_d = noise_density / sqrt(dt)" in text
    for key, ch, term in (("gyroscope_noise_density", "gyro_y", "N"),
                          ("gyroscope_random_walk", "gyro_y", "K"),
                          ("accelerometer_noise_density", "accel_y", "N"),
                          ("accelerometer_random_walk", "accel_y", "K")):
        # The yaml carries the identified value exactly (repr round trip) ...
        assert doc[key] == res.channel(ch).terms[term].value
    # ... and the values match the hand conversions (N within 2 %, K within 25 %: one
    # 4000 s record's random-walk precision).
    assert doc["gyroscope_noise_density"] == pytest.approx(gn, rel=0.02)
    assert doc["accelerometer_noise_density"] == pytest.approx(an, rel=0.02)
    assert doc["gyroscope_random_walk"] == pytest.approx(gk, rel=0.25)
    assert doc["accelerometer_random_walk"] == pytest.approx(ak, rel=0.25)
    # Discrete-time values a filter would use: sigma_d = N / sqrt(dt) is the per-sample std.
    sigma_d = doc["gyroscope_noise_density"] * math.sqrt(rate)
    assert sigma_d == pytest.approx(gn * math.sqrt(rate), rel=0.02)
    # The worst axis is the per-parameter maximum.
    worst = yaml.safe_load(kalibr_yaml(res))
    assert worst["gyroscope_random_walk"] == max(res.channel(c).terms["K"].value
                                                 for c in ("gyro_x", "gyro_y", "gyro_z"))


def test_characterize_cli_outputs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from gyrodrift.cli import main

    rng = np.random.default_rng(2)
    x = rng.standard_normal((20000, 6)) * [1e-3, 1e-3, 1e-3, 1e-2, 1e-2, 1e-2]
    np.save(tmp_path / "imu.npy", x)
    code = main(["characterize", str(tmp_path / "imu.npy"), "--rate-hz", "100",
                 "--gyro-units", "rad/s", "--accel-units", "m/s^2",
                 "--kalibr", str(tmp_path / "imu.yaml"),
                 "--html", str(tmp_path / "r.html"),
                 "--out-dir", str(tmp_path / "plots"), "--self-check", "--json"])
    assert code == 0
    import json

    doc = json.loads(capsys.readouterr().out)
    assert set(doc["channels"]) == set(CHANNELS)
    n_gyro = doc["channels"]["gyro_x"]["terms"]["N"]
    # White noise of std s at rate f: N = s / sqrt(f).
    assert n_gyro["value"] == pytest.approx(1e-3 / 10.0, rel=0.03)
    assert n_gyro["ci_low"] <= n_gyro["value"] <= n_gyro["ci_high"]
    assert len(doc["simulation_check"]["rows"]) == 6 * 5
    assert doc["kalibr"]["gyroscope_noise_density"]["unit"] == "rad/s/sqrt(Hz)"
    html = (tmp_path / "r.html").read_text()
    assert "Simulation check" in html and "Fit self-check" in html
    assert html.count("data:image/png;base64,") == 2
    assert (tmp_path / "plots" / "gyro.png").stat().st_size > 1000
    assert (tmp_path / "plots" / "accel.png").stat().st_size > 1000
    assert (tmp_path / "imu.yaml").read_text().count("_density:") == 2


def _chromium() -> str:
    from conftest import skip_unless_ci

    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        skip_unless_ci("Debian chromium is not installed (scripts/setup installs it)")
    return str(exe)


def test_html_report_renders_in_headless_chromium(tmp_path: Path) -> None:
    """Open the report in a real browser; an inline script records, after load, every image's
    decoded naturalWidth and the number of table rows into the DOM that --dump-dom prints."""
    exe = _chromium()
    rng = np.random.default_rng(4)
    n = 20000
    cols = {name: rng.standard_normal(n) * (1e-3 if name.startswith("gyro") else 1e-2)
            for name in CHANNELS}
    res = characterize(ImuData(cols, 100.0, "browser", "simulated", n))
    from gyrodrift.workflows.characterize import write_outputs

    html = tmp_path / "report.html"
    write_outputs(res, kalibr=kalibr_yaml(res), kalibr_path=None, html_path=str(html),
                  out_dir=None)
    probe = ("<script>window.addEventListener('load', function () {"
             "var w = Array.from(document.images).map(function (i) { return i.naturalWidth; });"
             "var r = document.querySelectorAll('#terms tr').length;"
             "var p = document.createElement('pre'); p.id = 'probe';"
             "p.textContent = 'widths=' + w.join(',') + ';rows=' + r;"
             "document.body.appendChild(p); });</script>")
    text = html.read_text()
    assert text.count("data:image/png;base64,") == 2
    html.write_text(text.replace("</body>", probe + "</body>"))
    out = subprocess.run(
        [exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
         f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=5000",
         "--dump-dom", html.as_uri()],
        capture_output=True, text=True, timeout=120, check=False)
    m = re.search(r"widths=([0-9,]*);rows=(\d+)", out.stdout)
    assert m, (out.returncode, out.stderr[-2000:])
    widths = [int(w) for w in m.group(1).split(",") if w]
    assert len(widths) == 2 and all(w > 0 for w in widths), widths
    assert int(m.group(2)) == 1 + 6 * 5  # header + 6 channels x 5 terms


def test_real_lasergyro_record(lasergyro_path: Path) -> None:
    """The shared vehicle record (engine running): all six channels are read from the PSINS
    file; the IEEE 952 term model cannot describe the vibration hump and tau^-1 slope of the
    gyros, which the result must say (band_scale > 1) rather than hide behind narrow
    intervals."""
    from gyrodrift.io.imu_data import load_imu

    rec = load_imu(lasergyro_path)
    assert rec.names == CHANNELS and rec.rate_hz == pytest.approx(100.0)
    assert rec.n == 184718
    res = characterize(rec)
    for c in res.channels:
        for t in c.terms.values():
            assert t.ci_low <= t.value <= t.ci_high
        if c.sensor == "gyro":
            assert c.extra["band_scale"] > 2.0, c.channel
    # The z gyro sees the vertical Earth rate, 7.292115e-5 sin(34.246 deg) rad/s, as its mean.
    z_mean = float(np.mean(rec.channels["gyro_z"]))
    assert z_mean == pytest.approx(7.292115e-5 * math.sin(math.radians(34.246048)), rel=0.05)


def test_gmwm_method_converts_units(monkeypatch: pytest.MonkeyPatch) -> None:
    """--identifier gmwm goes through gyrodrift.identify_gmwm (the published API, results in
    IEEE units of the deg/h record unit). A stand-in returning known values checks the channel
    scaling and the conversions back to SI; without the function the error is clear."""
    import gyrodrift
    from gyrodrift.workflows.characterize import characterize_channel

    x = np.random.default_rng(0).standard_normal(4000) * 1e-3
    if not hasattr(gyrodrift, "identify_gmwm"):
        with pytest.raises(ValueError, match="identify_gmwm"):
            characterize_channel(x, 100.0, "gyro_x", method="gmwm")

    class P:
        def __init__(self, name: str, value: float) -> None:
            self.name, self.value, self.ci_low, self.ci_high, self.unit = (
                name, value, 0.5 * value, 2.0 * value, "")

    seen = {}

    def fake(xd, rate_hz, *, ci):
        seen["x"] = xd
        tau = np.array([0.02, 0.04, 0.08])  # a wavelet variance the model describes exactly
        implied = {"N": 0.3, "N_ci_low": 0.15, "N_ci_high": 0.6, "K": 12.0, "K_ci_low": 6.0,
                   "K_ci_high": 24.0, "K_resolved": 1.0, "K_upper_limit": 30.0}
        return type("R", (), {"model": "N+K", "params": (P("N", 0.3), P("K", 12.0)),
                              "tau_s": tau, "wv": 1.0 / tau, "wv_fit": 1.0 / tau,
                              "rate_hz": rate_hz, "n_samples": xd.size, "objective": 0.5,
                              "implied": lambda self: implied})()

    monkeypatch.setattr(gyrodrift.stability.gmwm, "identify_gmwm", fake)
    c = characterize_channel(x, 100.0, "gyro_x", method="gmwm")
    # The gyro channel goes in as deg/h.
    np.testing.assert_allclose(seen["x"], x * 180.0 / math.pi * 3600.0, rtol=1e-15)
    # N 0.3 deg/sqrt(h) -> rad/s/sqrt(Hz); K 12 deg/h/sqrt(h) -> rad/s^2/sqrt(Hz) (by hand).
    assert c.terms["N"].value == pytest.approx(0.3 * math.pi / 180.0 / 60.0, rel=1e-12)
    assert c.terms["K"].value == pytest.approx(12.0 * math.pi / 180.0 / 3600.0 / 60.0,
                                               rel=1e-12)
    assert c.terms["K"].ci_high == pytest.approx(2.0 * c.terms["K"].value, rel=1e-12)
    # An accelerometer channel goes in unscaled: N 0.3 (m/s^2) sqrt(h) -> 18 m/s^2/sqrt(Hz).
    a = characterize_channel(x, 100.0, "accel_x", method="gmwm")
    np.testing.assert_allclose(seen["x"], x, rtol=0)
    assert a.terms["N"].value == pytest.approx(0.3 * 60.0, rel=1e-12)
    assert a.check is not None and a.check.holds and a.check.what == "wavelet variance"


def test_gmwm_method_with_the_real_identify_gmwm() -> None:
    """--identifier gmwm end to end with the package's GMWM (not a stand-in): white gyro noise of a
    known density is identified as model N, and the density's 95 % interval holds the truth."""
    from gyrodrift.workflows.characterize import characterize_channel

    rate_hz, n_true = 100.0, 1e-4  # rad/s/sqrt(Hz)
    x = np.random.default_rng(3).standard_normal(2**14) * n_true * math.sqrt(rate_hz)
    c = characterize_channel(x, rate_hz, "gyro_x", method="gmwm", ci=0.95)
    assert c.method == "gmwm" and c.extra["model"] == "N"
    n = c.terms["N"]
    assert n.ci_low <= n_true <= n.ci_high
    assert n.value == pytest.approx(n_true, rel=0.05)
    # No random walk in the record: K is not resolved, and its interval's top is the upper
    # limit the wavelet variance allows (positive), not a zero a Kalibr file would pass on.
    k = c.terms["K"]
    assert k.value == 0.0 and k.ci_high > 0.0
    assert k.ci_high == pytest.approx(c.extra["k_upper_limit"], rel=1e-12)


def test_gmwm_white_noise_in_a_short_gauss_markov_term_is_exported_as_density() -> None:
    """A GMWM model whose white noise sits in a Gauss-Markov term faster than the shortest
    scale (GM alone on white noise filtered over 2 samples) still exports a noise density: the
    implied N, within 10 % of the generating one, not 0 (which the Kalibr export refuses)."""
    from gyrodrift.stability.gmwm import identify_gmwm
    from gyrodrift.workflows.characterize import characterize_channel

    rate_hz, n_true = 100.0, 1e-4  # rad/s/sqrt(Hz)
    w = np.random.default_rng(5).standard_normal(2**15 + 1) * n_true * math.sqrt(rate_hz)
    x = 0.5 * (w[1:] + w[:-1])  # gain 1 at 0 Hz: the same density there, correlated over 2 samples
    s = 180.0 / math.pi * 3600.0
    assert identify_gmwm(x * s, rate_hz, model="GM").implied()["N"] > 0.0
    c = characterize_channel(x, rate_hz, "gyro_x", method="gmwm", ci=0.95)
    assert c.terms["N"].value == pytest.approx(n_true, rel=0.10)


def test_kalibr_warns_when_an_axis_has_no_white_noise_term() -> None:
    """An axis whose fitted model has no white-noise term (N = 0) drops out of the worst-axis
    choice: the exported density came from the other axes without a word (seen with GMWM on
    the shared laser-gyro record, whose x and y white noise sat in a 6-sample Gauss-Markov
    term). The export now says so."""
    import dataclasses

    from gyrodrift.workflows.characterize import characterize, kalibr_warnings

    rng = np.random.default_rng(4)
    rec = ImuData({"gyro_x": rng.normal(0, 1e-4, 4096), "gyro_z": rng.normal(0, 3e-5, 4096)},
                  rate_hz=100.0, source="bench", fmt="npy", n_total=4096)
    res = characterize(rec)
    assert kalibr_warnings(res) == []
    x = res.channel("gyro_x")
    no_n = dataclasses.replace(x, terms={**x.terms, "N": dataclasses.replace(
        x.terms["N"], value=0.0, ci_low=0.0, ci_high=0.0)})
    hidden = dataclasses.replace(res, channels=(no_n, res.channel("gyro_z")))
    warns = kalibr_warnings(hidden)
    assert any("gyro_x's model has no white-noise term" in w for w in warns), warns
    assert kalibr_warnings(hidden, axis="z") == []
