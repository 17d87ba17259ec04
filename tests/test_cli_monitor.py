"""`gyrodrift monitor`: one-line argument errors, the JSON lines (schema, units checked with
independent arithmetic), the reference (learned from --learn-s, or the configuration's drift
model, whose Allan variance is checked against the autocovariance sum), the arw_high alarm
after a 2x angle-random-walk step and not before, the plot, the exit code of --fail-on-alarm."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.cli import main
from gyrodrift.imu.config import drift_filter_config, write_config
from gyrodrift.imu.monitor import MonitorTrace, reference_from_record
from gyrodrift.report.monitor import segment_fits, trace_rows

RATE_HZ = 100.0
#: one deg/h in rad/s, and one rad/sqrt(s) in deg/sqrt(h), written out (not from gyrodrift.units)
DEG_H = math.pi / 180.0 / 3600.0
RT_S_TO_RT_H = 180.0 / math.pi * 60.0


@pytest.fixture(scope="module")
def records(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """White-noise records in deg/h at 100 Hz: 'steady' (1 deg/h per sample, 240 s) and
    'step' (1 deg/h for 150 s, then 2 deg/h: the angle random walk doubles)."""
    d = tmp_path_factory.mktemp("monitor")
    rng = np.random.default_rng(11)
    steady = rng.normal(0.0, 1.0, 24000)
    step = rng.normal(0.0, 1.0, 48000)
    step[15000:] *= 2.0
    out = {"steady": d / "steady.npy", "step": d / "step.npy", "dir": d}
    np.save(out["steady"], steady)
    np.save(out["step"], step)
    return out


def _fails(argv: list[str], capsys: pytest.CaptureFixture[str], *words: str) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("gyrodrift monitor: error:"), err
    for w in words:
        assert w in err, err


def test_argument_errors_are_one_line(records: dict[str, Path], tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    rec = str(records["steady"])
    base = ["monitor", rec, "--rate-hz", "100", "--gyro-units", "deg/h"]
    # 240 s: too short for the default 600 s learning span plus a report
    _fails(base, capsys, "shorter than the learning span", "600")
    _fails([*base, "--learn-s", "235", "--report-every-s", "10"], capsys, "235 + 10")
    _fails([*base, "--learn-s", "0"], capsys, "--learn-s")
    _fails([*base, "--learn-s", "nan"], capsys, "--learn-s")
    _fails([*base, "--report-every-s", "-5"], capsys, "--report-every-s")
    _fails([*base, "--report-every-s", "300"], capsys, "shorter than one report interval")
    _fails(["monitor", rec, "--rate-hz", "100"], capsys, "--gyro-units")
    _fails([*base, "--learn-s", "60", "--png", str(tmp_path / "m.txt")], capsys,
           "unsupported file type")
    _fails([*base, "--config", str(tmp_path / "missing.toml")], capsys, "missing.toml")
    # a configuration whose gyro channel has no drift model, one for another rate
    cfg = tmp_path / "gz.toml"
    write_config(drift_filter_config("gz", a1=0.5, a2=0.2, mean=0.0, q=1e-12, r=1e-10,
                                     sample_rate_hz=RATE_HZ), cfg)
    _fails([*base, "--config", str(cfg)], capsys, "'gx' is not monitored")
    cfg400 = tmp_path / "gx400.toml"
    write_config(drift_filter_config("gx", a1=0.5, a2=0.2, mean=0.0, q=1e-12, r=1e-10,
                                     sample_rate_hz=400.0), cfg400)
    _fails([*base, "--config", str(cfg400)], capsys, "400 Hz", "100 Hz")


def _trace() -> MonitorTrace:
    n = 2
    one = np.ones(n)
    return MonitorTrace(
        t_s=np.array([10.0, 20.0]), n=2e-6 * one, n_lo=1.5e-6 * one, n_hi=3e-6 * one,
        b=5e-7 * one, b_lo=np.array([math.nan, 4e-7]), b_hi=6e-7 * one,
        k=np.array([math.nan, 3e-8]), k_lo=np.array([math.nan, 2e-8]), k_hi=4e-8 * one,
        k_upper_limit=np.array([True, False]), a1=np.array([0.5, 0.6]), a2=0.1 * one,
        q=1e-14 * one, r=2e-10 * one, mean=1e-6 * one, gain0=0.2 * one, gain1=0.1 * one,
        status=("configured", "retuned"), health=np.array([0, 0b101], dtype=np.uint16),
        alarm_names=("arw_high", "bias_instability_high", "rate_random_walk_high", "stuck",
                     "saturated"),
        trips={"arw_high": {"statistic": 1.9, "threshold": 1.4, "tau_s": 0.01, "t_s": 20.0},
               "rate_random_walk_high": {"statistic": 3.0, "threshold": 2.0, "tau_s": 5.0,
                                         "t_s": 20.0}})


def test_rows_convert_to_ieee_units() -> None:
    """The trace (rad/s base) as JSON rows: N rad/sqrt(s) * 180/pi * 60 = deg/sqrt(h);
    B rad/s / (pi/180/3600) = deg/h; K rad/s/sqrt(s) * 180/pi * 3600 * 60 = deg/h/sqrt(h);
    q, r (rad/s)^2 / (pi/180/3600)^2 = (deg/h)^2. Same-formula products: 1e-14 relative."""
    rows = trace_rows(_trace())
    r0, r1 = rows
    rel = 1e-14
    assert r0["t_s"] == 10.0 and r1["t_s"] == 20.0
    assert r0["n_deg_rt_h"] == pytest.approx(2e-6 * RT_S_TO_RT_H, rel=rel)
    assert r0["n_lo_deg_rt_h"] == pytest.approx(1.5e-6 * RT_S_TO_RT_H, rel=rel)
    assert r0["n_hi_deg_rt_h"] == pytest.approx(3e-6 * RT_S_TO_RT_H, rel=rel)
    assert r0["b_deg_h"] == pytest.approx(5e-7 / DEG_H, rel=rel)
    assert r0["b_lo_deg_h"] is None and r1["b_lo_deg_h"] == pytest.approx(4e-7 / DEG_H, rel=rel)
    assert r0["k_deg_h_rt_h"] is None and r0["k_upper_limit"] is True
    assert r0["k_hi_deg_h_rt_h"] == pytest.approx(4e-8 / DEG_H * 60.0, rel=rel)
    assert r1["k_deg_h_rt_h"] == pytest.approx(3e-8 / DEG_H * 60.0, rel=rel)
    assert r1["k_upper_limit"] is False
    assert r0["q_deg_h_sq"] == pytest.approx(1e-14 / DEG_H ** 2, rel=rel)
    assert r0["r_deg_h_sq"] == pytest.approx(2e-10 / DEG_H ** 2, rel=rel)
    assert r0["mean_deg_h"] == pytest.approx(1e-6 / DEG_H, rel=rel)
    assert (r0["a1"], r1["a1"], r0["a2"], r0["gain"]) == (0.5, 0.6, 0.1, [0.2, 0.1])
    assert (r0["status"], r1["status"]) == ("configured", "retuned")
    assert r0["health"] == [] and r0["trips"] == {}
    assert r1["health"] == ["arw_high", "rate_random_walk_high"]
    assert r1["trips"]["arw_high"]["statistic"] == 1.9
    json.dumps(rows, allow_nan=False)  # strict JSON as they are


def test_segment_fits_of_a_step(records: dict[str, Path]) -> None:
    """The offline fit of each half of the step record: N = sigma sqrt(dt) in deg/sqrt(h)
    (1 deg/h and 2 deg/h per sample at 100 Hz: 1/60 * 0.1 and twice that); within 5 % (edf
    of the N term above 1e4 per half)."""
    y = np.load(records["step"]) * DEG_H
    first, second = segment_fits(y, RATE_HZ, [(0.0, 150.0), (150.0, 480.0)])
    assert first.n_deg_rt_h == pytest.approx(0.1 / 60.0, rel=0.05)
    assert second.n_deg_rt_h == pytest.approx(0.2 / 60.0, rel=0.05)
    assert first.n_lo_deg_rt_h < first.n_deg_rt_h < first.n_hi_deg_rt_h
    (short,) = segment_fits(y, RATE_HZ, [(0.0, 0.05)])  # 5 samples: no fit
    assert math.isnan(short.n_deg_rt_h)


# ---------------------------------------------------------------- the command over the core

KEYS = {"t_s", "n_deg_rt_h", "n_lo_deg_rt_h", "n_hi_deg_rt_h", "b_deg_h", "b_lo_deg_h",
        "b_hi_deg_h", "k_deg_h_rt_h", "k_lo_deg_h_rt_h", "k_hi_deg_h_rt_h", "k_upper_limit",
        "a1", "a2", "q_deg_h_sq", "r_deg_h_sq", "mean_deg_h", "gain", "status", "health",
        "trips", "identifier", "fit_status"}


def _lines(out: str) -> list[dict[str, object]]:
    return [json.loads(line) for line in out.splitlines()]


def test_json_lines_one_per_report(records: dict[str, Path],
                                   capsys: pytest.CaptureFixture[str]) -> None:
    """240 s, a report every 20 s: 12 lines with the fields and the units of the table; N of
    1 deg/h white noise at 100 Hz is 1/600 deg/sqrt(h) (the online interval holds it, or the
    estimate is within 10 % of it: the Allan variance at tau0 over 24000 samples has edf
    ~ 16000, 1 %)."""
    assert main(["monitor", str(records["steady"]), "--rate-hz", "100", "--gyro-units", "deg/h",
                 "--learn-s", "60", "--report-every-s", "20", "--json"]) == 0
    rows = _lines(capsys.readouterr().out)
    assert [r["t_s"] for r in rows] == pytest.approx([20.0 * k for k in range(1, 13)])
    for r in rows:
        assert set(r) >= KEYS, KEYS - set(r)
        assert isinstance(r["health"], list)
    last = rows[-1]
    assert last["n_deg_rt_h"] == pytest.approx(1.0 / 600.0, rel=0.1)
    assert last["health"] == []


def test_config_reference_and_table(records: dict[str, Path], tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    """--config: the model the rows report before any retuning is the configuration's, in
    (deg/h)^2; the text table has a row per report and says the health."""
    cfg = tmp_path / "gx.toml"
    q, r = 1e-4 * DEG_H ** 2, 1.0 * DEG_H ** 2
    write_config(drift_filter_config("gx", a1=0.5, a2=0.2, mean=0.0, q=q, r=r,
                                     sample_rate_hz=RATE_HZ), cfg)
    argv = ["monitor", str(records["steady"]), "--rate-hz", "100", "--gyro-units", "deg/h",
            "--config", str(cfg), "--report-every-s", "40"]
    assert main([*argv, "--json"]) == 0
    rows = _lines(capsys.readouterr().out)
    assert len(rows) == 6
    assert rows[0]["a1"] == 0.5 and rows[0]["a2"] == 0.2
    assert rows[0]["q_deg_h_sq"] == pytest.approx(1e-4, rel=1e-12)
    assert rows[0]["r_deg_h_sq"] == pytest.approx(1.0, rel=1e-12)
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "reference from the configuration" in text
    assert sum(1 for line in text.splitlines() if line.strip().startswith(("40 ", "240 "))) == 2


def test_arw_step_raises_arw_high_after_the_change_and_not_before(
        records: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """1 deg/h white noise for 150 s, then 2 deg/h (angle random walk x2): the reference is
    learned from the first 60 s; no report up to the change carries arw_high, the last one
    does. --fail-on-alarm: exit 3 after writing the outputs; --png writes a PNG."""
    png = tmp_path / "monitor.png"
    argv = ["monitor", str(records["step"]), "--rate-hz", "100", "--gyro-units", "deg/h",
            "--learn-s", "60", "--report-every-s", "10", "--json", "--png", str(png)]
    assert main([*argv, "--fail-on-alarm"]) == 3
    captured = capsys.readouterr()
    assert captured.err.strip() == "gyrodrift monitor: alarm raised: arw_high"
    rows = _lines(captured.out)
    before = [r for r in rows if float(r["t_s"]) <= 150.0]  # type: ignore[arg-type]
    assert before and all("arw_high" not in r["health"] for r in before)  # type: ignore[operator]
    assert "arw_high" in rows[-1]["health"]  # type: ignore[operator]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    assert main(argv) == 0  # without --fail-on-alarm the alarm is reported, not the exit code
    capsys.readouterr()


def test_rows_without_reidentification_report_the_reference_model() -> None:
    """While the re-identification is off the trace's model is NaN; the rows give the
    reference's model and its steady-state gain: K = P H^T / (H P H^T + r) with P the
    predicted covariance of the discrete algebraic Riccati equation (scipy), 1e-9 relative
    (the C++ solver iterates to convergence)."""
    import dataclasses

    from gyrodrift.imu.monitor import MonitorReference
    from scipy.linalg import solve_discrete_are

    a1, a2, q, r, mean = 0.6, 0.2, 2e-12, 5e-10, 3e-6
    nan = np.full(2, math.nan)
    tr = dataclasses.replace(
        _trace(), a1=nan, a2=nan, q=nan, r=nan, mean=nan, gain0=nan, gain1=nan,
        status=("off", "off"),
        reference=MonitorReference(drift=(a1, a2, q, r, mean), avar=np.ones(3)))
    f = np.array([[a1, a2], [1.0, 0.0]])
    h = np.array([[1.0, 0.0]])
    # the gain depends on q / r only: scipy's solver is given r = 1 (at variances of 1e-12
    # its own result is off by 1e-5 relative)
    p = solve_discrete_are(f.T, h.T, np.diag([q / r, 0.0]), np.array([[1.0]]))
    gain = (p @ h.T / (h @ p @ h.T + 1.0)).ravel()
    for row in trace_rows(tr):
        assert (row["a1"], row["a2"], row["status"]) == (a1, a2, "off")
        assert row["q_deg_h_sq"] == pytest.approx(q / DEG_H ** 2, rel=1e-14)
        assert row["r_deg_h_sq"] == pytest.approx(r / DEG_H ** 2, rel=1e-14)
        assert row["mean_deg_h"] == pytest.approx(mean / DEG_H, rel=1e-14)
        np.testing.assert_allclose(row["gain"], gain, rtol=1e-9)


def test_learn_s_sets_the_reference(records: dict[str, Path],
                                    capsys: pytest.CaptureFixture[str]) -> None:
    """Without --config the model reported (the re-identification is off by default, so the
    filter runs the reference) is the one learned from the first --learn-s seconds:
    reference_from_record on those samples in rad/s (same arithmetic: 1e-12 relative)."""
    x = np.load(records["steady"])
    for learn_s in (60.0, 120.0):
        ref = reference_from_record(x * DEG_H, RATE_HZ, learn_s, 16)
        assert main(["monitor", str(records["steady"]), "--rate-hz", "100", "--gyro-units",
                     "deg/h", "--learn-s", str(learn_s), "--report-every-s", "60",
                     "--json"]) == 0
        rows = _lines(capsys.readouterr().out)
        assert rows[0]["status"] == "off"
        a1, a2, q, r, mean = ref.drift
        assert rows[0]["a1"] == pytest.approx(a1, rel=1e-12)
        assert rows[0]["a2"] == pytest.approx(a2, rel=1e-12)
        assert rows[-1]["q_deg_h_sq"] == pytest.approx(q / DEG_H ** 2, rel=1e-12)
        assert rows[-1]["r_deg_h_sq"] == pytest.approx(r / DEG_H ** 2, rel=1e-12)
        assert rows[-1]["mean_deg_h"] == pytest.approx(mean / DEG_H, rel=1e-12)


def test_replay_report_plots_the_monitor(tmp_path: Path, cpp_build_dir: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    """A replay whose configuration enables the monitor: report.json carries the monitor's
    reports per monitored channel (one a second over 4 s) and the host run's alarms beside
    the loop's counters (equal where the loop reports them); monitor-gz.png is written and
    named in the output. Without the monitor enabled neither appears."""
    from gyrodrift.replay.harness import LOOP_RELATIVE

    cfg = drift_filter_config("gz", a1=1.0, a2=-0.25, mean=0.0, q=1e-10, r=1e-8,
                              sample_rate_hz=400.0)
    on, off = tmp_path / "on.toml", tmp_path / "off.toml"
    write_config(cfg.with_monitor(enabled=True, report_interval_s=1.0), on)
    write_config(cfg, off)
    loop = str(cpp_build_dir / LOOP_RELATIVE)
    for config, out in ((on, tmp_path / "on"), (off, tmp_path / "off")):
        assert main(["replay", "--duration-s", "4", "--fast", "--no-rt", "--loop-binary", loop,
                     "--config", str(config), "--out-dir", str(out)]) == 0
    text = capsys.readouterr().out
    rep = json.loads((tmp_path / "on" / "report.json").read_text())
    mon = rep["monitor"]
    assert list(mon["channels"]) == ["gz"] and mon["channels"]["gz"]["reports"] == 4
    assert mon["channels"]["gz"]["last"]["t_s"] == 4.0
    assert set(mon["alarms_host"]) == {"arw_high", "bias_instability_high",
                                       "rate_random_walk_high", "stuck", "saturated"}
    assert mon["agree"] in (None, True), mon
    png = tmp_path / "on" / "monitor-gz.png"
    assert png.read_bytes()[:4] == b"\x89PNG" and str(png) in text
    assert "monitor gz" in text
    assert "monitor" not in json.loads((tmp_path / "off" / "report.json").read_text())
    assert not list((tmp_path / "off").glob("monitor*.png"))


# ---------------------------------------------------------------- the lag identifier


def test_reidentify_lag_retunes_to_the_offline_fit_of_the_same_samples(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--reidentify lag over 25 min at 50 Hz of the papers' AR(2) drift (0.2297, 0.1638),
    q = r = 1 (deg/h)^2, mean 3 deg/h, from a configured model off by 2x (q, r) and in a1:
    a fit every 300 s (the first after min_learn_s = 300 s), applied fit_delay_s = 10 s
    later, so the row at 300 k + 10 s is the first with k retunes; max_step 10, so the model
    in use is the fit. The k-th fit reads the samples before its request except those paused
    while the earlier fits ran (10 s each), and equals `fit_drift_model` of exactly those
    samples (concatenated) within 0.1 of the offline standard errors in a1, a2, q, r and the
    mean: the fit maximises Whittle's likelihood of lag statistics to L = 8 in float (within
    0.07 standard errors of the exact fit on the validation records; observed here 0.011)."""
    from gyrodrift.filters.drift_model import fit_drift_model
    from scipy.signal import lfilter

    rate, n = 50.0, 75000
    rng = np.random.default_rng(21)
    y = lfilter([1.0], [1.0, -0.2297, -0.1638], rng.normal(0.0, 1.0, n)) + \
        rng.normal(0.0, 1.0, n) + 3.0
    rec = tmp_path / "gyro.npy"
    np.save(rec, y)
    cfg = tmp_path / "lag.toml"
    write_config(drift_filter_config("gz", a1=0.5, a2=0.1, mean=0.0, q=2.0 * DEG_H ** 2,
                                     r=0.5 * DEG_H ** 2, sample_rate_hz=rate).with_monitor(
        octaves=10, report_interval_s=10.0, retune_s=300.0, fit_delay_s=10.0,
        min_learn_s=300.0, max_step=10.0), cfg)
    assert main(["monitor", str(rec), "--rate-hz", "50", "--gyro-units", "deg/h", "--config",
                 str(cfg), "--channel", "gz", "--reidentify", "lag", "--json"]) == 0
    rows = {round(float(r["t_s"])): r for r in _lines(capsys.readouterr().out)}
    assert len(rows) == 150 and all(r["identifier"] == "lag" for r in rows.values())
    first = rows[300]
    assert (first["status"], first["fit_status"], first["retunes"]) == (
        "learning", "too_few_samples", 0)
    assert (first["a1"], first["q_deg_h_sq"]) == (0.5, pytest.approx(2.0, rel=1e-6))
    cadence, delay = 15000, 500  # samples
    for k in range(1, 5):
        before, after = rows[300 * k], rows[300 * k + 10]
        assert (before["retunes"], after["retunes"], after["refused_retunes"]) == (k - 1, k, 0)
        assert (after["status"], after["fit_status"]) == ("tracking", "ok")
        keep = np.ones(k * cadence, dtype=bool)
        for j in range(1, k):
            keep[j * cadence:j * cadence + delay] = False
        fit = fit_drift_model(y[:k * cadence][keep], rate)
        got = {"a1": after["a1"], "a2": after["a2"], "q": after["q_deg_h_sq"],
               "r": after["r_deg_h_sq"], "mean": after["mean_deg_h"]}
        for name, value in got.items():
            z = (value - getattr(fit, name)) / fit.stderr[name]
            assert abs(z) < 0.1, (k, name, value, getattr(fit, name), z)


def test_reidentify_options_and_their_errors(records: dict[str, Path], tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """--reidentify recursive reports the recursive identifier (no fit status); without it and
    without --config the re-identification is off; a configuration whose fit_delay_s exceeds
    its retune_s is refused for the lag identifier in one line naming both fields."""
    rec = str(records["steady"])
    base = ["monitor", rec, "--rate-hz", "100", "--gyro-units", "deg/h", "--learn-s", "60",
            "--report-every-s", "60", "--json"]
    assert main(base) == 0
    rows = _lines(capsys.readouterr().out)
    assert {(r["status"], r["fit_status"]) for r in rows} == {("off", None)}
    assert main([*base, "--reidentify", "recursive"]) == 0
    rows = _lines(capsys.readouterr().out)
    assert {r["identifier"] for r in rows} == {"recursive"}
    assert {r["fit_status"] for r in rows} == {None} and rows[0]["status"] == "learning"
    cfg = tmp_path / "slow.toml"
    write_config(drift_filter_config("gx", a1=0.5, a2=0.2, mean=0.0, q=1e-4 * DEG_H ** 2,
                                     r=DEG_H ** 2, sample_rate_hz=RATE_HZ).with_monitor(
        retune_s=30.0, fit_delay_s=40.0), cfg)  # valid for the recursive identifier
    _fails(["monitor", rec, "--rate-hz", "100", "--gyro-units", "deg/h", "--config", str(cfg),
            "--reidentify", "lag"], capsys, "slow.toml: monitor.fit_delay_s:", "retune_s")
