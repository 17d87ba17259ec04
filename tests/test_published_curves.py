"""`gyrodrift allan --curve`: a published Allan-deviation curve is read and fitted like a
measured one, with its self-check.

Test data: imu_utils' published curves (tests/data/published_curves, MIT, attribution and
the published values in LICENSE.md). imu_utils reads its white noise N off its own fitted
curve at tau = 1 s, where the other terms still contribute; here N is fitted together with B
and K over 0.1..10 s (the stretch where the curves fall as tau^-1/2; at shorter taus the A3's
accelerometer curve rises with its sensor's low-pass filter, at longer ones the flicker floor
and drifts take over). The two readings of one curve agree within 20 % (measured: A3 gyro
+11.5 %, ADIS16448 gyro -13 %, A3 accelerometer -2.6 %). The curves carry no count, so the
record length is given: 2 hours (an assumption; it only scales all weights alike here, which
leaves the fitted N unchanged)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.cli import main
from gyrodrift.stability.self_check import SELF_CHECK_EXIT

DATA = Path(__file__).parent / "data" / "published_curves"
DURATION = "7200"
PUBLISHED_N = {  # imu_utils data/<IMU>_imu_param.yaml, x axis, continuous-time white noise
    ("imu_utils_A3_gyr_x.csv", "--gyro-units", "deg/h"): 1.0312669892959053e-04,
    ("imu_utils_16448_gyr_x.csv", "--gyro-units", "deg/h"): 1.9497697212844325e-04,
    ("imu_utils_A3_acc_x.csv", "--accel-units", "m/s^2"): 1.1687799474421937e-03,
}


def _json(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, dict]:
    code = main(list(argv))
    out = capsys.readouterr().out
    return code, json.loads(out) if code in (0, SELF_CHECK_EXIT) else {}


@pytest.mark.parametrize(("name", "flag", "unit"), list(PUBLISHED_N))
def test_fit_of_a_published_curve_matches_the_published_n(
        capsys: pytest.CaptureFixture[str], name: str, flag: str, unit: str) -> None:
    code, doc = _json(capsys, "allan", str(DATA / name), "--curve", flag, unit, "--duration-s",
                      DURATION, "--fit-range", "0.1:10", "--terms", "N,B,K", "--json",
                      "--self-check")
    assert code == 0
    assert doc["self_check"]["holds"] is True
    n = doc["terms_si"]["N"]
    assert n["unit"] == ("rad/s/sqrt(Hz)" if flag == "--gyro-units" else "m/s^2/sqrt(Hz)")
    assert n["value"] == pytest.approx(PUBLISHED_N[(name, flag, unit)], rel=0.2)


def test_a_model_that_cannot_describe_the_curve_is_flagged(
        capsys: pytest.CaptureFixture[str]) -> None:
    # a flat line (B alone) through a curve that falls over three decades of tau
    code, doc = _json(capsys, "allan", str(DATA / "imu_utils_A3_acc_x.csv"), "--curve",
                      "--accel-units", "m/s^2", "--duration-s", DURATION, "--terms", "B",
                      "--json", "--self-check")
    assert code == SELF_CHECK_EXIT
    assert doc["self_check"]["holds"] is False
    # the automatic range cannot shrink to a window where a flat line fits: the model is
    # flagged where it leaves the curve, inside or just outside the range it kept
    assert sum(not p for p in doc["self_check"]["passed"]) > 10


def test_curve_units_and_degrees_of_freedom(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    src = DATA / "imu_utils_16448_gyr_x.csv"
    # no units: refused, naming both flags
    assert main(["allan", str(src), "--curve", "--duration-s", DURATION]) == 2
    assert "--gyro-units" in capsys.readouterr().err
    # no count or edf and no record length: refused, naming --duration-s
    assert main(["allan", str(src), "--curve", "--gyro-units", "deg/h"]) == 2
    assert "--duration-s" in capsys.readouterr().err
    # allantools' columns (taus, devs, errors, ns) with its count: read as is; the units
    # convert (deg/s -> deg/h: x 3600)
    tau = np.array([1.0, 2.0, 4.0, 8.0, 16.0])
    adev = 0.01 / np.sqrt(tau)
    path = tmp_path / "allantools.csv"
    path.write_text("tau_s,adev,adev_error,n\n" + "".join(
        f"{float(t)!r},{float(a)!r},{float(a) / 10!r},{int(1000 / t)}\n"
        for t, a in zip(tau, adev, strict=True)))
    code, doc = _json(capsys, "allan", str(path), "--curve", "--gyro-units", "deg/s",
                      "--json")
    assert code == 0
    assert doc["curve"]["edf_from"] == "count"
    assert doc["curve"]["edf"] == [999.0, 499.0, 249.0, 124.0, 61.0]
    np.testing.assert_allclose(doc["curve"]["adev"], adev * 3600.0, rtol=1e-15)
    # white noise of 0.01 deg/s at tau = 1 s: N = 0.01 deg/s/sqrt(Hz) in rad/s/sqrt(Hz)
    assert doc["terms_si"]["N"]["value"] == pytest.approx(0.01 * np.pi / 180.0, rel=1e-6)
