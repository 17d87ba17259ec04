"""Units are never guessed: a .npy or text record needs --gyro-units (and --accel-units when it
has accelerometer columns); a file that carries its units (an IMU log, a bag, PSINS) needs
none; and a static record whose values contradict the declared units by a large factor is
refused with the likely unit named (the rules: docs/guides/units.md).

The static record: an accelerometer triad reading 1 g (tilted a little) with 1 mg noise, a
gyro triad reading Earth rate plus a bias of 0.01 deg/s with 0.02 deg/s noise, 100 Hz. Before
units were required, `characterize` read such deg/s and g data as deg/h and m/s^2 without a
word: a gyro density 3600x too low and an accelerometer density 9.8x too low."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from gyrodrift.cli import main
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.io.imu_data import ImuData, check_units_plausible
from gyrodrift.units import DEG, G0_M_S2

RATE_HZ = 100.0
N = 8000
EARTH_DEG_S = np.array([0.002, 0.0, 0.0035])  # about 15 deg/h in some orientation


def _static(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(gyro deg/s, accel g), each (N, 3)."""
    rng = np.random.default_rng(seed)
    gyro = EARTH_DEG_S + 0.01 + rng.normal(0.0, 0.02, (N, 3))
    g_dir = np.array([0.02, -0.03, 1.0]) / np.linalg.norm([0.02, -0.03, 1.0])
    accel = g_dir + rng.normal(0.0, 1e-3, (N, 3))
    return gyro, accel


def _save(tmp_path: Path, gyro: np.ndarray, accel: np.ndarray) -> Path:
    path = tmp_path / "imu.npy"
    np.save(path, np.hstack([gyro, accel]))
    return path


def _char(path: Path, *flags: str) -> int:
    return main(["characterize", str(path), "--rate-hz", str(RATE_HZ), "--taus", "octave",
                 "--terms", "N,B", *flags])


def test_characterize_refuses_to_guess_units(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    path = _save(tmp_path, *_static())
    assert _char(path) == 2
    err = capsys.readouterr().err
    assert "does not say its units" in err and "--gyro-units" in err
    assert _char(path, "--gyro-units", "deg/s") == 2
    assert "--accel-units" in capsys.readouterr().err
    # stated, the same data give the right densities
    assert _char(path, "--gyro-units", "deg/s", "--accel-units", "g", "--json") == 0
    import json

    doc = json.loads(capsys.readouterr().out)
    n_gyro = doc["channels"]["gyro_x"]["terms"]["N"]["value"]
    n_acc = doc["channels"]["accel_x"]["terms"]["N"]["value"]
    # white noise of std s per sample at rate f: N = s / sqrt(f) (SI units); 10 % covers
    # the estimate of an 8000-sample record
    assert n_gyro == pytest.approx(0.02 * DEG / np.sqrt(RATE_HZ), rel=0.1)
    assert n_acc == pytest.approx(1e-3 * G0_M_S2 / np.sqrt(RATE_HZ), rel=0.1)


def test_a_gyro_only_record_needs_no_accel_units(tmp_path: Path) -> None:
    gyro, _ = _static()
    path = tmp_path / "g.npy"
    np.save(path, gyro)
    assert main(["characterize", str(path), "--rate-hz", "100", "--gyro-units", "deg/s",
                 "--terms", "N,B"]) == 0


@pytest.mark.parametrize(("gyro_units", "accel_units", "scale_g", "scale_a", "likely"), [
    ("deg/s", "m/s^2", 1.0, 1.0, "--accel-units g"),          # g read as m/s^2
    ("deg/s", "g", 1.0, G0_M_S2, "--accel-units m/s^2"),      # m/s^2 read as g
    ("deg/h", "g", DEG, 1.0, "look like rad/s"),              # rad/s read as deg/h
    ("rad/s", "g", 3600.0, 1.0, "look like deg/h"),           # deg/h read as rad/s
])
def test_contradicting_units_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                         gyro_units: str, accel_units: str, scale_g: float,
                                         scale_a: float, likely: str) -> None:
    gyro, accel = _static()
    path = _save(tmp_path, gyro * scale_g, accel * scale_a)
    assert _char(path, "--gyro-units", gyro_units, "--accel-units", accel_units) == 2
    assert likely in capsys.readouterr().err


def test_moving_or_gravity_free_records_are_not_judged() -> None:
    rng = np.random.default_rng(1)
    t = np.arange(N) / RATE_HZ
    # a moving record whose magnitude swings by more than STATIC_SPREAD: not judged
    swing = 1.0 + 0.5 * np.sin(2 * np.pi * 0.3 * t)
    moving = {f"accel_{k}": swing * v for k, v in zip("xyz", (0.0, 0.0, 1.0), strict=True)}
    check_units_plausible(ImuData(moving, RATE_HZ, "m", "npy", N), "rad/s", "m/s^2")
    # a gravity-free (simulated) record: no unit puts it near 1 g, nothing to name
    free = {f"accel_{k}": rng.normal(0.0, 1e-2, N) for k in "xyz"}
    free.update({f"gyro_{k}": rng.normal(0.0, 1e-6, N) for k in "xyz"})
    check_units_plausible(ImuData(free, RATE_HZ, "f", "npy", N), "deg/h", "m/s^2")
    # a deg/h record of a quiet gyro with the Earth rate in it is left alone
    static = {f"accel_{k}": np.full(N, v) + rng.normal(0.0, 1e-3, N)
              for k, v in zip("xyz", (0.0, 0.0, G0_M_S2), strict=True)}
    static.update({f"gyro_{k}": (v + rng.normal(0.0, 0.01, N)) * DEG / 3600.0
                   for k, v in zip("xyz", (7.0, 0.0, 12.0), strict=True)})
    check_units_plausible(ImuData(static, RATE_HZ, "s", "npy", N), "deg/h", "m/s^2")
    # the same m/s^2 values declared g (the record holds what the loader made of them)
    as_g = {k: v * G0_M_S2 if k.startswith("accel") else v for k, v in static.items()}
    with pytest.raises(GyrodriftValueError, match=r"look like m/s\^2"):
        check_units_plausible(ImuData(as_g, RATE_HZ, "s", "npy", N), "deg/h", "g")


def test_single_channel_commands_need_gyro_units(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "gyro.npy"
    np.save(path, np.random.default_rng(0).normal(0.0, 1.0, 4096))
    for cmd in ("allan", "identify", "psd", "fit", "filter"):
        extra = ["-o", str(tmp_path / "f.npy")] if cmd == "filter" else []
        assert main([cmd, str(path), "--rate-hz", "100", *extra]) == 2, cmd
        err = capsys.readouterr().err
        assert "does not say its units: give --gyro-units" in err, (cmd, err)
    assert main(["allan", str(path), "--rate-hz", "100", "--gyro-units", "deg/h"]) == 0


def test_a_log_carries_its_units(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "imu.bin"
    assert main(["simulate", "-o", str(log), "--format", "bin", "--duration-s", "20",
                 "--arw-deg-rt-h", "0.5"]) == 0
    capsys.readouterr()
    assert main(["allan", str(log)]) == 0
    assert "does not say its units" not in capsys.readouterr().err
