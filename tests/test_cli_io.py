"""gyrodrift.io.records.load_record: formats, columns, units, NaN policy, memory mapping."""

from __future__ import annotations

import math

import numpy as np
import pytest
from gyrodrift.io import records
from gyrodrift.io.imu_log import write_imu_log


def test_npy_1d_is_memory_mapped_2d_column(tmp_path) -> None:
    x = np.random.default_rng(0).normal(size=1000)
    np.save(tmp_path / "a.npy", x)
    rec = records.load_record(tmp_path / "a.npy", rate_hz=10.0)
    assert isinstance(rec.rate_deg_h, np.memmap)  # large records stay on disk
    np.testing.assert_array_equal(np.asarray(rec.rate_deg_h), x)
    np.save(tmp_path / "b.npy", np.column_stack([x, 2 * x, 3 * x]))
    rec2 = records.load_record(tmp_path / "b.npy", rate_hz=10.0, column=2)
    np.testing.assert_array_equal(rec2.rate_deg_h, 3 * x)
    with pytest.raises(ValueError, match="choose a column"):
        records.load_record(tmp_path / "b.npy", rate_hz=10.0)
    with pytest.raises(ValueError, match="out of range"):
        records.load_record(tmp_path / "b.npy", rate_hz=10.0, column=5)


@pytest.mark.parametrize(("units", "factor"), [
    ("deg/h", 1.0), ("deg/s", 3600.0), ("rad/s", 180.0 / math.pi * 3600.0),
    # increments per sample at 50 Hz: x [unit] / 0.02 s -> deg/h
    ("arcsec", 1.0 / 3600.0 * 50.0 * 3600.0), ("deg", 50.0 * 3600.0),
    ("rad", 180.0 / math.pi * 50.0 * 3600.0),
])
def test_units(tmp_path, units: str, factor: float) -> None:
    x = np.linspace(-1.0, 1.0, 101)
    np.save(tmp_path / "u.npy", x)
    rec = records.load_record(tmp_path / "u.npy", rate_hz=50.0, units=units)
    np.testing.assert_allclose(rec.rate_deg_h, x * factor, rtol=1e-15)
    assert rec.units_in == units


def test_csv_without_header_and_bad_cells(tmp_path) -> None:
    # Text in a numeric cell is an error naming the cell, even with nan_policy="drop"
    # (issue 13: it was reported as NaN and the user told to drop NaN).
    bad = tmp_path / "b.csv"
    bad.write_text("0.0,1.5\n0.1,2.5\n0.2,oops\n0.3,4.5\n")
    for policy in ("refuse", "drop"):
        with pytest.raises(ValueError, match=r"line 3, column '1': 'oops' is not a number"):
            records.load_record(bad, column=1, rate_hz=10.0, nan_policy=policy)
    path = tmp_path / "n.csv"
    path.write_text("0.0,1.5\n0.1,2.5\n0.2,nan\n0.3,4.5\n")
    with pytest.raises(ValueError, match="1 of 4 samples are NaN/Inf"):
        records.load_record(path, column=1, rate_hz=10.0)
    rec = records.load_record(path, column=1, rate_hz=10.0, nan_policy="drop")
    np.testing.assert_array_equal(rec.rate_deg_h, [1.5, 2.5, 4.5])
    assert rec.n_dropped == 1 and rec.n_total == 4


def test_replay_csv_and_binary_logs(tmp_path) -> None:
    n = 200
    t_s = np.arange(n) / 100.0
    gyro = np.column_stack([np.full(n, 1e-4), np.full(n, 2e-4), np.linspace(0, 1e-3, n)])
    accel = np.zeros((n, 3))
    for name in ("imu.csv", "imu.bin"):
        write_imu_log(tmp_path / name, t_s, gyro, accel)
        rec = records.load_record(tmp_path / name, column="y")
        assert rec.rate_hz == pytest.approx(100.0, rel=1e-6)
        # float32 on the wire: 1e-7 relative
        np.testing.assert_allclose(rec.rate_deg_h, 2e-4 * 180 / math.pi * 3600, rtol=1e-6)
    with pytest.raises(ValueError, match="gyro axes"):
        records.load_record(tmp_path / "imu.bin", column="w")


def test_unsupported_and_empty(tmp_path) -> None:
    (tmp_path / "x.txt").write_text("1\n2\n")
    with pytest.raises(ValueError, match="unsupported file type"):
        records.load_record(tmp_path / "x.txt", rate_hz=1.0)
    (tmp_path / "e.csv").write_text("")
    with pytest.raises(ValueError, match="empty"):
        records.load_record(tmp_path / "e.csv", rate_hz=1.0)
    with pytest.raises(FileNotFoundError):
        records.load_record(tmp_path / "none.csv")
    with pytest.raises(ValueError, match="unknown units"):
        records.load_record(tmp_path / "x.txt", units="furlong/fortnight")


def test_csv_ragged_rows_are_an_error(tmp_path) -> None:
    path = tmp_path / "r.csv"
    path.write_text("t_s,rate_deg_h\n0.0,1.0\n0.1,2.0,9.9\n0.2,3.0\n")
    with pytest.raises(ValueError, match="malformed CSV"):
        records.load_record(path, column="rate_deg_h")


def test_time_gaps_are_an_error(tmp_path) -> None:
    t = np.arange(100) / 10.0
    t = np.delete(t, [30, 31, 70])  # three missing samples in two gaps
    path = tmp_path / "g.csv"
    np.savetxt(path, np.column_stack([t, np.ones_like(t)]), delimiter=",",
               header="t_s,rate_deg_h", comments="")
    with pytest.raises(ValueError, match="2 gaps"):
        records.load_record(path, column="rate_deg_h")
    # an explicit --rate is the user's statement that the samples are uniform
    assert records.load_record(path, column="rate_deg_h", rate_hz=10.0).n == 97
