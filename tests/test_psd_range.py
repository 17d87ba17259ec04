"""`gyrodrift psd` on records whose PSD leaves the range of float64: one line, exit code 2
(before: exit 0 with "N = inf" for a record of 1e200 deg/h, "N = 0" for 1e-200); inside the
range the numbers are those of the plain Welch PSD."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from cli_units import with_units
from gyrodrift.cli import main
from gyrodrift.stability.psd import welch_psd

RATE_HZ = 100.0


def _record(tmp_path: Path, scale: float) -> tuple[Path, np.ndarray]:
    x = np.random.default_rng(5).normal(0.0, 1.0, 4000) * scale
    p = tmp_path / "rec.npy"
    np.save(p, x)
    return p, x


@pytest.mark.parametrize("scale", [1e200, 1e-200, 1e-155])  # 1e-155: a subnormal PSD
def test_psd_out_of_range_is_one_line(tmp_path: Path, scale: float, capsys) -> None:
    p, _ = _record(tmp_path, scale)
    code = main(with_units(["psd", str(p), "--rate-hz", str(RATE_HZ), "--png",
                            str(tmp_path / "p.png")]))
    err = capsys.readouterr().err
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "outside the range of float64" in err
    assert not (tmp_path / "p.png").exists()


def _psd_json(tmp_path: Path, p: Path, capsys) -> dict:
    code = main(with_units(["psd", str(p), "--rate-hz", str(RATE_HZ), "--png",
                            str(tmp_path / "p.png"), "--json", "--csv", str(tmp_path / "p.csv")]))
    out = capsys.readouterr().out
    assert code == 0
    return json.loads(out)


def test_psd_in_range_is_the_plain_welch_psd(tmp_path: Path, capsys) -> None:
    """A record of ordinary size: the CSV holds exactly the plain Welch PSD (the scaling by a
    power of two is exact); one of 1e150 deg/h (PSD near 1e298): the plain PSD of the
    unit-scale record times 1e300, to double rounding (1e-12 relative)."""
    p, x = _record(tmp_path, 1.0)
    _psd_json(tmp_path, p, capsys)
    table = np.loadtxt(tmp_path / "p.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(table[:, 1], welch_psd(x, RATE_HZ).psd)
    p, x = _record(tmp_path, 1e150)
    out = _psd_json(tmp_path, p, capsys)
    table = np.loadtxt(tmp_path / "p.csv", delimiter=",", skiprows=1)
    want = welch_psd(x / 1e150, RATE_HZ).psd * 1e300
    np.testing.assert_allclose(table[:, 1], want, rtol=1e-12)
    assert np.isfinite(out["n_arw_deg_rt_h"]) and out["n_arw_deg_rt_h"] > 1e140
