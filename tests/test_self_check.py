"""The fit self-check travels with every output of `allan`, `identify` and `characterize`
(text, JSON, CSV, HTML, Kalibr yaml), `--self-check` turns a model that does not hold into
exit code 3, and the Kalibr export refuses a white-noise density of zero or none.

The misfit record: white noise under a sinusoid of its standard deviation at 0.5 Hz (a
vibration): the Allan deviation then has a hump and dips at multiples of the period that no
sum of IEEE 952 terms follows (the fitted curve leaves the measured one at several taus by
far more than the tolerance). With a sinusoid of 20 standard deviations the fit drops the
white noise altogether (N = 0), the failure a Kalibr export must refuse. The good record:
white noise alone (the model N describes it; the check's band is simultaneous at 95 %, so a
right model fails it rarely, and this seed is fixed)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from gyrodrift.cli import main
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.io.imu_data import ImuData
from gyrodrift.stability.self_check import SELF_CHECK_EXIT
from gyrodrift.workflows.characterize import characterize, kalibr_yaml

RATE_HZ = 100.0
N = 20000


def _white(seed: int = 3) -> np.ndarray:
    return np.random.default_rng(seed).normal(0.0, 1.0, N)


def _vibrating(seed: int = 3, amplitude: float = 1.0) -> np.ndarray:
    t = np.arange(N) / RATE_HZ
    return _white(seed) + amplitude * np.sin(2.0 * np.pi * 0.5 * t)


def _imu(gyro: np.ndarray) -> ImuData:
    rng = np.random.default_rng(7)
    return ImuData({"gyro_x": gyro * 1e-5, "accel_x": rng.normal(0.0, 1e-3, N)}, RATE_HZ,
                   "bench", "npy", N)


# ---------------------------------------------------------------------------------- Kalibr

def test_kalibr_refuses_absent_white_noise_density() -> None:
    # a fit without the N term: before, the yaml went out with no gyro noise density
    res = characterize(_imu(_white()), terms=["B", "K"])
    with pytest.raises(GyrodriftValueError, match=r"gyroscope_noise_density.*no white-noise"):
        kalibr_yaml(res)


def test_kalibr_refuses_zero_white_noise_density() -> None:
    # a white-noise density fitted as zero (e.g. the white noise hidden in another term):
    # before, `gyroscope_noise_density: 0.0` was written with a comment only
    res = characterize(_imu(_white()))
    gx = res.channel("gyro_x")
    zero_n = dataclasses.replace(gx.terms["N"], value=0.0, ci_low=0.0)
    bad = dataclasses.replace(res, channels=(dataclasses.replace(
        gx, terms={**gx.terms, "N": zero_n}), res.channel("accel_x")))
    with pytest.raises(GyrodriftValueError, match=r"gyroscope_noise_density is 0\.0"):
        kalibr_yaml(bad)


def test_characterize_kalibr_refuses_the_zero_density_of_a_vibrating_record(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    yaml_path = tmp_path / "imu.yaml"
    assert _characterize(tmp_path, _vibrating(amplitude=20.0), "--kalibr", str(yaml_path)) == 2
    assert "Kalibr export refused: gyroscope_noise_density is 0.0" in capsys.readouterr().err
    assert not yaml_path.exists()


def test_kalibr_yaml_of_a_misfit_carries_warnings(tmp_path: Path) -> None:
    text = kalibr_yaml(characterize(_imu(_vibrating())))
    head = [line for line in text.splitlines() if line.startswith("# WARNING")]
    assert any("gyro_x: model does not hold" in line for line in head)
    assert any("widened" in line for line in head)
    # the warnings are comments: Kalibr (a YAML reader) sees the four values only
    doc = yaml.safe_load(text)
    assert doc["gyroscope_noise_density"] > 0
    # and they come first, before any value
    lines = text.splitlines()
    first_value = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    assert all(lines.index(line) < first_value for line in head if "gyro_x:" in line)


def test_kalibr_yaml_of_a_good_fit_says_it_holds() -> None:
    text = kalibr_yaml(characterize(_imu(_white())))
    assert "model does not hold" not in text and "widened" not in text
    assert "# fit self-check: every channel's model holds" in text


# ---------------------------------------------------------------------------- characterize

def _save_imu(tmp_path: Path, gyro: np.ndarray) -> Path:
    rng = np.random.default_rng(7)
    arr = np.column_stack([gyro * 1e-5, rng.normal(0.0, 1e-3, N)])
    path = tmp_path / "imu.npy"
    np.save(path, arr)
    return path


def _characterize(tmp_path: Path, gyro: np.ndarray, *extra: str) -> int:
    path = _save_imu(tmp_path, gyro)
    return main(["characterize", str(path), "--rate-hz", str(RATE_HZ), "--gyro-units", "rad/s",
                 "--accel-units", "m/s^2", "--column-channels", "gyro_x,accel_x", *extra])


def test_characterize_self_check_exit_code(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                           ) -> None:
    yaml_path = tmp_path / "imu.yaml"
    html_path = tmp_path / "r.html"
    assert _characterize(tmp_path, _vibrating(), "--kalibr", str(yaml_path), "--html",
                         str(html_path)) == 0  # without --self-check: warned, exit 0
    out = capsys.readouterr().out
    assert "WARNING: gyro_x: model does not hold" in out
    assert "gyro_x self-check: model does NOT hold" in out
    assert "# WARNING: gyro_x: model does not hold" in yaml_path.read_text()
    page = html_path.read_text()
    assert "Fit self-check" in page and "WARNING" in page and "(fails)" in page
    assert _characterize(tmp_path, _vibrating(), "--json", "--self-check") == SELF_CHECK_EXIT
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    chk = doc["channels"]["gyro_x"]["self_check"]
    assert chk["holds"] is False and not all(chk["passed"]) and len(chk["ratio"]) == len(
        doc["channels"]["gyro_x"]["taus"])
    assert doc["holds"] is False and doc["kalibr_warnings"]
    assert "self-check failed" in captured.err and "gyro_x" in captured.err
    # a record the model describes passes
    assert _characterize(tmp_path, _white(), "--self-check") == 0


# ------------------------------------------------------------------------- allan, identify

def _save_rate(tmp_path: Path, x: np.ndarray) -> Path:
    path = tmp_path / "gyro.npy"
    np.save(path, x)
    return path


def test_allan_carries_the_check(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rec = _save_rate(tmp_path, _vibrating())
    base = ["allan", str(rec), "--rate-hz", "100", "--gyro-units", "deg/h"]
    csv_path = tmp_path / "t.csv"
    assert main([*base, "--csv", str(csv_path)]) == 0
    out = capsys.readouterr().out
    assert "self-check: model does NOT hold" in out and "WARNING: model does not hold" in out
    head = csv_path.read_text().splitlines()[0].split(",")
    assert {"fit_adev_deg_h", "fit_used", "fit_ratio", "fit_passed"} <= set(head)
    assert main([*base, "--json", "--self-check"]) == SELF_CHECK_EXIT
    doc = json.loads(capsys.readouterr().out)
    assert doc["self_check"]["holds"] is False
    # the automatic range leaves the hump out, and the model leaves the curve there by far
    # more than the extrapolation factor: flagged all the same
    assert any(not t["fit_passed"] for t in doc["taus"])
    rec = _save_rate(tmp_path, _white())
    assert main(["allan", str(rec), "--rate-hz", "100", "--gyro-units", "deg/h",
                 "--self-check"]) == 0


@pytest.mark.parametrize("identifier", ["allan-nnls", "gmwm"])
def test_identify_carries_the_check(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                    identifier: str) -> None:
    rec = _save_rate(tmp_path, _vibrating())
    base = ["identify", str(rec), "--rate-hz", "100", "--gyro-units", "deg/h", "--identifier",
            identifier]
    assert main([*base, "--self-check", "--json"]) == SELF_CHECK_EXIT
    doc = json.loads(capsys.readouterr().out)
    assert doc["self_check"]["holds"] is False and doc["self_check"]["warnings"]
    assert main(base) == 0
    assert "WARNING: model does not hold" in capsys.readouterr().out


def test_identify_self_check_refused_for_slope(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    rec = _save_rate(tmp_path, _white())
    assert main(["identify", str(rec), "--rate-hz", "100", "--gyro-units", "deg/h",
                 "--identifier", "slope", "--self-check"]) == 2
    assert "--self-check applies to" in capsys.readouterr().err
