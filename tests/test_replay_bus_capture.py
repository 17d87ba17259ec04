"""Real bus captures: a CAN log with other nodes' traffic (foreign standard and extended IDs,
remote frames, error frames) between the IMU's frames, written with python-can's own writers
in every CAN log format the project reads. The reader must skip and count every non-IMU frame
(by ID; remote and error frames separately), use the IMU frames, and account for every frame;
a replay of such a capture must run and report the same counts.
"""

from __future__ import annotations

import json
from pathlib import Path

import can
import numpy as np
import pytest
from gyrodrift.codecs import INPUT_BASE_ID, encode_sample
from gyrodrift.imu.config import default_config
from gyrodrift.io.imu_log import CAN_FORMATS, read_imu_log
from gyrodrift.replay.harness import LOOP_RELATIVE, ReplayOptions, run_replay

SUFFIX = {"candump": ".log", "asc": ".asc", "blf": ".blf"}
RATE_HZ = 400.0


def _bus_capture(path: Path, n: int, rng: np.random.Generator) -> dict[str, object]:
    """Write n IMU samples interleaved with other traffic; return what was written."""
    gyro = rng.normal(0.0, 1e-4, (n, 3))
    accel = rng.normal(0.0, 1e-2, (n, 3)) + np.array([0.0, 0.0, 9.80665])
    values = np.concatenate([gyro, accel], axis=1).astype(np.float32)
    foreign_std = {0x080: 0, 0x3E8: 0, 0x104: 0}  # 0x104 sits just above the IMU's IDs
    foreign_ext = {0x18FEF100: 0, 0x100: 0}  # an extended frame with the IMU's number
    remote = error = 0
    total = 0
    with can.Logger(str(path)) as w:
        def put(m: can.Message, t: float) -> None:
            nonlocal total
            m.timestamp = t
            m.channel = 0
            w.on_message_received(m)
            total += 1

        for k in range(n):
            t = 100.0 + k / RATE_HZ
            for j, m in enumerate(encode_sample(k, values[k])):
                put(m, t + j * 1e-5)
                # Other nodes talk between the IMU's frames.
                if j == 1 and k % 3 == 0:
                    fid = (0x080, 0x3E8, 0x104)[k % 9 // 3]
                    put(can.Message(arbitration_id=fid, data=bytes([k % 256, 1, 2]),
                                    is_extended_id=False), t + 1.5e-5)
                    foreign_std[fid] += 1
                if j == 2 and k % 4 == 1:
                    fid = 0x18FEF100 if k % 8 == 1 else 0x100
                    put(can.Message(arbitration_id=fid, data=bytes(8), is_extended_id=True),
                        t + 2.5e-5)
                    foreign_ext[fid] += 1
            if k % 5 == 2:
                # A remote request for one of the IMU's own IDs: not data, never used.
                put(can.Message(arbitration_id=INPUT_BASE_ID + 1, is_remote_frame=True, dlc=8,
                                is_extended_id=False), t + 5e-5)
                remote += 1
            if k % 7 == 3:
                put(can.Message(is_error_frame=True, arbitration_id=0, dlc=0), t + 6e-5)
                error += 1
    return {"values": values, "foreign_std": foreign_std, "foreign_ext": foreign_ext,
            "remote": remote, "error": error, "total": total}


def _check_report(rep: dict, want: dict, n: int) -> None:
    assert rep["frames_total"] == want["total"]
    assert rep["imu_frames_used"] == 4 * n
    assert rep["remote_frames"] == want["remote"]
    assert rep["error_frames"] == want["error"]
    expected_foreign = {f"{i:#05x}": c for i, c in want["foreign_std"].items() if c}
    expected_foreign |= {f"{i:#010x} ext": c for i, c in want["foreign_ext"].items() if c}
    assert rep["foreign_frames_by_id"] == expected_foreign
    assert rep["imu_samples"] == n
    assert rep["imu_frames_dropped"] == 0 and rep["incomplete_samples"] == 0
    # Every frame is accounted for exactly once.
    assert (rep["imu_frames_used"] + rep["imu_frames_dropped"] + rep["remote_frames"]
            + rep["error_frames"] + sum(rep["foreign_frames_by_id"].values())
            == rep["frames_total"])


@pytest.mark.parametrize("fmt", CAN_FORMATS)
def test_bus_capture_is_read_and_every_frame_counted(tmp_path: Path, rng: np.random.Generator,
                                                     fmt: str) -> None:
    n = 90
    path = tmp_path / f"bus{SUFFIX[fmt]}"
    want = _bus_capture(path, n, rng)
    # The capture really holds what the test says (read back with python-can alone).
    msgs = list(can.LogReader(str(path)))
    assert len(msgs) == want["total"]
    assert sum(m.is_error_frame for m in msgs) == want["error"]
    assert sum(m.is_remote_frame for m in msgs) == want["remote"]
    s = read_imu_log(path)
    assert len(s) == n
    np.testing.assert_array_equal(s.seq, np.arange(n, dtype=np.uint16))
    np.testing.assert_array_equal(s.channels, want["values"])
    assert s.log_report is not None
    _check_report(s.log_report.as_dict(), want, n)


def test_incomplete_samples_are_counted_not_fatal(tmp_path: Path,
                                                  rng: np.random.Generator) -> None:
    # A capture that starts and ends in the middle of a sample: the partial ones are counted.
    full = tmp_path / "full.log"
    _bus_capture(full, 12, rng)
    msgs = list(can.LogReader(str(full)))
    imu_idx = [i for i, m in enumerate(msgs) if not m.is_error_frame and not m.is_remote_frame
               and not m.is_extended_id and 0x100 <= m.arbitration_id <= 0x103]
    cut = msgs[imu_idx[2]:imu_idx[-2]]  # drop sample 0's first two and sample 11's last two
    out = tmp_path / "cut.log"
    with can.Logger(str(out)) as w:
        for m in cut:
            w.on_message_received(m)
    s = read_imu_log(out)
    np.testing.assert_array_equal(s.seq, np.arange(1, 11, dtype=np.uint16))
    rep = s.log_report.as_dict()
    assert rep["incomplete_samples"] == 2 and rep["imu_frames_dropped"] == 4
    assert rep["imu_frames_used"] == 40
    assert (rep["imu_frames_used"] + rep["imu_frames_dropped"] + rep["remote_frames"]
            + rep["error_frames"] + sum(rep["foreign_frames_by_id"].values())
            == rep["frames_total"] == len(cut))


def test_capture_without_imu_samples_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "other.log"
    with can.Logger(str(path)) as w:
        for k in range(5):
            w.on_message_received(can.Message(timestamp=k * 0.01, arbitration_id=0x3E8,
                                              data=b"\x01", channel=0, is_extended_id=False))
    with pytest.raises(ValueError, match=r"no IMU samples.*5 frames.*0x3e8"):
        read_imu_log(path)


def test_replay_of_a_bus_capture(tmp_path: Path, rng: np.random.Generator,
                                 cpp_build_dir: Path) -> None:
    n = 160
    path = tmp_path / "bus.blf"
    want = _bus_capture(path, n, rng)
    samples = read_imu_log(path)
    res = run_replay(samples, ReplayOptions(
        transport="slcan", speed=0.0, loop_binary=str(cpp_build_dir / LOOP_RELATIVE),
        processor=default_config(sample_rate_hz=RATE_HZ).with_timing(loop_rate_hz=1000.0)))
    rep = res.report
    assert rep["ok"], {k: v for k, v in rep["checks"].items() if not v}
    assert rep["accounting"]["outputs_received"] == n and rep["accounting"]["unaccounted"] == 0
    _check_report(rep["input_log"], want, n)


def test_replay_cli_prints_the_capture_counts(tmp_path: Path, rng: np.random.Generator,
                                              cpp_build_dir: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    import argparse

    from gyrodrift.cli import replay as replay_cli

    n = 80
    path = tmp_path / "bus.asc"
    want = _bus_capture(path, n, rng)
    parser = argparse.ArgumentParser(prog="gyrodrift")
    replay_cli.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["replay", str(path), "--transport", "slcan", "--fast",
                              "--loop-binary", str(cpp_build_dir / LOOP_RELATIVE),
                              "--loop-rate-hz", "1000", "--out-dir", str(tmp_path / "rep")])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert f"{want['total']} frames" in out and f"error {want['error']}" in out
    assert f"remote {want['remote']}" in out
    rep = json.loads((tmp_path / "rep" / "report.json").read_text())
    _check_report(rep["input_log"], want, n)


def test_allan_on_a_bus_capture(tmp_path: Path, rng: np.random.Generator,
                                capsys: pytest.CaptureFixture[str]) -> None:
    from gyrodrift.cli import main

    n = 400
    path = tmp_path / "bus.log"
    want = _bus_capture(path, n, rng)
    rc = main(["allan", str(path)])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert f"{want['total']} frames" in out and f"{4 * n} IMU frames used" in out
