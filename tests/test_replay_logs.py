"""Replay logs and bulk wire encoding: round trips in every format, hand-checked bytes, errors."""

from __future__ import annotations

import struct
from pathlib import Path

import can
import numpy as np
import pytest
from gyrodrift.codecs import FrameParser, crc16_ccitt_false
from gyrodrift.codecs.wire import (
    decode_stream,
    encode_frames,
    make_samples,
)
from gyrodrift.io.imu_log import FORMATS, read_imu_log, write_imu_log

SUFFIX = {"bin": ".bin", "csv": ".csv", "candump": ".log", "asc": ".asc", "blf": ".blf"}


def _record(rng: np.random.Generator, n: int = 700) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t_s = np.arange(n) * 0.0025 + 12.5  # 400 Hz
    gyro = rng.normal(0.0, 1e-3, (n, 3)) + np.array([7.3e-5, 0.0, 2e-5])
    accel = rng.normal(0.0, 1e-2, (n, 3)) + np.array([0.0, 0.0, 9.80665])
    return t_s, gyro, accel


def test_crc_check_value() -> None:
    # The catalogued check value of CRC-16/CCITT-FALSE over ASCII "123456789".
    assert crc16_ccitt_false(b"123456789") == 0x29B1


def test_frame_bytes_hand_checked() -> None:
    s = make_samples(np.array([1.5]), np.array([[1.0, -2.0, 0.5]]), np.array([[0.0, 0.0, 9.75]]))
    s.seq[:] = 0x1234
    raw = encode_frames(s)[0].tobytes()
    body = bytes([0x01, 36]) + struct.pack("<HHQ6f", 0x1234, 0, 1_500_000,
                                           1.0, -2.0, 0.5, 0.0, 0.0, 9.75)
    assert raw[:2] == b"\xa5\x5a"
    assert raw[2:40] == body
    assert raw[4:6] == b"\x34\x12"  # little-endian seq
    assert raw[8:16] == (1_500_000).to_bytes(8, "little")
    assert raw[40:42] == crc16_ccitt_false(body).to_bytes(2, "little")
    assert len(raw) == 42


@pytest.mark.parametrize("fmt", FORMATS)
def test_round_trip_every_format(tmp_path: Path, rng: np.random.Generator, fmt: str) -> None:
    t_s, gyro, accel = _record(rng)
    path = write_imu_log(tmp_path / f"rec{SUFFIX[fmt]}", t_s, gyro, accel)
    back = read_imu_log(path)
    assert len(back) == t_s.size
    # float32 on the wire: exact equality with the float32-rounded input.
    np.testing.assert_array_equal(back.channels[:, :3], gyro.astype(np.float32))
    np.testing.assert_array_equal(back.channels[:, 3:], accel.astype(np.float32))
    np.testing.assert_array_equal(back.seq, np.arange(t_s.size, dtype=np.uint16))
    got, want = back.t_s, t_s
    if fmt in ("asc", "blf"):  # these formats store time relative to the first message
        got, want = got - got[0], want - want[0]
    # Timestamps: microsecond resolution (0.5 us rounding bound on each of two stamps).
    assert np.max(np.abs(got - want)) <= 1e-6 + 1e-12


def test_explicit_format_overrides_suffix(tmp_path: Path, rng: np.random.Generator) -> None:
    t_s, gyro, accel = _record(rng, 10)
    path = write_imu_log(tmp_path / "rec.dat", t_s, gyro, accel, fmt="bin")
    assert path.stat().st_size == 10 * 42
    assert len(read_imu_log(path, fmt="bin")) == 10


def test_sequence_wraps(rng: np.random.Generator) -> None:
    n = 70000
    s = make_samples(np.arange(n) * 1e-3, np.zeros((n, 3)), np.zeros((n, 3)))
    assert s.seq[65535] == 65535 and s.seq[65536] == 0 and s.seq[-1] == (n - 1) % 65536


def test_bad_inputs_raise(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="suffix"):
        write_imu_log(tmp_path / "x.xyz", np.zeros(2), np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="shape"):
        write_imu_log(tmp_path / "x.bin", np.zeros(2), np.zeros((2, 2)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="non-empty"):
        write_imu_log(tmp_path / "x.bin", np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
    with pytest.raises(ValueError, match="non-decreasing"):
        write_imu_log(tmp_path / "x.bin", np.array([1.0, 0.5]), np.zeros((2, 3)),
                      np.zeros((2, 3)))
    with pytest.raises(ValueError, match="non-finite"):
        write_imu_log(tmp_path / "x.bin", np.array([0.0, np.nan]), np.zeros((2, 3)),
                      np.zeros((2, 3)))
    with pytest.raises(FileNotFoundError):
        read_imu_log(tmp_path / "missing.bin")


def test_corrupted_binary_log_is_an_error(tmp_path: Path, rng: np.random.Generator) -> None:
    t_s, gyro, accel = _record(rng, 50)
    path = write_imu_log(tmp_path / "rec.bin", t_s, gyro, accel)
    data = bytearray(path.read_bytes())
    data[42 * 7 + 20] ^= 0x40  # flip one payload bit of frame 7
    path.write_bytes(bytes(data) + b"\xa5\x5a\x01")  # and a truncated tail
    with pytest.raises(ValueError, match="crc_errors': 1"):
        read_imu_log(path)


def test_decode_stream_resynchronises(rng: np.random.Generator) -> None:
    t_s, gyro, accel = _record(rng, 40)
    frames = encode_frames(make_samples(t_s, gyro, accel))
    junk = bytes(rng.integers(0, 256, 17, dtype=np.uint8))
    bad = bytearray(frames[5].tobytes())
    bad[30] ^= 1
    stream = (junk + frames[:5].tobytes() + bytes(bad) + frames[6:].tobytes() + b"\xa5\x5a\x01\x24")
    dec = decode_stream(stream)
    assert list(dec.samples.seq) == [k for k in range(40) if k != 5]
    assert dec.crc_errors == 1
    assert dec.truncated_bytes == 4
    # The junk (17 bytes) plus the corrupted frame's bytes are skipped as garbage.
    assert dec.garbage_bytes == 17 + 42


def test_decoder_agrees_with_codecs_parser(rng: np.random.Generator) -> None:
    t_s, gyro, accel = _record(rng, 60)
    frames = encode_frames(make_samples(t_s, gyro, accel)).tobytes()
    stream = b"\x00\x13" + frames[:700] + b"\xa5" + frames[700:]
    ours = decode_stream(stream)
    theirs = FrameParser().feed(stream)
    assert [f.seq for f in theirs] == list(ours.samples.seq)
    np.testing.assert_array_equal(np.array([f.values for f in theirs], np.float32),
                                  ours.samples.channels)


def test_can_log_frames_match_the_dbc(tmp_path: Path, rng: np.random.Generator) -> None:
    t_s, gyro, accel = _record(rng, 5)
    path = write_imu_log(tmp_path / "rec.log", t_s, gyro, accel)
    msgs = list(can.LogReader(str(path)))
    assert [m.arbitration_id for m in msgs[:4]] == [0x100, 0x101, 0x102, 0x103]
    # Hand-checked layout of 0x101 (sample 1): GyroZ float32, Seq u16, Flags u16, little-endian.
    assert bytes(msgs[5].data) == struct.pack("<fHH", np.float32(gyro[1, 2]), 1, 0)
    assert all(m.timestamp == pytest.approx(t_s[k // 4], abs=1e-6) for k, m in enumerate(msgs))


def test_incomplete_can_log_is_counted(tmp_path: Path, rng: np.random.Generator) -> None:
    # A capture cut inside the last sample: that sample is counted as incomplete, the others
    # are used (a real capture starts and stops anywhere; see test_replay_bus_capture.py).
    t_s, gyro, accel = _record(rng, 10)
    path = write_imu_log(tmp_path / "rec.log", t_s, gyro, accel)
    msgs = list(can.LogReader(str(path)))
    out = tmp_path / "cut.log"
    with can.Logger(str(out)) as w:
        for m in msgs[:-1]:
            w.on_message_received(m)
    back = read_imu_log(out)
    np.testing.assert_array_equal(back.seq, np.arange(9, dtype=np.uint16))
    assert back.log_report is not None
    assert back.log_report.incomplete_samples == 1
    assert back.log_report.imu_frames_dropped == 3
    assert back.log_report.frames_total == 39


@pytest.mark.parametrize("fmt", FORMATS)
def test_fault_values_are_written_in_every_format(tmp_path: Path, fmt: str) -> None:
    # The issue's reproduction (+Inf in a .log raised cantools' EncodeError) and every other
    # value a faulty IMU can put on the wire: +-FLT_MAX, +-Inf, NaN, the smallest subnormal.
    big = float(np.finfo(np.float32).max)
    tiny = float(np.finfo(np.float32).smallest_subnormal)
    path = write_imu_log(tmp_path / f"c{SUFFIX[fmt]}", np.arange(2) / 400,
                         np.array([[np.inf, 0, 0], [0, 0, 0]]), np.zeros((2, 3)))
    assert len(read_imu_log(path)) == 2
    faults = np.array([[big, -big, np.inf], [-np.inf, np.nan, tiny], [-0.0, 1.0, -tiny]])
    path = write_imu_log(tmp_path / f"f{SUFFIX[fmt]}", np.arange(3) / 400, faults, faults[::-1])
    back = read_imu_log(path)
    want = np.concatenate([faults, faults[::-1]], axis=1).astype(np.float32)
    np.testing.assert_array_equal(back.channels, want)  # NaN == NaN for assert_array_equal
    assert np.array_equal(np.signbit(back.channels), np.signbit(want))  # -0.0 kept
