"""IMU logs and PSINS logs read in blocks (gyrodrift.io.imu_log.ImuLogBlocks,
gyrodrift.io.psins.PsinsBlocks, the bounded readers of load_imu and load_record) give what
the whole-file read gives: the same samples bit for bit, the same counts (a CAN log's
frame report, the binary decoder's CRC errors, garbage and truncated tail) and the same
error, with blocks that cut the file inside a frame, a sample or between lines; on clean
and on damaged logs.

The whole-file read is `read_imu_log` / `read_psins_imu` (one block: the default block
sizes exceed these logs), whose formats and counts the tests of test_replay_logs.py,
test_replay_bus_capture.py and test_can_signals.py check against hand-made logs."""

from __future__ import annotations

import tempfile
from pathlib import Path

import can
import numpy as np
import pytest
from gyrodrift.codecs import INPUT_BASE_ID, encode_sample
from gyrodrift.codecs.wire import (
    Samples,
    StreamDecoder,
    decode_stream,
    encode_frames,
    make_samples,
)
from gyrodrift.errors import GyrodriftValueError
from gyrodrift.io import imu_log, psins, records, spool
from gyrodrift.io.imu_data import load_imu
from gyrodrift.io.imu_log import ImuLogBlocks, read_imu_log, write_imu_log
from gyrodrift.io.psins import PsinsBlocks, read_psins_imu
from gyrodrift.io.records import load_record

DATA = Path(__file__).parent / "data"
SUFFIX = {"candump": ".log", "asc": ".asc", "blf": ".blf"}
RATE_HZ = 400.0


def _joined(parts: list[Samples]) -> Samples:
    return Samples(np.concatenate([p.seq for p in parts]), np.concatenate([p.flags for p in parts]),
                   np.concatenate([p.t_us for p in parts]),
                   np.concatenate([p.channels for p in parts]))


def _same_samples(a: Samples, b: Samples) -> None:
    np.testing.assert_array_equal(a.seq, b.seq)
    np.testing.assert_array_equal(a.flags, b.flags)
    np.testing.assert_array_equal(a.t_us, b.t_us)
    assert a.channels.dtype == b.channels.dtype == np.float32
    # bit patterns: NaN payloads and the sign of zero too
    np.testing.assert_array_equal(a.channels.view(np.uint32), b.channels.view(np.uint32))


def _error(fn) -> str:  # type: ignore[no-untyped-def]
    with pytest.raises(GyrodriftValueError) as info:
        fn()
    return str(info.value)


def _record(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t_s = 3.0 + np.arange(n) / RATE_HZ
    gyro = rng.normal(0.0, 1e-3, (n, 3))
    accel = rng.normal(0.0, 1e-2, (n, 3)) + np.array([0.0, 0.0, 9.80665])
    return t_s, gyro, accel


# ------------------------------------------------------------------- the binary frame decoder

def _damaged_stream(rng: np.random.Generator) -> bytes:
    """Frames with garbage before them, one CRC failure, a lone sync byte, a cut frame in
    the middle and a truncated tail."""
    t_s, gyro, accel = _record(rng, 12)
    frames = encode_frames(make_samples(t_s, gyro, accel))
    bad = bytearray(frames[4].tobytes())
    bad[25] ^= 0x10
    return (b"\x13\x37\xa5" + frames[:4].tobytes() + bytes(bad) + frames[5:7].tobytes()
            + b"\xa5" + frames[7].tobytes()[:30] + frames[8:].tobytes() + b"\xa5\x5a\x01")


def test_stream_decoder_in_pieces_equals_one_call(rng: np.random.Generator) -> None:
    """Every cut of a damaged stream into two pieces, and into pieces of 1..45 bytes: the
    frames, their end offsets and the counts of one call on the whole stream."""
    data = _damaged_stream(rng)
    whole = decode_stream(data)
    # hand-counted: 10 good frames; two CRC failures (frame 4, and frame 7's header followed
    # by frame 8's bytes); garbage = 3 + frame 4 (42) + the lone 0xa5 and frame 7's first 30
    # bytes; tail 3 bytes
    assert list(whole.samples.seq) == [0, 1, 2, 3, 5, 6, 8, 9, 10, 11]
    assert (whole.crc_errors, whole.garbage_bytes, whole.truncated_bytes) == (2, 3 + 42 + 31, 3)
    cuts = [[k] for k in range(len(data) + 1)] + [list(range(0, len(data), w))[1:]
                                                  for w in range(1, 46)]
    for cut in cuts:
        dec = StreamDecoder()
        parts, lo = [], 0
        for hi in cut:
            parts.append(dec.feed(data[lo:hi]))
            lo = hi
        parts.append(dec.feed(data[lo:], final=True))
        _same_samples(_joined([p.samples for p in parts]), whole.samples)
        np.testing.assert_array_equal(np.concatenate([p.end_offset for p in parts]),
                                      whole.end_offset)
        np.testing.assert_array_equal(np.concatenate([p.frame_type for p in parts]),
                                      whole.frame_type)
        last = parts[-1]
        assert (last.crc_errors, last.garbage_bytes, last.truncated_bytes) == (
            whole.crc_errors, whole.garbage_bytes, whole.truncated_bytes), cut


def test_stream_decoder_refuses_data_after_the_end() -> None:
    dec = StreamDecoder()
    dec.feed(b"", final=True)
    with pytest.raises(GyrodriftValueError, match="ended"):
        dec.feed(b"\xa5")


@pytest.mark.parametrize("chunk_bytes", [1, 5, 41, 42, 43, 100, 1 << 20])
def test_binary_log_in_chunks(tmp_path: Path, rng: np.random.Generator,
                              chunk_bytes: int) -> None:
    t_s, gyro, accel = _record(rng, 50)
    gyro[3, 1], accel[7, 2] = np.nan, -0.0
    path = write_imu_log(tmp_path / "rec.bin", t_s, gyro, accel)
    blocks = list(ImuLogBlocks(path, chunk_bytes=chunk_bytes))
    _same_samples(_joined(blocks), read_imu_log(path))
    assert (len(blocks) > 1) == (chunk_bytes < 50 * 42)
    # damaged logs: the same refusal, with the same counts, however the file is cut
    data = path.read_bytes()
    for name, bad in (("crc", data[:300] + bytes([data[300] ^ 1]) + data[301:]),
                      ("garbage", data[:420] + b"\x00\xa5" + data[420:]),
                      ("tail", data + b"\xa5\x5a\x01\x24"),
                      ("cut", data[:1000] + data[1010:])):
        p = tmp_path / f"{name}.bin"
        p.write_bytes(bad)
        want = _error(lambda p=p: read_imu_log(p))
        assert "corrupted binary frame log" in want
        assert _error(lambda p=p: list(ImuLogBlocks(p, chunk_bytes=chunk_bytes))) == want


# ------------------------------------------------------------------------------- CAN logs

def _bus_capture(path: Path, n: int, rng: np.random.Generator) -> None:
    """n IMU samples among other nodes' frames (foreign standard and extended IDs, remote and
    error frames), damaged: the capture starts inside sample 0 and ends inside the last
    sample, one frame is lost (an orphan half), one repeated (a duplicate), one has a bad
    DLC."""
    values = np.concatenate(_record(rng, n)[1:], axis=1).astype(np.float32)
    values[5, 0] = np.nan
    msgs: list[can.Message] = []
    for k in range(n):
        t = 20.0 + k / RATE_HZ
        for j, m in enumerate(encode_sample(k, values[k], flags=k % 3)):
            m.timestamp = t + j * 1e-5
            msgs.append(m)
            if j == 1 and k % 3 == 0:
                msgs.append(can.Message(timestamp=t + 1.5e-5, arbitration_id=0x3E8,
                                        data=bytes([k % 256]), is_extended_id=False))
            if j == 2 and k % 4 == 1:
                msgs.append(can.Message(timestamp=t + 2.5e-5, arbitration_id=0x100,
                                        data=bytes(8), is_extended_id=True))
        if k % 5 == 2:
            msgs.append(can.Message(timestamp=t + 5e-5, arbitration_id=INPUT_BASE_ID + 1,
                                    is_remote_frame=True, dlc=8, is_extended_id=False))
        if k % 7 == 3:
            msgs.append(can.Message(timestamp=t + 6e-5, is_error_frame=True,
                                    arbitration_id=0, dlc=0))
    imu = [i for i, m in enumerate(msgs) if not m.is_extended_id and not m.is_remote_frame
           and not m.is_error_frame and 0x100 <= m.arbitration_id <= 0x103]
    msgs[imu[4 * 9 + 1]] = can.Message(timestamp=msgs[imu[4 * 9 + 1]].timestamp,
                                       arbitration_id=0x101, data=bytes(4),
                                       is_extended_id=False)  # bad DLC
    msgs.insert(imu[4 * 12 + 1] + 1, msgs[imu[4 * 12 + 1]])  # a duplicate
    del msgs[imu[4 * 6 + 2]]  # a lost frame
    with can.Logger(str(path)) as w:
        for m in msgs[imu[2]:imu[-2]]:
            m.channel = 0
            w.on_message_received(m)


@pytest.mark.parametrize("fmt", ["candump", "blf"])
def test_can_log_in_blocks(tmp_path: Path, rng: np.random.Generator, fmt: str) -> None:
    path = tmp_path / f"bus{SUFFIX[fmt]}"
    _bus_capture(path, 40, rng)
    whole = read_imu_log(path)
    rep = whole.log_report
    assert rep is not None
    # the damage is there: every kind of count is non-zero
    assert min(rep.incomplete_samples, rep.orphan_frames, rep.duplicate_frames, rep.bad_dlc,
               rep.remote_frames, rep.error_frames, rep.foreign_frames) > 0, rep
    for size in (1, 2, 3, 7, 36):
        blocks = ImuLogBlocks(path, block_samples=size)
        parts = list(blocks)
        assert [len(p) for p in parts[:-1]] == [size] * (len(parts) - 1)
        _same_samples(_joined(parts), whole)
        assert blocks.report is not None and blocks.report.as_dict() == rep.as_dict()


def test_can_log_without_samples_is_refused_in_blocks(tmp_path: Path) -> None:
    path = tmp_path / "other.log"
    with can.Logger(str(path)) as w:
        for k in range(5):
            w.on_message_received(can.Message(timestamp=k * 0.01, arbitration_id=0x3E8,
                                              data=b"\x01", channel=0, is_extended_id=False))
    want = _error(lambda: read_imu_log(path))
    assert _error(lambda: list(ImuLogBlocks(path, block_samples=1))) == want


def test_can_log_with_a_signal_map_in_blocks(tmp_path: Path, rng: np.random.Generator) -> None:
    """A user's DBC (tests/data/vendor_imu.dbc through vendor_imu_map.toml): samples of
    three frames each with other pages and another ECU's frames between them."""
    import cantools

    db = cantools.database.load_file(str(DATA / "vendor_imu.dbc"))
    rates, mux = db.get_message_by_name("VendorImu_Rates"), db.get_message_by_name("VendorImu_Mux")
    path = tmp_path / "vendor.log"
    with can.Logger(str(path)) as w:
        def put(m: cantools.database.can.Message, sig: dict[str, int], t: float) -> None:
            w.on_message_received(can.Message(
                timestamp=t, arbitration_id=m.frame_id, is_extended_id=m.is_extended_frame,
                data=m.encode(sig, scaling=False), channel=0))

        raw = rng.integers(-32768, 32768, (30, 6))
        for k in range(1, 30):  # the first sample's rates frame is not in the capture
            t = 7.0 + k / RATE_HZ
            if k:
                put(rates, {"RateX": int(raw[k, 0]), "RateY": int(raw[k, 1]),
                            "RateZ": int(raw[k, 2]), "Counter": k % 16, "Status": 3,
                            "Spare": 0}, t)
            put(mux, {"Page": 0, "AccelX": int(raw[k, 3]), "AccelY": int(raw[k, 4]),
                      "AccelZ": int(raw[k, 5])}, t + 1e-4)
            if k % 4 == 1:
                put(mux, {"Page": 2, "DiagCode": k}, t + 2e-4)
            put(mux, {"Page": 1, "TimeStamp": 1000 + 250 * k, "Temperature": 20}, t + 3e-4)
    smap = DATA / "vendor_imu_map.toml"
    whole = read_imu_log(path, signals=smap)
    assert len(whole) == 29 and whole.log_report is not None
    assert whole.log_report.imu_frames_ignored > 0
    for size in (1, 4):
        blocks = ImuLogBlocks(path, signals=smap, block_samples=size)
        _same_samples(_joined(list(blocks)), whole)
        assert blocks.report is not None
        assert blocks.report.as_dict() == whole.log_report.as_dict()


# -------------------------------------------------------------------------------- CSV logs

def test_csv_log_in_blocks(tmp_path: Path, rng: np.random.Generator) -> None:
    t_s, gyro, accel = _record(rng, 23)
    gyro[4, 2] = np.inf
    path = write_imu_log(tmp_path / "rec.csv", t_s, gyro, accel)
    lines = path.read_text().splitlines()
    path.write_text("\n".join([*lines[:5], "", *lines[5:]]) + "\n")  # a blank line
    whole = read_imu_log(path)
    assert len(whole) == 23
    for size in (1, 2, 3, 5, 22):
        _same_samples(_joined(list(ImuLogBlocks(path, block_samples=size))), whole)


def test_damaged_csv_logs_give_the_same_error_in_blocks(tmp_path: Path,
                                                        rng: np.random.Generator) -> None:
    t_s, gyro, accel = _record(rng, 12)
    path = write_imu_log(tmp_path / "rec.csv", t_s, gyro, accel)
    head, *rows = path.read_text().splitlines()
    back = list(rows)
    back[6] = back[6].replace(back[6].split(",")[0], "0.5", 1)  # time goes back at row 7
    cases = {
        "non-numeric": ([*rows[:8], rows[8].replace(",0,", ",x,", 1), *rows[9:]],
                        "line 10: non-numeric CSV field"),
        "width": ([*rows[:3], rows[3] + ",1", *rows[4:]], "line 5: expected 9 columns, got 10"),
        "time back": (back, "t_s must be finite, >= 0 and non-decreasing"),
        # the time goes back first, the malformed row comes later: the row is named, as the
        # whole-file parse names it
        "both": ([*back[:10], back[10] + ",1", *back[11:]], "line 12: expected 9 columns"),
        "no rows": ([], "no data rows"),
    }
    for name, (body, want) in cases.items():
        p = tmp_path / f"{name.replace(' ', '_')}.csv"
        p.write_text("\n".join([head, *body]) + "\n")
        message = _error(lambda p=p: read_imu_log(p))
        assert want in message, (name, message)
        for size in (1, 2, 5):
            got = _error(lambda p=p, size=size: list(ImuLogBlocks(p, block_samples=size)))
            assert got == message, (name, size)


# ------------------------------------------------------------------------------ PSINS logs

def _psins_text(counts: np.ndarray) -> str:
    head = ["% PSINS log", "0 0 30 0 0 0", "%  lat lon h t0 interval g",
            "34.2 108.9 380 0 2.5 9.79", "0.01 0.02 0.03 50 60 70"]
    body = []
    for k, row in enumerate(counts):
        body.append(" ".join(str(int(c)) for c in row) + (" # note" if k == 3 else ""))
        if k % 5 == 2:
            body.append("% a comment between the data lines")
        if k == 8:
            body.append("")
    return "\n".join(head + body) + "\n"


def test_psins_log_in_blocks(tmp_path: Path, rng: np.random.Generator) -> None:
    counts = rng.integers(-500, 500, (21, 6))
    path = tmp_path / "rec.imu"
    path.write_text(_psins_text(counts))
    whole = read_psins_imu(path)
    # the increments from the counts and scale factors (numpy, independently)
    arcsec = np.pi / 180.0 / 3600.0
    np.testing.assert_allclose(whole.dtheta, counts[:, :3] * [0.01, 0.02, 0.03] * arcsec,
                               rtol=1e-15)
    for size in (1, 2, 3, 7, 20):
        blocks = PsinsBlocks(path, block_lines=size)
        parts = list(blocks)
        assert blocks.dt_s == whole.dt_s and blocks.n == 21
        np.testing.assert_array_equal(np.concatenate([d for d, _ in parts]), whole.dtheta)
        np.testing.assert_array_equal(np.concatenate([v for _, v in parts]), whole.dv)


def test_damaged_psins_logs_give_the_same_error_in_blocks(tmp_path: Path,
                                                          rng: np.random.Generator) -> None:
    text = _psins_text(rng.integers(-500, 500, (12, 6)))
    lines = text.splitlines()
    first = 5  # index of the first data line

    def with_line(k: int, new: str) -> str:
        return "\n".join([*lines[:first + k], new, *lines[first + k + 1:]]) + "\n"

    cases = {
        "non-numeric": (with_line(9, "1 2 x 4 5 6"), ":15: malformed data line '1 2 x 4 5 6'"),
        "five counts": (with_line(6, "1 2 3 4 5"), ":12: a data line needs 6 counts, got 5"),
        "nan": (with_line(2, "1 2 nan 4 5 6"), ":8: non-finite counts"),
        # a NaN on line 8, three counts on line 9: the first is named
        "first of two": (with_line(2, "1 2 nan 4 5 6").replace(lines[first + 3], "1 2 3", 1),
                         ":8: non-finite counts"),
        "no data": ("\n".join(lines[:first]) + "\n% nothing\n", "no data lines"),
        "not utf-8": (None, "byte 60 is not UTF-8"),
    }
    for name, (body, want) in cases.items():
        p = tmp_path / f"{name.replace(' ', '_')}.imu"
        if body is None:
            raw = text.encode()
            p.write_bytes(raw[:60] + b"\xff" + raw[61:])
        else:
            p.write_text(body)
        message = _error(lambda p=p: read_psins_imu(p))
        assert want in message, (name, message)
        for size in (1, 2, 4):
            got = _error(lambda p=p, size=size: list(PsinsBlocks(p, block_lines=size)))
            assert got == message, (name, size)


# --------------------------------------------------------- load_imu and load_record in pieces

def _small_blocks(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """Every log read in small blocks (7 samples, 100 bytes, 5 lines) and its channels
    through temporary files (in a directory of their own, returned)."""
    monkeypatch.setattr(spool, "SPOOL_MIN_SAMPLES", 0)
    monkeypatch.setattr(spool, "BLOCK_ROWS", 11)
    monkeypatch.setattr(records, "BLOCK_ROWS", 11)
    monkeypatch.setattr(imu_log, "BLOCK_SAMPLES", 7)
    monkeypatch.setattr(imu_log, "CHUNK_BYTES", 100)
    monkeypatch.setattr(psins, "BLOCK_LINES", 5)
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    return tmp


def _logs(tmp_path: Path, rng: np.random.Generator) -> dict[str, Path]:
    """A record with a NaN sample as a binary, CSV and candump log; a PSINS log."""
    t_s, gyro, accel = _record(rng, 60)
    gyro[17, 0] = np.nan
    out = {fmt: write_imu_log(tmp_path / f"rec.{fmt}", t_s, gyro, accel)
           for fmt in ("bin", "csv", "log")}
    out["imu"] = tmp_path / "rec.imu"
    out["imu"].write_text(_psins_text(rng.integers(-500, 500, (60, 6))))
    return out


def _reads(path: Path) -> dict[str, object]:
    """Everything load_imu and load_record give for a log (values as float64 arrays)."""
    out: dict[str, object] = {}
    for policy in ("drop", "refuse"):
        try:
            rec = load_imu(path, nan_policy=policy)
            out[f"imu {policy}"] = ({k: np.array(v) for k, v in rec.channels.items()},
                                    rec.rate_hz, rec.n_total, rec.n_dropped, rec.fmt,
                                    rec.detail)
        except GyrodriftValueError as exc:
            out[f"imu {policy}"] = str(exc)
        for axis in "xyz":
            try:
                one = load_record(path, column=axis, nan_policy=policy)
                out[f"record {axis} {policy}"] = (np.array(one.rate_deg_h), one.rate_hz,
                                                  one.n_total, one.n_dropped, one.units_in,
                                                  one.column, one.log_summary)
            except GyrodriftValueError as exc:
                out[f"record {axis} {policy}"] = str(exc)
    return out


def _assert_same(a: object, b: object) -> None:
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys()
        for k in a:
            _assert_same(a[k], b[k])
    elif isinstance(a, tuple | list):
        assert isinstance(b, tuple | list) and len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            _assert_same(x, y)
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype
        np.testing.assert_array_equal(a, b)
    else:
        assert a == b


def test_load_imu_and_load_record_of_logs_in_pieces(tmp_path: Path, rng: np.random.Generator,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """The analysis readers on logs: read in small blocks into temporary files, they give
    the values, rates, counts and errors of the read in memory; and the in-memory values
    are the wire values (float32 channels, as float64) with the NaN rows dropped."""
    (tmp_path / "logs").mkdir()
    logs = _logs(tmp_path / "logs", rng)
    in_memory = {fmt: _reads(p) for fmt, p in logs.items()}
    wire = read_imu_log(logs["bin"])
    ch = wire.channels.astype(np.float64)
    ok = np.isfinite(ch).all(axis=1)
    imu_drop = in_memory["bin"]["imu drop"]
    assert isinstance(imu_drop, tuple)
    np.testing.assert_array_equal(imu_drop[0]["gyro_x"], ch[ok, 0])
    assert imu_drop[1] == pytest.approx(RATE_HZ, rel=1e-9) and imu_drop[2:4] == (60, 1)
    assert "1 of 60 samples have NaN/Inf" in str(in_memory["bin"]["imu refuse"])
    assert "1 of 60 samples are NaN/Inf" in str(in_memory["bin"]["record x refuse"])
    tmp = _small_blocks(monkeypatch, tmp_path)
    for fmt, path in logs.items():
        got = _reads(path)
        _assert_same(got, in_memory[fmt])
        del got
    assert not list(tmp.iterdir())  # the temporary files went with their arrays


def test_sequence_breaks_across_blocks_are_counted(tmp_path: Path, rng: np.random.Generator,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """A sample lost where one block ends and the next begins is a break, as in the whole
    log."""
    _small_blocks(monkeypatch, tmp_path)
    t_s, gyro, accel = _record(rng, 40)
    keep = np.ones(40, dtype=bool)
    keep[[7, 21]] = False  # the 8th sample: the first of the second block of 7
    s = make_samples(t_s, gyro, accel)
    path = tmp_path / "lost.csv"
    imu_log.write_samples(path, s.take(np.flatnonzero(keep)))
    with pytest.raises(GyrodriftValueError, match="2 breaks in the sequence numbers"):
        load_imu(path)


def test_six_channels_stay_in_memory_up_to_one_columns_threshold(
        tmp_path: Path, rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch) -> None:
    """load_imu keeps a log's six channels in memory up to SPOOL_MIN_SAMPLES samples
    together (one column's 8 MB), not each: characterize on a BLF log of 1e6 samples held
    48 MB of channels and exceeded its budget (253 MB)."""
    monkeypatch.setattr(spool, "SPOOL_MIN_SAMPLES", 600)
    t_s, gyro, accel = _record(rng, 150)  # 150 x 6 channels > 600 samples
    path = write_imu_log(tmp_path / "rec.bin", t_s, gyro, accel)
    rec = load_imu(path)
    assert all(isinstance(v, np.memmap) for v in rec.channels.values())
    short = write_imu_log(tmp_path / "short.bin", t_s[:90], gyro[:90], accel[:90])
    assert not any(isinstance(v, np.memmap) for v in load_imu(short).channels.values())
