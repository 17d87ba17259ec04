"""Every bad path of the command line ends cleanly (issue 13): one line on stderr, exit code 2
(130 for Ctrl-C), no traceback, and no file left behind (outputs are checked before the work
and written atomically).

Most cases run `gyrodrift.cli.main` in-process; broken pipes, Ctrl-C and the process exit
code need a real child process (`python -m gyrodrift`).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from cli_units import with_units
from gyrodrift.cli import main
from gyrodrift.io.atomic import atomic_output

RATE_HZ = 100.0


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(with_units(argv))
    out, err = capsys.readouterr()
    return code, out, err


def one_line_error(code: int, err: str, *needles: str) -> None:
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err  # no traceback, no warning before it
    assert "Traceback" not in err
    for n in needles:
        assert n in lines[0], lines[0]


def write_table(p: Path, t: np.ndarray, x: np.ndarray, sep: str) -> None:
    lines = [f"{float(a)!r}{sep}{float(b)!r}" for a, b in zip(t, x, strict=True)]
    p.write_text(f"t_s{sep}gyro\n" + "\n".join(lines) + "\n")


def files(d: Path) -> set[str]:
    return {str(p.relative_to(d)) for p in d.rglob("*")}


@pytest.fixture()
def rec(tmp_path: Path) -> Path:
    p = tmp_path / "rec.npy"
    np.save(p, np.random.default_rng(0).normal(0.0, 1.0, 4000))
    return p


# --------------------------------------------------------------- outputs checked first


def test_second_output_bad_writes_neither(tmp_path: Path, rec: Path, capsys) -> None:
    """Two outputs, the second unwritable: before, the first was written, then a traceback."""
    before = files(tmp_path)
    code, _, err = run(capsys, "allan", rec, "--rate-hz", RATE_HZ, "--csv",
                       tmp_path / "ok.csv", "--png", tmp_path / "nodir" / "a.png")
    one_line_error(code, err, "--png", "nodir", "does not exist")
    assert files(tmp_path) == before


@pytest.mark.parametrize("argv", [
    ("simulate", "-o", "{d}/nodir/x.npy", "--samples", "100", "--arw-deg-rt-h", "0.1"),
    ("filter", "{rec}", "--rate-hz", "100", "-o", "{d}/nodir/f.npy"),
    ("filter", "{rec}", "--rate-hz", "100", "-o", "{d}/rec.npy/f.npy"),  # parent is a file
    ("psd", "{rec}", "--rate-hz", "100", "--png", "{d}/nodir/p.png"),
    ("allan", "{rec}", "--rate-hz", "100", "--png", "{d}/a.jpgx"),
    ("psd", "{rec}", "--rate-hz", "100", "--png", "{d}"),  # a directory
    ("wavelet-response", "--png", "{d}/w.jpgx"),
    ("replay", "--out-dir", "{d}/rec.npy/sub", "--duration-s", "1"),
])
def test_bad_output_location_fails_before_work(tmp_path: Path, rec: Path, capsys,
                                               argv: tuple[str, ...]) -> None:
    before = files(tmp_path)
    code, _, err = run(capsys, *(a.format(d=tmp_path, rec=rec) for a in argv))
    one_line_error(code, err)
    assert files(tmp_path) == before


def test_atomic_output_leaves_nothing_on_failure_or_ctrl_c(tmp_path: Path) -> None:
    target = tmp_path / "x.npy"
    np.save(target, np.ones(2))
    for exc in (RuntimeError("boom"), KeyboardInterrupt()):
        with pytest.raises(type(exc)), atomic_output(target) as tmp:
            np.save(tmp, np.zeros(5))
            raise exc
        assert files(tmp_path) == {"x.npy"}  # no temporary file left
        np.testing.assert_array_equal(np.load(target), np.ones(2))  # old content intact
    with atomic_output(target) as tmp:
        np.save(tmp, np.zeros(5))
    assert np.load(target).shape == (5,) and files(tmp_path) == {"x.npy"}
    assert (target.stat().st_mode & 0o777) == 0o666 & ~_umask()


def _umask() -> int:
    m = os.umask(0o022)
    os.umask(m)
    return m


# ------------------------------------------------------------------------ bad inputs


def test_empty_and_text_npy_and_fifo(tmp_path: Path, capsys) -> None:
    (tmp_path / "empty.npy").write_bytes(b"")
    code, _, err = run(capsys, "allan", tmp_path / "empty.npy", "--rate-hz", RATE_HZ)
    one_line_error(code, err, "empty.npy", "empty file")
    (tmp_path / "text.npy").write_text("1.0\n2.0\n")
    code, _, err = run(capsys, "allan", tmp_path / "text.npy", "--rate-hz", RATE_HZ)
    one_line_error(code, err, "text.npy", "not a NumPy .npy file")
    fifo = tmp_path / "pipe.npy"
    os.mkfifo(fifo)
    code, _, err = run(capsys, "allan", fifo, "--rate-hz", RATE_HZ)  # must not block
    one_line_error(code, err, "pipe.npy", "not a regular file")


def test_misleading_csv_messages(tmp_path: Path, capsys) -> None:
    binary = tmp_path / "bin.csv"
    binary.write_bytes(bytes(range(256)) * 4)
    code, _, err = run(capsys, "allan", binary, "--rate-hz", RATE_HZ)
    one_line_error(code, err, "bin.csv", "not a text CSV")
    text_cell = tmp_path / "cell.csv"
    t = np.arange(50) / RATE_HZ
    rows = [f"{float(a)!r},{float(b)!r}" for a, b in zip(t, np.sin(t), strict=True)]
    rows[17] = f"{float(t[17])!r},abc"
    text_cell.write_text("t_s,gyro\n" + "\n".join(rows) + "\n")
    for extra in ((), ("--drop-nan",)):
        code, _, err = run(capsys, "allan", text_cell, *extra)
        one_line_error(code, err, "cell.csv", "line 19", "'gyro'", "'abc' is not a number")
    two = tmp_path / "two.csv"
    two.write_text("a,b\n1,2\n3,4\n")
    code, _, err = run(capsys, "allan", two, "--rate-hz", RATE_HZ)
    one_line_error(code, err, "--column")
    assert "column=" not in err.replace("--column", "")
    header_only = tmp_path / "hdr.csv"
    header_only.write_text("t_s,gyro\n")
    code, _, err = run(capsys, "allan", header_only)
    one_line_error(code, err, "hdr.csv", "no data rows")  # and no numpy warning line


def test_semicolon_csv_is_read(tmp_path: Path, capsys) -> None:
    x = np.random.default_rng(1).normal(size=400)
    t = np.arange(x.size) / RATE_HZ
    semi = tmp_path / "semi.csv"
    write_table(semi, t, x, ";")
    comma = tmp_path / "comma.csv"
    write_table(comma, t, x, ",")
    code_s, out_s, err_s = run(capsys, "allan", semi, "--json")
    code_c, out_c, _ = run(capsys, "allan", comma, "--json")
    assert code_s == 0 == code_c, err_s
    assert out_s.replace("semi.csv", "X") == out_c.replace("comma.csv", "X")


@pytest.mark.parametrize("rate", ["1e-300", "1e300", "0", "-5", "nan", "inf"])
def test_absurd_rates(tmp_path: Path, rec: Path, capsys, rate: str) -> None:
    before = files(tmp_path)
    for argv in (("allan", rec, "--rate-hz", rate),
                 ("simulate", "-o", tmp_path / "s.npy", "--samples", "100", "--rate-hz", rate,
                  "--arw-deg-rt-h", "1"),
                 ("wavelet-response", "--rate-hz", rate, "--png", tmp_path / "w.png")):
        code, _, err = run(capsys, *argv)
        one_line_error(code, err, "rate")
    assert files(tmp_path) == before


# ----------------------------------------------------- refused instead of accepted


def test_allan_on_a_handful_of_samples_is_refused(tmp_path: Path, capsys) -> None:
    for n in (3, 5, 8):
        p = tmp_path / f"s{n}.npy"
        np.save(p, np.arange(float(n)))
        code, _, err = run(capsys, "allan", p, "--rate-hz", RATE_HZ, "--csv", tmp_path / "a.csv")
        one_line_error(code, err, "too short", f"{n} samples")
        assert not (tmp_path / "a.csv").exists()
    p = tmp_path / "s9.npy"
    np.save(p, np.random.default_rng(2).normal(size=9))
    assert run(capsys, "allan", p, "--rate-hz", RATE_HZ)[0] == 0


def test_psd_of_a_constant_record_is_refused(tmp_path: Path, capsys) -> None:
    p = tmp_path / "c.npy"
    np.save(p, np.full(1000, 3.0))
    code, _, err = run(capsys, "psd", p, "--rate-hz", RATE_HZ, "--png", tmp_path / "p.png")
    one_line_error(code, err, "constant")
    assert not (tmp_path / "p.png").exists()


@pytest.mark.filterwarnings("error")
def test_float_wavelet_filter_refuses_a_value_beyond_float32_in_one_line(
        tmp_path: Path, capsys) -> None:
    """filter --filter wavelet --core float on a record holding 1e39 (finite in float64,
    beyond float32): one line naming the value and its index, no numpy overflow warning
    (warnings are errors here), no output."""
    p = tmp_path / "big.npy"
    x = np.random.default_rng(3).normal(size=4000)
    x[1234] = 1e39
    np.save(p, x)
    code, _, err = run(capsys, "filter", p, "--rate-hz", RATE_HZ, "--gyro-units", "deg/h",
                       "--filter", "wavelet", "--core", "float", "-o", tmp_path / "y.npy")
    one_line_error(code, err, "1e+39 at index 1234", "beyond the float32 range")
    assert not (tmp_path / "y.npy").exists()


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("method", ["ar", "kalman"])
def test_float_ar_filters_refuse_what_float32_cannot_hold_in_one_line(
        tmp_path: Path, capsys, method: str) -> None:
    """filter --filter ar/kalman --core float: a value beyond float32, and a record whose
    AR(2) model's variance (about 1e66 (deg/h)^2 here, fitted in double) float32 cannot hold,
    are each refused in one line that says so, with no numpy warning and no output (before:
    numpy's overflow warning, then "ar_filter_batch: bad argument" or "...: non-finite")."""
    x = np.random.default_rng(3).normal(size=4000)
    big = x.copy()
    big[1234] = 1e39
    for y, needles in ((big, ("1e+39 at index 1234", "beyond the float32 range")),
                       (x * 1e33, ("float32", "float64"))):
        p = tmp_path / "big.npy"
        np.save(p, y)
        code, _, err = run(capsys, "filter", p, "--rate-hz", RATE_HZ, "--gyro-units", "deg/h",
                           "--filter", method, "--core", "float", "-o", tmp_path / "y.npy")
        one_line_error(code, err, *needles)
        assert not (tmp_path / "y.npy").exists()


def test_float_realtime_wavelet_reports_the_samples_it_skipped(tmp_path: Path, capsys) -> None:
    """filter --filter realtime-wavelet --core float on a record at 1e33 deg/h, whose window
    sums float32 cannot hold: the filter skips those samples and repeats its last output, and
    the command says how many (warning and JSON), instead of writing a silent run of zeros.
    A record float32 holds reports none."""
    x = np.random.default_rng(3).normal(size=4000)
    for scale, skipped in ((1e33, True), (1.0, False)):
        p = tmp_path / "rec.npy"
        np.save(p, x * scale)
        argv = ("filter", p, "--rate-hz", RATE_HZ, "--gyro-units", "deg/h", "--filter",
                "realtime-wavelet", "--core", "float", "--json", "-o", tmp_path / "y.npy")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            code, out, err = run(capsys, *argv)
        assert code == 0, err
        faults = json.loads(out)["filter"]["faults"]
        said = [str(w.message) for w in caught if "skipped" in str(w.message)]
        if skipped:
            assert faults > 2000, faults
            assert len(said) == 1 and f"{faults} sample(s)" in said[0], said
        else:
            assert faults == 0 and not said, said


def test_simulate_without_noise_is_refused(tmp_path: Path, capsys) -> None:
    code, _, err = run(capsys, "simulate", "-o", tmp_path / "z.npy", "--samples", "100")
    one_line_error(code, err, "no noise term")
    assert not (tmp_path / "z.npy").exists()


def test_rate_contradicting_the_time_column(tmp_path: Path, capsys) -> None:
    x = np.random.default_rng(3).normal(size=500)
    t = np.arange(x.size) / RATE_HZ
    p = tmp_path / "t.csv"
    write_table(p, t, x, ",")
    code, _, err = run(capsys, "allan", p, "--rate-hz", "400")
    one_line_error(code, err, "contradicts", "100", "--force-rate")
    code, out, _ = run(capsys, "allan", p, "--rate-hz", "400", "--force-rate", "--json")
    assert code == 0 and '"rate_hz": 400.0' in out
    code, out, _ = run(capsys, "allan", p, "--rate-hz", "100.2", "--json")  # within 1 %
    assert code == 0


def test_failing_align_leaves_no_output_dir(tmp_path: Path, capsys) -> None:
    out = tmp_path / "al" / "run1"
    code, _, err = run(capsys, "align", "--out-dir", out, "--runs", "1")
    one_line_error(code, err, "--runs")
    assert files(tmp_path) == set()  # neither run1 nor the parent it created


# ------------------------------------------------------------------ child processes


def _cli(*argv: object, **kw: object) -> subprocess.Popen[bytes]:
    env = dict(os.environ)
    return subprocess.Popen([sys.executable, "-m", "gyrodrift", *with_units(argv)], env=env,
                            **kw)  # type: ignore[call-overload]


def test_broken_pipe_is_one_line(rec: Path) -> None:
    """`gyrodrift allan ... | head -0`: the reader is gone before the table is printed."""
    proc = _cli("allan", rec, "--rate-hz", RATE_HZ, stdout=subprocess.PIPE,
                stderr=subprocess.PIPE)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # the reader leaves at once
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 2, err
    assert err.strip().splitlines() == ["gyrodrift allan: error: output pipe closed by the reader"]


def test_ctrl_c_exits_130_with_one_line_and_no_partial_output(tmp_path: Path) -> None:
    """SIGINT while align works: exit 130, one line, and the output directory it created is
    gone again (no partial files)."""
    out = tmp_path / "mc"
    proc = _cli("align", "--out-dir", out, "--runs", "50", "--duration-s", "600",
                stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while not out.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)  # the directory appears when the work starts
    assert out.exists(), "align did not start"
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    text = err.decode()
    assert proc.returncode == 130, text
    assert text.strip().splitlines() == ["gyrodrift align: interrupted"]
    assert not out.exists()


def test_ctrl_c_during_replay_ends_the_loop_child(tmp_path: Path, cpp_build_dir: Path) -> None:
    """SIGINT to the command alone (not its process group, so the loop child gets no signal
    of its own) while the replay runs: the harness ends the gyrodrift-loop child, the command
    exits 130 with one line and leaves no report files."""
    from gyrodrift.replay.harness import LOOP_RELATIVE

    out = tmp_path / "rep"
    proc = _cli("replay", "--duration-s", "120", "--no-rt", "--out-dir", out,
                "--loop-binary", cpp_build_dir / LOOP_RELATIVE, stdout=subprocess.PIPE,
                stderr=subprocess.PIPE, start_new_session=True)

    def children() -> list[int]:
        got = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True)
        return [int(x) for x in got.stdout.split()]

    deadline = time.monotonic() + 180
    while not children() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    kids = children()
    assert kids, "the replay did not start its loop child"
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err.decode()
    assert err.decode().strip().splitlines() == ["gyrodrift replay: interrupted"]
    time.sleep(0.5)
    assert not [k for k in kids if Path(f"/proc/{k}").exists()], "loop child still running"
    assert not out.exists() or files(out) == set()


@pytest.mark.parametrize("failing", ["plot_allan", "plot_psd"])
def test_compare_failure_midway_leaves_no_file(tmp_path: Path, rec: Path, capsys,
                                               monkeypatch: pytest.MonkeyPatch,
                                               failing: str) -> None:
    """`compare --out-dir` writes five files; a writer that fails after writing part of its
    file (a full disk) must leave none of them, partial or complete, and no directory it
    made. Before, compare.md and compare.csv stayed, and the failing PNG stayed half
    written (issue 13)."""
    from gyrodrift.report import plots

    def fail_midway(series: object, path: str | Path, **kw: object) -> None:
        Path(path).write_bytes(b"\x89PNG partial")
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(plots, failing, fail_midway)
    out = tmp_path / "report"
    code, _, err = run(capsys, "compare", rec, "--rate-hz", "100", "--out-dir", out)
    one_line_error(code, err, "No space left on device")
    assert not out.exists() or files(out) == set(), files(out)
    assert files(tmp_path) == {"rec.npy"} or files(tmp_path) == {"rec.npy", "report"}
