"""`gyrodrift fit`: table/JSON of the three models, the chosen one, the filter, the written
configuration (issue-12 TOML schema v1, parsed here with tomllib) and one-line errors."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
import tomllib
from gyrodrift.cli import main
from gyrodrift.filters.drift_model import compare_drift_models
from scipy.signal import lfilter


@pytest.fixture(scope="module")
def record(tmp_path_factory: pytest.TempPathFactory) -> Path:
    rng = np.random.default_rng(3)
    x = lfilter([1.0], [1.0, -0.6868, 0.0213], rng.normal(0, 0.5, 6000))
    path = tmp_path_factory.mktemp("fit") / "drift.npy"
    np.save(path, 9.7 + x + rng.normal(0, 0.3, 6000))
    return path


def test_fit_json_and_toml(record: Path, tmp_path: Path,
                           capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "gyro.toml"
    assert main(["fit", str(record), "--rate-hz", "100", "--json", "-o", str(out),
                 "--gyro-units", "deg/h"]) == 0
    payload = json.loads(capsys.readouterr().out)
    ref = compare_drift_models(np.load(record), 100.0)
    assert payload["chosen"] == ref.chosen and payload["criterion"] == "aic"
    assert [f["model"] for f in payload["fits"]] == ["ar2+white", "ar1+white", "white"]
    best = ref.best
    assert payload["filter"]["dc_gain"] == pytest.approx(best.response().dc_gain)
    cfg = tomllib.loads(out.read_text())
    assert cfg["schema"] == "gyrodrift.processor" and cfg["version"] == 1
    assert cfg["timing"]["sample_rate_hz"] == 100.0
    stage = cfg["channels"]["gx"]["stages"][0]
    k = math.pi / 180 / 3600
    assert stage["type"] == "ar2_kalman" and stage["steady_state"] is True
    assert stage["a1"] == best.a1 and stage["a2"] == best.a2
    assert stage["q"] == pytest.approx(best.q * k * k, rel=1e-15)
    assert stage["r"] == pytest.approx(best.r * k * k, rel=1e-15)
    assert stage["mean_rad_s"] == pytest.approx(best.mean * k, rel=1e-15)
    assert set(cfg["channels"]) == {"gx", "gy", "gz", "ax", "ay", "az"}
    assert cfg["channels"]["ay"]["stages"][0]["type"] == "pass_through"


def test_fit_table_and_bic(record: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["fit", str(record), "--rate-hz", "100", "--criterion", "bic",
                 "--gyro-units", "deg/h"]) == 0
    text = capsys.readouterr().out
    assert "chosen:" in text and "(lowest BIC)" in text and "-3 dB bandwidth" in text
    for model in ("ar2+white", "ar1+white", "white"):
        assert model in text


def test_fit_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    const = tmp_path / "const.npy"
    np.save(const, np.full(100, 3.0))
    assert main(["fit", str(const), "--rate-hz", "10", "--gyro-units", "deg/h"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "constant" in err
    rec = tmp_path / "ok.npy"
    np.save(rec, np.random.default_rng(0).normal(size=200))
    assert main(["fit", str(rec), "--rate-hz", "10", "-o", str(tmp_path / "x.yaml"),
                 "--gyro-units", "deg/h"]) == 2
    assert "suffix" in capsys.readouterr().err


def test_fit_filter_failure_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """Regression: a filter that cannot be built (a steady-state recursion that does not
    converge) ended `gyrodrift fit` in a traceback; it is a one-line error, exit 2."""
    from gyrodrift.filters.drift_model import DriftModelFit

    def no_filter(self: DriftModelFit) -> None:
        raise ValueError("Ar2SteadyStateKalman: not converged")

    monkeypatch.setattr(DriftModelFit, "response", no_filter)
    rec = tmp_path / "white.npy"
    np.save(rec, np.random.default_rng(2).normal(size=2000))
    assert main(["fit", str(rec), "--rate-hz", "100", "--gyro-units", "deg/h"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not converged" in err


def test_demo_yardstick_rows(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--duration-s", "300", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["yardstick"]["rows"]
    assert list(rows) == ["raw", "papers' tuning", "ML tuning", "true model"]
    mse = {k: v["mse_vs_drift_deg_h_sq"] for k, v in rows.items()}
    # The true model is the optimum; ML within 10 % of it; the papers' tuning no better than raw
    # on this record (the finding), both clearly worse than ML.
    assert mse["true model"] <= mse["ML tuning"] <= 1.10 * mse["true model"]
    assert mse["papers' tuning"] > 1.2 * mse["ML tuning"]
    assert mse["raw"] > 1.2 * mse["ML tuning"]
    for row in rows.values():
        assert row["std_deg_h"] > 0 and row["adev_1s_deg_h"] > 0


def test_config_uses_the_minimax_tuning_when_not_identified() -> None:
    # A near-white record (-0.0340/0.0252, r/q = 1): the fit cannot split drift from white
    # noise, so the written stage is the q = r tuning (filter_params), not the raw ML q, r.
    from gyrodrift.cli.fit import config_toml
    from gyrodrift.filters.drift_model import fit_drift_model

    rng = np.random.default_rng(200)
    x = lfilter([1.0], [1.0, 0.0340, -0.0252], rng.normal(0.0, 1.0, 22000))[2000:]
    fit = fit_drift_model(9.7 + x + rng.normal(0.0, 1.0, 20000), rate_hz=100.0)
    assert not fit.identified
    cfg = tomllib.loads(config_toml(fit, 100.0, "gx", "near_white.npy"))
    stage = cfg["channels"]["gx"]["stages"][0]
    k = math.pi / 180 / 3600
    a1, a2, q, _ = fit.filter_params
    assert cfg["meta"]["tuning"] == "minimax-split"
    assert stage["a1"] == a1 and stage["a2"] == a2
    assert stage["q"] == pytest.approx(q * k * k, rel=1e-15)
    assert stage["r"] == pytest.approx(stage["q"], rel=1e-9)  # q = r


def test_fit_reports_the_maximum_across_a2_zero(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    # 0.6868/-0.0213, r/q = 1, 6000 samples (short enough that fit does not decimate), seed 6:
    # AIC chooses AR(2) + white at a2 about +0.12, with a second maximum across a2 = 0 near
    # -0.16, 0.64 log-likelihood units lower: the table says so, the JSON carries it.
    rng = np.random.default_rng(6)
    x = lfilter([1.0], [1.0, -0.6868, 0.0213], rng.normal(size=8000))[2000:]
    path = tmp_path / "fold.npy"
    np.save(path, 9.7 + x + rng.normal(0.0, 1.0, 6000))
    args = ["fit", str(path), "--rate-hz", "100", "--gyro-units", "deg/h"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "chosen: ar2+white" in text
    assert "a2 next to the fold a2 = 0: a second maximum across it at a2 -0.1" in text
    assert "NOT identified: maxima on both sides" not in text
    assert main([*args, "--json"]) == 0
    ar2 = json.loads(capsys.readouterr().out)["fits"][0]
    assert ar2["model"] == "ar2+white" and ar2["ar_identified"] is True
    assert ar2["a2"] > 0.05 and ar2["fold_a2"] < -0.05
    assert 0.3 < ar2["loglike"] - ar2["fold_loglike"] < 1.0


def test_fit_configuration_records_the_fold(tmp_path: Path, cpp_build_dir: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """The configuration's [meta] carries what `gyrodrift fit` prints about the fold a2 = 0
    (ar_identified, fold_a2, fold_loglike: the JSON's values, exact through TOML's shortest
    round-trip floats), and both readers (Python's and the loop's) still accept the file; a
    fit with no second maximum writes ar_identified alone."""
    from gyrodrift.cli.fit import config_toml
    from gyrodrift.filters.drift_model import fit_drift_model
    from gyrodrift.imu.config import load_config
    from gyrodrift.replay.harness import LOOP_RELATIVE

    rng = np.random.default_rng(6)  # the record of test_fit_reports_the_maximum_across_a2_zero
    x = lfilter([1.0], [1.0, -0.6868, 0.0213], rng.normal(size=8000))[2000:]
    path = tmp_path / "fold.npy"
    np.save(path, 9.7 + x + rng.normal(0.0, 1.0, 6000))
    out = tmp_path / "fold.toml"
    assert main(["fit", str(path), "--rate-hz", "100", "--gyro-units", "deg/h", "--json",
                 "-o", str(out)]) == 0
    ar2 = json.loads(capsys.readouterr().out)["fits"][0]
    assert ar2["model"] == "ar2+white" and math.isfinite(ar2["fold_a2"])
    meta = tomllib.loads(out.read_text())["meta"]
    assert meta["ar_identified"] is True
    assert (meta["fold_a2"], meta["fold_loglike"]) == (ar2["fold_a2"], ar2["fold_loglike"])
    assert dict(load_config(out).meta)["fold_a2"] == ar2["fold_a2"]
    loop = subprocess.run([str(cpp_build_dir / LOOP_RELATIVE), "--check-config", str(out)],
                          capture_output=True, text=True, timeout=10)
    assert (loop.returncode, loop.stdout, loop.stderr) == (0, f"{out}: ok\n", "")

    white = fit_drift_model(np.random.default_rng(0).normal(0.5, 1.0, 1000), 100.0, "white")
    assert math.isnan(white.fold_loglike)
    meta = tomllib.loads(config_toml(white, 100.0, "gx", "white.npy"))["meta"]
    assert meta["ar_identified"] is True and "fold_a2" not in meta
