"""Records normalized in pieces (gyrodrift.io.spool): the temporary-file path gives the
values and the analyses of the in-memory path, the chunked helpers give what numpy gives on
the whole array, and the temporary files are removed.

The spooled path is forced on small records by setting SPOOL_MIN_SAMPLES to 0 and the block
sizes to a few rows (so every record is cut into many pieces, at rows that are not block
multiples)."""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import gyrodrift.cli as cli
import numpy as np
import pytest
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.io import imu_data, records, spool
from gyrodrift.io.imu_data import load_imu
from gyrodrift.io.records import load_record, rate_from_time
from gyrodrift.io.spool import SampleSpool, chunked_median, iter_row_blocks, iter_text_tables
from gyrodrift.units import RATE_UNITS

RATE = 100.0
N = 6000


@pytest.fixture
def spooled(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """Every record through temporary files, in pieces of 997 rows / 13 text lines; the
    temporary files in a directory of their own (returned)."""
    return _spool_everything(monkeypatch, tmp_path)


def _spool_everything(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    monkeypatch.setattr(spool, "SPOOL_MIN_SAMPLES", 0)
    monkeypatch.setattr(spool, "BLOCK_ROWS", 997)
    monkeypatch.setattr(records, "BLOCK_ROWS", 997)
    monkeypatch.setattr(imu_data, "BLOCK_ROWS", 997)
    monkeypatch.setattr(spool, "TEXT_BLOCK_LINES", 13)
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    return tmp


def _record_2d_rad_s(tmp_path: Path) -> tuple[Path, Path, np.ndarray]:
    """A (N, 3) rad/s record with NaN and Inf in its middle column, as .npy and as CSV with
    a time column; and the middle column in deg/h without them (numpy, independently)."""
    rng = np.random.default_rng(7)
    drift = np.cumsum(rng.standard_normal(N)) * 2e-7
    x = rng.standard_normal((N, 3)) * 1e-4 + drift[:, None]
    x[[5, 400, 401, 3999], 1] = np.nan
    x[1234, 1] = np.inf
    npy = tmp_path / "imu.npy"
    np.save(npy, x)
    csv = tmp_path / "imu.csv"
    with csv.open("w") as fh:
        fh.write("t_s,gx,gy,gz\n")
        for i, row in enumerate(x):
            fh.write(f"{i / RATE!r}," + ",".join(repr(float(v)) for v in row) + "\n")
    col = x[:, 1] * RATE_UNITS["rad/s"].to_deg_h
    return npy, csv, col[np.isfinite(col)]


def test_spooled_record_holds_the_converted_column(tmp_path: Path, spooled: Path) -> None:
    npy, csv, want = _record_2d_rad_s(tmp_path)
    for path in (npy, csv):
        rec = load_record(path, column=1 if path == npy else "gy", rate_hz=RATE,
                          units="rad/s", nan_policy="drop")
        assert isinstance(rec.rate_deg_h, np.memmap), path  # the temporary-file path ran
        assert (rec.n_total, rec.n_dropped, rec.rate_hz) == (N, 5, RATE)
        # one IEEE multiplication per sample, the same on every machine
        np.testing.assert_array_equal(rec.rate_deg_h, want)
        with pytest.raises(GyrodriftValueError, match=r"5 of 6000 samples are NaN/Inf"):
            load_record(path, column=1 if path == npy else "gy", rate_hz=RATE, units="rad/s")
    del rec
    assert list(spooled.iterdir()) == []  # each temporary directory went with its last map


def _analyses(path: Path, column: str, capsys: pytest.CaptureFixture[str], png: Path
              ) -> dict[str, dict]:
    common = [str(path), "--column", column, "--rate-hz", f"{RATE:g}", "--gyro-units",
              "rad/s", "--drop-nan", "--json"]
    out: dict[str, dict] = {}
    for name, argv in (("allan", ["allan"]), ("identify", ["identify"]),
                       ("gmwm", ["identify", "--identifier", "gmwm", "--model", "N+K"]),
                       ("fit", ["fit"]),
                       ("psd", ["psd", "--png", str(png)])):
        code = cli.main([*argv, *common])
        text, err = capsys.readouterr()
        assert code == 0, (name, err)
        out[name] = json.loads(text)
    return out


def _assert_close(a: object, b: object, where: str) -> None:
    """Equal structure; numbers within 1e-12 relative (the file-backed and in-memory paths
    sum the same values in other orders: a few ulps), the rest equal."""
    if isinstance(a, dict) and isinstance(b, dict):
        assert a.keys() == b.keys(), where
        for k in a:
            _assert_close(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list) and isinstance(b, list):
        assert len(a) == len(b), where
        for i, (u, v) in enumerate(zip(a, b, strict=True)):
            _assert_close(u, v, f"{where}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert a == b or math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-300), (where, a, b)
    else:
        assert a == b, (where, a, b)


def test_analyses_of_a_spooled_record_equal_the_in_memory_ones(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """allan, identify (Allan and GMWM), fit and psd on a 2-D rad/s .npy record with NaN/Inf
    and --drop-nan: through a temporary file in pieces (a memory map, which allan and psd
    read from the file) == in memory. (The CSV form of the record gives the same values:
    test_spooled_record_holds_the_converted_column.)"""
    npy, _, _ = _record_2d_rad_s(tmp_path)
    png = tmp_path / "psd.png"
    memory = _analyses(npy, "1", capsys, png)
    _spool_everything(monkeypatch, tmp_path)  # the fixture's settings, from here on
    _assert_close(memory, _analyses(npy, "1", capsys, png), "npy")
    assert memory["allan"]["record"]["n_dropped_nonfinite"] == 5


def test_characterize_readers_spool_what_they_read_in_memory(tmp_path: Path,
                                                             spooled: Path) -> None:
    """load_imu: a .npy record with --drop-nan spooled per channel, a text record (CSV and
    whitespace) through temporary files: the channels, counts and rate of the in-memory
    readers (taken before the settings of `spooled` apply to anything)."""
    rng = np.random.default_rng(3)
    x = rng.standard_normal((N, 6)) * [1e-3, 1e-3, 1e-3, 0.01, 0.01, 0.01] \
        + [0, 0, 0, 0, 0, 9.81]
    x[[10, 2000], 2] = np.nan
    x[77, 4] = -np.inf
    np.save(tmp_path / "imu.npy", x)
    t = np.arange(N) / RATE
    np.savetxt(tmp_path / "imu.txt", np.column_stack([t, x]), fmt="%.17g")
    np.savetxt(tmp_path / "imu.csv", np.column_stack([t, x]), fmt="%.17g", delimiter=",",
               header="time,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z", comments="")
    # in memory: the same readers with no temporary file and the whole text as one block
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(spool, "SPOOL_MIN_SAMPLES", 10 * N)
        mp.setattr(spool, "TEXT_BLOCK_LINES", 10 * N)
        want = {
            "npy": load_imu(tmp_path / "imu.npy", rate_hz=RATE, nan_policy="drop"),
            "txt": load_imu(tmp_path / "imu.txt", nan_policy="drop"),
            "csv": load_imu(tmp_path / "imu.csv", nan_policy="drop", gyro_units="deg/s"),
        }
    got = {
        "npy": load_imu(tmp_path / "imu.npy", rate_hz=RATE, nan_policy="drop",
                        spool_dir=tmp_path / "sp", chunk_rows=997),
        "txt": load_imu(tmp_path / "imu.txt", nan_policy="drop"),
        "csv": load_imu(tmp_path / "imu.csv", nan_policy="drop", gyro_units="deg/s"),
    }
    for key in want:
        w, g = want[key], got[key]
        assert (g.names, g.n_total, g.n_dropped) == (w.names, N, 3), key
        assert g.rate_hz == w.rate_hz, key
        for name in w.names:
            assert isinstance(g.channels[name], np.memmap), (key, name)
            np.testing.assert_array_equal(g.channels[name], w.channels[name])
    with pytest.raises(GyrodriftValueError, match="3 of 6000 samples have NaN/Inf channels"):
        load_imu(tmp_path / "imu.txt")


def test_chunked_median_is_numpys_median() -> None:
    rng = np.random.default_rng(0)
    for n in (1, 2, 3, 10, 1001, 4096):
        for kind in ("normal", "ties", "tiny", "signed-zero", "inf"):
            v = rng.standard_normal(n)
            if kind == "ties":
                v = np.round(v, 1)
            elif kind == "tiny":
                v = np.abs(v) * 1e-310  # subnormal
            elif kind == "signed-zero":
                v[::2] = -0.0
            elif kind == "inf":
                v[::5] = np.inf
            parts = np.array_split(v, 7)
            assert chunked_median(lambda parts=parts: iter(parts)) == np.median(v), (n, kind)
    assert math.isnan(chunked_median(lambda: iter([np.array([1.0, np.nan])])))


def test_file_backed_rate_from_time_is_the_in_memory_one(monkeypatch: pytest.MonkeyPatch
                                                         ) -> None:
    """Rate, refusals and messages of a time column read in pieces of 7 (a memory map of a
    temporary file) == of the same column in memory: jitter, NaN times (also at the start),
    a gap, a repeated time, nanoseconds read as seconds, a falling column."""
    monkeypatch.setattr(records, "BLOCK_ROWS", 7)
    rng = np.random.default_rng(2)
    base = np.arange(300) * 0.0025 + 5.0
    cases = {"jitter": base + rng.uniform(-1e-4, 1e-4, base.size), "clean": base.copy(),
             "nan": np.where((np.arange(300) >= 100) & (np.arange(300) < 120), np.nan, base),
             "nan-first": np.where(np.arange(300) < 6, np.nan, base),
             "gap": np.delete(base, 50), "repeat": np.insert(base, 8, base[7]),
             "ns": base * 1e9, "falling": base[::-1].copy()}
    for name, t in cases.items():
        with SampleSpool(memory_max=0) as sp:
            for piece in np.array_split(t, 5):
                sp.append(piece)
            mm = sp.finish()
        assert records.is_file_backed(mm)
        results = []
        for col in (t, mm):
            try:
                results.append(rate_from_time(col, "log.csv", time_units="s"))
            except GyrodriftValueError as exc:
                results.append(str(exc))
        assert results[0] == results[1], name


def test_text_blocks_report_the_files_line_numbers(tmp_path: Path) -> None:
    """A row with a wrong field count in a later block: genfromtxt's message with the line
    number of the file (as one call on the whole file gives it), whatever the block size."""
    lines = ["1,2\n", "3,4\n", "\n", "# note\n", "5,6\n", "7,8,9\n", "10,11\n"]
    with pytest.raises(ValueError, match=r"Line #6 \(got 3 columns instead of 2\)") as whole:
        np.genfromtxt(lines, delimiter=",", dtype=np.float64, ndmin=2)
    for block in (1, 2, 3, 5, 100):
        with pytest.raises(GyrodriftValueError,
                           match=r"^t.csv: malformed: Some errors were detected !; "
                                 r"Line #6 \(got 3 columns instead of 2\)$"):
            list(iter_text_tables(iter(lines), delimiter=",", first_line_no=1, lines=block,
                                  malformed="t.csv: malformed"))
    assert "Line #6" in str(whole.value)
    tables = [t for t, _, _ in iter_text_tables(iter(lines[:5]), delimiter=",",
                                                first_line_no=1, lines=2)]
    np.testing.assert_array_equal(np.concatenate(tables), [[1, 2], [3, 4], [5, 6]])


def test_row_blocks_of_a_fortran_and_a_c_order_map(tmp_path: Path) -> None:
    a = np.arange(60, dtype=np.float32).reshape(20, 3)
    for order, arr in (("C", a), ("F", np.asfortranarray(a))):
        np.save(tmp_path / f"{order}.npy", arr)
        mm = np.load(tmp_path / f"{order}.npy", mmap_mode="r")
        got = np.concatenate(list(iter_row_blocks(mm, rows=7)))
        np.testing.assert_array_equal(got, a)


def test_spool_removes_its_file_on_error_and_when_released(tmp_path: Path,
                                                           spooled: Path) -> None:
    with pytest.raises(RuntimeError), SampleSpool() as sp:
        sp.append(np.ones(5))
        assert sp.on_file and len(list(spooled.iterdir())) == 1
        raise RuntimeError
    assert list(spooled.iterdir()) == []
    with SampleSpool() as sp:
        sp.append(np.ones(5))
        x = sp.finish()
    view = x[2:]
    del x
    assert len(list(spooled.iterdir())) == 1  # a view still maps the file
    assert float(view.sum()) == 3.0
    del view
    assert list(spooled.iterdir()) == []


def test_units_check_reads_a_spooled_record(tmp_path: Path, spooled: Path) -> None:
    """The units plausibility check samples a spooled channel from its file (not through the
    map) and reaches the in-memory verdict: g values declared m/s^2 are refused, naming g."""
    rng = np.random.default_rng(5)
    x = np.column_stack([rng.normal(0.0, 1e-4, (N, 3)),
                         rng.normal([0.0, 0.0, 1.0], 1e-3, (N, 3))])
    np.save(tmp_path / "imu.npy", x)
    rec = load_imu(tmp_path / "imu.npy", rate_hz=RATE, spool_dir=tmp_path / "sp")
    assert all(isinstance(v, np.memmap) for v in rec.channels.values())
    with pytest.raises(GyrodriftValueError, match=r"the data look like g;"):
        imu_data.check_units_plausible(rec, "rad/s", "m/s^2")
    right = load_imu(tmp_path / "imu.npy", rate_hz=RATE, spool_dir=tmp_path / "sp2",
                     accel_units="g")
    imu_data.check_units_plausible(right, "rad/s", "g")  # the right units pass


@pytest.mark.parametrize("dtype", ["int16", "uint64", ">f8", "float16", "float32"])
def test_every_number_dtype_is_spooled_as_numpy_converts_it(tmp_path: Path, spooled: Path,
                                                            dtype: str) -> None:
    """Integer, big-endian, half and single precision records (1-D and a column of a 2-D
    array, deg/s): the spooled deg/h record is numpy's float64 conversion times the unit
    factor (one IEEE multiplication per sample)."""
    raw = (np.random.default_rng(4).standard_normal((3001, 2)) * 100).astype(dtype)
    np.save(tmp_path / "one.npy", raw[:, 0])
    np.save(tmp_path / "two.npy", raw)
    for path, column, col in ((tmp_path / "one.npy", None, raw[:, 0]),
                              (tmp_path / "two.npy", 1, raw[:, 1])):
        rec = load_record(path, column=column, rate_hz=RATE, units="deg/s")
        assert isinstance(rec.rate_deg_h, np.memmap) and rec.rate_deg_h.dtype == np.float64
        np.testing.assert_array_equal(
            rec.rate_deg_h, col.astype(np.float64) * RATE_UNITS["deg/s"].to_deg_h)


#: Cells of the text-table property test below: numbers in every syntax either parser reads
#: (or only Python's float reads: underscores, non-ASCII digits), cells genfromtxt turns into
#: NaN (text, hex, Fortran exponents, quotes, empty and blank cells), comments inside a row.
_CELLS = ["1", "-2.5", " 3 ", "4.", ".5", "+.5e-3", "1e400", "1e-400", "nan", "NaN", "-nan",
          "inf", "-Infinity", "1_0", "0x10", "1d5", "\u0661", "True", "x", '"1"', "", " ",
          "7 # note"]
_BLANK_LINES = ["\n", "   \n", "\t\n", "# comment\n", "  # indented comment\n"]


def _random_table(rng: np.random.Generator, delimiter: str | None) -> list[str]:
    """20-80 lines: mostly rows of two cells, some of one or three, some blank or comment
    lines; plain numbers in most rows, so that many blocks are all numbers."""
    lines = []
    for _ in range(int(rng.integers(20, 80))):
        if rng.random() < 0.08:
            lines.append(str(rng.choice(_BLANK_LINES)))
            continue
        k = 2 if rng.random() < 0.97 else int(rng.choice([1, 3]))
        cells = [f"{rng.normal():.6g}" if rng.random() < 0.9 else str(rng.choice(_CELLS))
                 for _ in range(k)]
        if delimiter is None:  # whitespace: cells without blanks, joined by spaces or tabs
            cells = [c.strip().replace(" ", "") or "0" for c in cells]
            lines.append(str(rng.choice([" ", "\t", "  "])).join(cells) + "\n")
        else:
            lines.append(delimiter.join(cells) + ("," if rng.random() < 0.02 else "") + "\n")
    return lines


def test_text_blocks_parse_as_genfromtxt_parses_them(monkeypatch: pytest.MonkeyPatch) -> None:
    """A block goes to numpy.loadtxt's parser first and to genfromtxt when loadtxt refuses
    it: every table of random lines (hostile cells, blank and comment lines, wrong field
    counts; comma and whitespace delimited, several block sizes) gives the tables, NaN and
    the error message genfromtxt alone gives for each block (the same values exactly: both
    parsers round each decimal number correctly)."""
    rng = np.random.default_rng(5)

    def parse(lines: list[str], delimiter: str | None, block: int) -> list[object]:
        try:
            return [(t.shape, t.tolist(), n) for t, _, n in iter_text_tables(
                iter(lines), delimiter=delimiter, first_line_no=2, lines=block,
                malformed="t.csv: malformed")]
        except GyrodriftValueError as exc:
            return [str(exc)]

    fast_blocks = 0
    for case in range(300):
        delimiter = None if case % 3 == 0 else ","
        lines = _random_table(rng, delimiter)
        block = int(rng.choice([1, 7, 16, 1000]))
        with monkeypatch.context() as m:
            m.setattr(spool, "_parse_plain", lambda *a: None)  # genfromtxt alone
            want = parse(lines, delimiter, block)
        got = parse(lines, delimiter, block)
        assert repr(got) == repr(want), (case, lines)  # repr: NaN equal to NaN
        fast_blocks += sum(spool._parse_plain(lines[i:i + block], delimiter, "#") is not None
                           for i in range(0, len(lines), block))
    assert fast_blocks > 300  # most blocks were read by loadtxt, not only by the fallback


def test_a_plain_text_table_is_read_without_genfromtxt(monkeypatch: pytest.MonkeyPatch
                                                       ) -> None:
    """Blocks of plain numbers go to numpy.loadtxt's C parser (a quarter of genfromtxt's
    time per line, which made text records of 1e8 rows take hours)."""
    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("genfromtxt called")

    monkeypatch.setattr(np, "genfromtxt", refuse)
    lines = ["# t_s,gyro_z\n", *(f"{i / 400:.4f},{(-1) ** i * 0.25 * i:.6f}\n"
                                 for i in range(1000)), "\n"]
    tables = [t for t, _, _ in iter_text_tables(iter(lines), delimiter=",", first_line_no=2,
                                                lines=64)]
    table = np.concatenate(tables)
    np.testing.assert_array_equal(table[:, 0], np.arange(1000) / 400)  # 4 decimals: exact
    np.testing.assert_array_equal(table[:, 1], (-1.0) ** np.arange(1000) * 0.25
                                  * np.arange(1000))
