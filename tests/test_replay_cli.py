"""`gyrodrift replay` end to end: the simulated demo, a log file input, and user errors."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.cli import CliError
from gyrodrift.cli import replay as replay_cli
from gyrodrift.io.imu_log import write_imu_log
from gyrodrift.replay.harness import LOOP_RELATIVE


def _run(argv: list[str]) -> int:
    # Only this subcommand: the CLI module must work on its own.
    parser = argparse.ArgumentParser(prog="gyrodrift")
    replay_cli.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["replay", *argv])
    return args.func(args)


@pytest.fixture(scope="module")
def loop_bin(cpp_build_dir: Path) -> str:
    return str(cpp_build_dir / LOOP_RELATIVE)


def test_demo_without_input(tmp_path: Path, loop_bin: str,
                            capsys: pytest.CaptureFixture[str]) -> None:
    rc = _run(["--duration-s", "1.5", "--fast", "--loop-binary", loop_bin,
               "--fault-corrupt", "0.02", "--seed", "3", "--out-dir", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "PASS" in out and "unaccounted" in out
    rep = json.loads((tmp_path / "report.json").read_text())
    assert rep["ok"] and rep["accounting"]["unaccounted"] == 0
    assert rep["accounting"]["samples_in_record"] == 600  # 1.5 s at 400 Hz
    assert rep["accounting"]["rejected_on_link"]["crc"] == rep["accounting"]["injected"]["corrupt"]
    assert (tmp_path / "report.png").stat().st_size > 10_000


@pytest.mark.parametrize("suffix", [".bin", ".csv", ".log"])
def test_log_input_real_time(tmp_path: Path, loop_bin: str, suffix: str,
                             capsys: pytest.CaptureFixture[str]) -> None:
    n, rate = 400, 400.0
    rng = np.random.default_rng(2)
    log = write_imu_log(tmp_path / f"rec{suffix}", np.arange(n) / rate,
                        rng.normal(0, 1e-4, (n, 3)), rng.normal(0, 1e-2, (n, 3)) + 9.8)
    transport = "slcan" if suffix == ".log" else "serial"
    rc = _run([str(log), "--transport", transport, "--loop-binary", loop_bin,
               "--loop-rate-hz", "1000", "--out-dir", str(tmp_path / "rep")])
    out = capsys.readouterr().out
    assert rc == 0, out
    rep = json.loads((tmp_path / "rep" / "report.json").read_text())
    assert rep["accounting"]["outputs_received"] == n
    assert rep["speed"] == "1x"


def test_user_errors(tmp_path: Path, loop_bin: str) -> None:
    with pytest.raises(CliError, match="no such log"):
        _run([str(tmp_path / "missing.bin"), "--loop-binary", loop_bin])
    bad = tmp_path / "bad.toml"
    bad.write_text('schema = "gyrodrift.processor"\nversion = 1\n')
    with pytest.raises(CliError, match="timing: missing value"):
        _run(["--config", str(bad), "--loop-binary", loop_bin])
    with pytest.raises(CliError, match="does not exist"):
        _run(["--duration-s", "0.5", "--fast", "--loop-binary", str(tmp_path / "nope")])
    with pytest.raises(CliError, match="rates sum"):
        _run(["--fault-drop", "0.7", "--fault-corrupt", "0.7", "--loop-binary", loop_bin])
    with pytest.raises(CliError, match="loop-rate-hz"):
        _run(["--loop-rate-hz", "5000", "--loop-binary", loop_bin])


@pytest.mark.parametrize("choice", ["always", "never", "auto"])
def test_progress_bar_only_when_asked_or_on_a_terminal(tmp_path: Path, loop_bin: str,
                                                       choice: str,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    # capsys's stderr is not a terminal: `always` draws the bar there, `never` and `auto` stay
    # quiet (CONTRIBUTING.md: --progress auto|always|never, auto only on a terminal).
    rc = _run(["--duration-s", "0.5", "--fast", "--loop-binary", loop_bin, "--progress", choice,
               "--out-dir", str(tmp_path)])
    cap = capsys.readouterr()
    assert rc == 0, cap.out
    if choice == "always":
        assert "replay" in cap.err and "200/200" in cap.err, cap.err
    else:
        assert cap.err == ""
