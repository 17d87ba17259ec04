"""Multi-channel IMU inputs (gyrodrift.io.imu_data): .npy, text tables, PSINS .imu, replay logs and
ROS bags written by rosbags' own writers (rosbag1, rosbag2 with sqlite3 and MCAP storage)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.io import imu_data
from gyrodrift.io.imu_data import CHANNELS, load_imu

RATE = 100.0


def _data(n: int = 400, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE
    vals = rng.standard_normal((n, 6)) * [1e-3, 2e-3, 3e-3, 1e-2, 2e-2, 3e-2] + [0, 0, 0, 0, 0,
                                                                                   9.8]
    return t, vals


def _check(rec, vals: np.ndarray, rtol: float = 0.0) -> None:
    assert rec.names == CHANNELS
    assert rec.rate_hz == pytest.approx(RATE, rel=1e-9)
    for j, name in enumerate(CHANNELS):
        np.testing.assert_allclose(rec.channels[name], vals[:, j], rtol=rtol, atol=0)


def test_npy_six_columns_and_chunked_spool(tmp_path: Path) -> None:
    _, vals = _data()
    np.save(tmp_path / "imu.npy", vals)
    _check(load_imu(tmp_path / "imu.npy", rate_hz=RATE), vals)
    # The chunked reader (fleet workers): chunks of 7 rows give the same values, memory-mapped.
    rec = load_imu(tmp_path / "imu.npy", rate_hz=RATE, spool_dir=tmp_path / "spool",
                   chunk_rows=7)
    assert isinstance(rec.channels["gyro_x"], np.memmap)
    _check(rec, vals)
    with pytest.raises(ValueError, match="rate"):
        load_imu(tmp_path / "imu.npy")


def test_npy_units_and_named_columns(tmp_path: Path) -> None:
    _, vals = _data()
    np.save(tmp_path / "deg.npy", np.column_stack([vals[:, 3], np.degrees(vals[:, 0])]))
    rec = load_imu(tmp_path / "deg.npy", rate_hz=RATE, columns=["accel_x", "gyro_x"],
                   gyro_units="deg/s")
    assert rec.names == ("gyro_x", "accel_x")
    np.testing.assert_allclose(rec.channels["gyro_x"], vals[:, 0], rtol=1e-14)
    # Angle increments per sample are divided by dt.
    np.save(tmp_path / "inc.npy", vals[:, :3] / RATE)
    rec = load_imu(tmp_path / "inc.npy", rate_hz=RATE, gyro_units="rad")
    np.testing.assert_allclose(rec.channels["gyro_y"], vals[:, 1], rtol=1e-14)


@pytest.mark.parametrize("delim,header", [(",", True), (",", False), (";", True),
                                          (" ", False), ("\t", True)])
def test_text_tables(tmp_path: Path, delim: str, header: bool) -> None:
    t, vals = _data()
    path = tmp_path / "imu.txt"
    lines = []
    if header:
        lines.append(delim.join(["time", "gx", "gy", "gz", "ax", "ay", "az"]))
    for k in range(t.size):
        lines.append(delim.join([f"{t[k]:.6f}", *(repr(float(v)) for v in vals[k])]))
    path.write_text("\n".join(lines) + "\n")
    rec = load_imu(path)
    _check(rec, vals)
    assert rec.detail["time_column"] == ("time" if header else "0")


def test_text_gaps_reordering_and_nan(tmp_path: Path) -> None:
    t, vals = _data()
    rows = np.column_stack([t, vals])
    gap = tmp_path / "gap.csv"
    np.savetxt(gap, np.delete(rows, 50, axis=0), delimiter=",", header="t_s,gx,gy,gz,ax,ay,az",
               comments="")
    with pytest.raises(ValueError, match="1 gaps"):
        load_imu(gap)
    swapped = rows.copy()
    swapped[[60, 61]] = swapped[[61, 60]]
    back = tmp_path / "back.csv"
    np.savetxt(back, swapped, delimiter=",", header="t_s,gx,gy,gz,ax,ay,az", comments="")
    with pytest.raises(ValueError, match="backward"):
        load_imu(back)
    bad = rows.copy()
    bad[10, 3] = np.nan
    nan = tmp_path / "nan.csv"
    np.savetxt(nan, bad, delimiter=",", header="t_s,gx,gy,gz,ax,ay,az", comments="")
    with pytest.raises(ValueError, match="1 of 400 samples"):
        load_imu(nan)
    rec = load_imu(nan, nan_policy="drop")
    assert rec.n == 399 and rec.n_dropped == 1


def _write_psins(path: Path, counts: np.ndarray, dt_ms: float = 10.0) -> None:
    head = ["% PSINS-format SIMU log file. (DO NOT EDIT!)",
            "0 0 0 0 0 0", f"34.2 108.9 380 0 {dt_ms} 9.78",
            "0.1 0.1 0.1 125 125 125"]
    body = [" ".join(str(int(c)) for c in row) for row in counts]
    path.write_text("\n".join(head + body) + "\n")


def test_psins_imu(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    counts = rng.integers(-50, 50, size=(300, 6))
    path = tmp_path / "rec.imu"
    _write_psins(path, counts)
    rec = load_imu(path)
    arcsec = math.pi / 180.0 / 3600.0
    # angle increment = count * 0.1 arcsec per 10 ms; velocity = count * 125 ug*s per 10 ms.
    np.testing.assert_allclose(rec.channels["gyro_y"], counts[:, 1] * 0.1 * arcsec * 100.0,
                               rtol=1e-14)
    np.testing.assert_allclose(rec.channels["accel_z"],
                               counts[:, 5] * 125e-6 * 9.80665 * 100.0, rtol=1e-14)
    assert rec.rate_hz == pytest.approx(100.0)
    # The one-channel reader (allan, psd, filter) takes it too, in deg/h.
    from gyrodrift.io.records import load_record

    one = load_record(path, column="x")
    np.testing.assert_allclose(one.rate_deg_h, counts[:, 0] * 0.1 * 100.0, rtol=1e-12)


@pytest.mark.parametrize("command", ["allan", "psd", "filter"])
def test_one_channel_commands_accept_psins(tmp_path: Path, command: str,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    """allan, psd and filter read the PSINS .imu file (they refused it before issue 14)."""
    rng = np.random.default_rng(6)
    path = tmp_path / "rec.imu"
    counts = rng.integers(-50, 50, size=(2000, 6))
    _write_psins(path, counts)
    from gyrodrift.cli import main

    extra = {"filter": ["-o", str(tmp_path / "out.npy")],
             "psd": ["--png", str(tmp_path / "psd.png")]}.get(command, [])
    assert main([command, str(path), "--column", "y", "--json", *extra]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["record"]["column"] == "gyro_y" and doc["record"]["n_used"] == 2000
    assert doc["record"]["rate_hz"] == pytest.approx(100.0)
    if command == "filter":
        # 0.1 arcsec per 10 ms count = 10 arcsec/s = 10 deg/h per count.
        assert doc["std_in_deg_h"] == pytest.approx(float(np.std(counts[:, 1] * 10.0)),
                                                    rel=1e-12)


def test_replay_log(tmp_path: Path) -> None:
    from gyrodrift.io.imu_log import write_imu_log

    t, vals = _data()
    path = write_imu_log(tmp_path / "imu.bin", t, vals[:, :3], vals[:, 3:])
    rec = load_imu(path)
    # The wire carries float32.
    _check(rec, vals.astype(np.float32).astype(np.float64))
    assert rec.fmt == "replay-log"


# ------------------------------------------------------------------------------- ROS bags

def _imu_msg(ts, i: int, t_ns: int, v: np.ndarray):
    Imu = ts.types["sensor_msgs/msg/Imu"]
    H = ts.types["std_msgs/msg/Header"]
    T = ts.types["builtin_interfaces/msg/Time"]
    V = ts.types["geometry_msgs/msg/Vector3"]
    Q = ts.types["geometry_msgs/msg/Quaternion"]
    hk = {"stamp": T(sec=t_ns // 10**9, nanosec=t_ns % 10**9), "frame_id": "imu"}
    if "seq" in H.__dataclass_fields__:  # ROS 1 header
        hk["seq"] = i
    z9 = np.zeros(9)
    return Imu(header=H(**hk), orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0),
               orientation_covariance=z9,
               angular_velocity=V(x=float(v[0]), y=float(v[1]), z=float(v[2])),
               angular_velocity_covariance=z9,
               linear_acceleration=V(x=float(v[3]), y=float(v[4]), z=float(v[5])),
               linear_acceleration_covariance=z9)


def write_bag(path: Path, kind: str, vals: np.ndarray, *, order: np.ndarray | None = None,
              extra_topic: bool = False) -> Path:
    """A bag with /imu (and optionally /imu2) written by rosbags' writers; stamps 10 ms
    apart, messages in `order` (default: time order)."""
    from rosbags.typesys import Stores, get_typestore

    idx = np.arange(vals.shape[0]) if order is None else order
    t0 = 1_700_000_000 * 10**9
    if kind == "rosbag1":
        from rosbags.rosbag1 import Writer as W1

        ts = get_typestore(Stores.ROS1_NOETIC)
        writer = W1(path)
        ser = ts.serialize_ros1
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        ts = get_typestore(Stores.ROS2_HUMBLE)
        plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
        writer = Writer(path, version=9, storage_plugin=plugin)
        ser = ts.serialize_cdr
    with writer as w:
        topics = ["/imu", "/imu2"] if extra_topic else ["/imu"]
        conns = [w.add_connection(tp, "sensor_msgs/msg/Imu", typestore=ts) for tp in topics]
        for k, i in enumerate(idx):
            t_ns = t0 + int(i) * 10_000_000
            for c in conns:
                w.write(c, t0 + k * 10_000_000,
                        ser(_imu_msg(ts, int(i), t_ns, vals[i]), "sensor_msgs/msg/Imu"))
    return path


@pytest.mark.parametrize("kind", ["rosbag1", "sqlite3", "mcap"])
def test_ros_bags(tmp_path: Path, kind: str) -> None:
    _, vals = _data(n=200)
    path = write_bag(tmp_path / ("imu.bag" if kind == "rosbag1" else "imu_bag"), kind, vals)
    rec = load_imu(path)
    _check(rec, vals)
    assert rec.fmt == ("rosbag1" if kind == "rosbag1" else "rosbag2")
    assert rec.detail["topic"] == "/imu"
    if kind != "rosbag1":
        # The storage file itself is accepted too.
        storage = next(path.glob("*.mcap" if kind == "mcap" else "*.db3"))
        _check(load_imu(storage), vals)


@pytest.mark.parametrize("kind", ["rosbag1", "sqlite3", "mcap"])
def test_ros_bag_topics_and_reordering(tmp_path: Path, kind: str) -> None:
    _, vals = _data(n=100)
    two = write_bag(tmp_path / ("two.bag" if kind == "rosbag1" else "two"), kind, vals,
                    extra_topic=True)
    with pytest.raises(ValueError, match=r"--topic.*/imu \(100 messages\), /imu2"):
        load_imu(two)
    _check(load_imu(two, topic="/imu2"), vals)
    with pytest.raises(ValueError, match="no sensor_msgs/msg/Imu topic '/nope'"):
        load_imu(two, topic="/nope")
    order = np.arange(100)
    order[[40, 41]] = order[[41, 40]]
    swapped = write_bag(tmp_path / ("sw.bag" if kind == "rosbag1" else "sw"), kind, vals,
                        order=order)
    with pytest.raises(ValueError, match="backward"):
        load_imu(swapped)
    gap = write_bag(tmp_path / ("gap.bag" if kind == "rosbag1" else "gap"), kind, vals,
                    order=np.delete(np.arange(100), 30))
    with pytest.raises(ValueError, match="1 gaps"):
        load_imu(gap)


@pytest.mark.parametrize("kind", ["rosbag1", "sqlite3", "mcap"])
def test_ros_bag_read_in_blocks_equals_the_whole_read(tmp_path: Path, kind: str) -> None:
    """Blocks of 7 messages (200 = 28 x 7 + 4: blocks split the record) appended to
    temporary files (memory_max=0) give the bits one block in memory gives, and the values
    written; NaN rows (in two blocks) are refused with the same count or dropped alike."""
    _, vals = _data(n=200)
    vals[[13, 150], [2, 4]] = np.nan
    path = write_bag(tmp_path / ("imu.bag" if kind == "rosbag1" else "imu_bag"), kind, vals)
    fmt = "rosbag1" if kind == "rosbag1" else "rosbag2"
    whole = imu_data._load_bag(path, fmt, None, None, "drop", block_messages=10**6)
    split = imu_data._load_bag(path, fmt, None, None, "drop", block_messages=7, memory_max=0)
    assert all(isinstance(v, np.memmap) for v in split.channels.values())
    assert not any(isinstance(v, np.memmap) for v in whole.channels.values())
    keep = np.all(np.isfinite(vals), axis=1)
    for rec in (whole, split):
        assert (rec.n_total, rec.n, rec.n_dropped, rec.fmt) == (200, 198, 2, fmt)
        assert rec.rate_hz == whole.rate_hz and rec.detail == whole.detail
        for j, name in enumerate(CHANNELS):
            np.testing.assert_array_equal(rec.channels[name], vals[keep, j])
    assert whole.rate_hz == pytest.approx(RATE, rel=1e-9)
    for block in (7, 10**6):
        with pytest.raises(ValueError, match="2 of 200 samples have NaN/Inf"):
            imu_data._load_bag(path, fmt, None, None, "refuse", block_messages=block,
                               memory_max=0)


def test_rosbag1_out_of_order_bag_times_read_in_time_order(tmp_path: Path) -> None:
    """A rosbag1 bag whose messages are stored out of their receive-time order is read in
    that time order (rosbags' order): the per-chunk index read falls back to the whole
    index there. Stored in file order, message 41 before 40 would be a backward step."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    _, vals = _data(n=100)
    order = np.arange(100)
    order[[40, 41]] = order[[41, 40]]
    t0 = 1_700_000_000 * 10**9
    path = tmp_path / "late.bag"
    with Writer(path) as w:
        conn = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
        for i in order:
            t_ns = t0 + int(i) * 10_000_000
            w.write(conn, t_ns, ts.serialize_ros1(_imu_msg(ts, int(i), t_ns, vals[i]),
                                                  "sensor_msgs/msg/Imu"))
    _check(load_imu(path), vals)
    _check(imu_data._load_bag(path, "rosbag1", None, None, "refuse", block_messages=3,
                              memory_max=0), vals)


def _two_publisher_bag(tmp_path: Path, run: int) -> tuple[Path, np.ndarray]:
    """A rosbag1 bag of 100 Imu messages in time order on one topic from two publishers
    (connections), alternating every `run` messages; its values."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    _, vals = _data(n=100)
    t0 = 1_700_000_000 * 10**9
    path = tmp_path / "two.bag"
    with Writer(path) as w:
        conns = [w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts,
                                  callerid=f"/node{k}") for k in range(2)]
        for i in range(100):
            t_ns = t0 + i * 10_000_000
            w.write(conns[(i // run) % 2], t_ns, ts.serialize_ros1(
                _imu_msg(ts, i, t_ns, vals[i]), "sensor_msgs/msg/Imu"))
    return path, vals


def test_rosbag1_topic_of_two_connections_read_in_time_order(tmp_path: Path) -> None:
    """Two publishers on one topic (two rosbag1 connections, alternate messages): their
    messages merged in time order, as rosbags merges them."""
    path, vals = _two_publisher_bag(tmp_path, 1)
    _check(imu_data._load_bag(path, "rosbag1", None, None, "refuse", block_messages=3,
                              memory_max=0), vals)


def test_rosbag1_topic_of_two_connections_never_holds_the_whole_index(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Two publishers on one topic, messages in time order: the lean reader merges their
    index records in blocks (here of 7 entries) instead of reading the whole index (about
    140 bytes per message); before, a topic of several connections always read it whole."""
    path, vals = _two_publisher_bag(tmp_path, 3)
    lean = imu_data._lean_rosbag1_reader()

    def whole_index(self: object, conn: int) -> list[object]:
        raise AssertionError("the whole index was read")

    monkeypatch.setattr(lean, "_read_index", whole_index)
    monkeypatch.setattr(imu_data, "LEAN_INDEX_BLOCK", 7)
    _check(imu_data._load_bag(path, "rosbag1", None, None, "refuse", block_messages=5,
                              memory_max=0), vals)


def test_characterize_cli_lists_bag_topics(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    _, vals = _data(n=50)
    two = write_bag(tmp_path / "two.bag", "rosbag1", vals, extra_topic=True)
    from gyrodrift.cli import main

    assert main(["characterize", str(two)]) == 2
    err = capsys.readouterr().err
    assert "/imu (50 messages), /imu2 (50 messages)" in err


def test_chunked_reader_fortran_order_one_column_and_truncation(tmp_path: Path) -> None:
    _, vals = _data(n=101)
    np.save(tmp_path / "f.npy", np.asfortranarray(vals))
    _check(load_imu(tmp_path / "f.npy", rate_hz=RATE, spool_dir=tmp_path / "s1", chunk_rows=10),
           vals)
    np.save(tmp_path / "one.npy", vals[:, 2].astype(np.float32))
    rec = load_imu(tmp_path / "one.npy", rate_hz=RATE, spool_dir=tmp_path / "s2", chunk_rows=9)
    np.testing.assert_array_equal(rec.channels["gyro_z"], vals[:, 2].astype(np.float32))
    np.save(tmp_path / "t.npy", vals)
    data = (tmp_path / "t.npy").read_bytes()
    (tmp_path / "t.npy").write_bytes(data[:-100])
    with pytest.raises(ValueError):
        load_imu(tmp_path / "t.npy", rate_hz=RATE, spool_dir=tmp_path / "s3")


@pytest.mark.parametrize("layout", ["c", "fortran", "one-column", "named-units"])
def test_npy_channels_one_at_a_time_equal_the_spool(tmp_path: Path, layout: str) -> None:
    """The fleet's in-memory reader (NpyChannels.channel: one channel per pass, chunks of 7
    rows) gives the spool's values bit for bit (the same float64 conversion and unit factor),
    for C and Fortran order, a 1-D record, and named columns in deg/s with a skipped one."""
    from gyrodrift.io.imu_data import NpyChannels

    _, vals = _data(n=101)
    kw: dict = {"rate_hz": RATE, "chunk_rows": 7}
    arr: np.ndarray = vals.astype(np.float32)
    if layout == "fortran":
        arr = np.asfortranarray(vals)
    elif layout == "one-column":
        arr = vals[:, 2].astype(np.float32)
    elif layout == "named-units":
        arr = np.column_stack([vals[:, 3], np.degrees(vals[:, 0]), vals[:, 1]])
        kw.update(columns=["accel_x", "gyro_x", "-"], gyro_units="deg/s")
    np.save(tmp_path / "r.npy", arr)
    spool = NpyChannels(tmp_path / "r.npy", **kw).spool(tmp_path / "spool")
    reader = NpyChannels(tmp_path / "r.npy", **kw)
    assert reader.names == spool.names and reader.n == spool.n
    assert reader.summary() == spool.summary()
    for name in reader.names:
        x = reader.channel(name)
        assert x.dtype == np.float64 and x.flags.c_contiguous
        np.testing.assert_array_equal(x, np.asarray(spool.channels[name]))


def test_npy_channels_refuse_nan_anywhere_before_the_first_channel(tmp_path: Path) -> None:
    """A NaN in the last column is refused by the first channel read (the pass counts every
    used column), with the spool's message and count; a skipped column's NaN is not counted."""
    from gyrodrift.io.imu_data import NpyChannels

    _, vals = _data(n=50)
    vals[[3, 40], 5] = np.nan
    vals[7, 4] = np.inf
    np.save(tmp_path / "nan.npy", vals)
    with pytest.raises(ValueError, match=r"nan\.npy: 3 NaN/Inf values; the chunked reader"):
        NpyChannels(tmp_path / "nan.npy", rate_hz=RATE, chunk_rows=8).channel("gyro_x")
    with pytest.raises(ValueError, match=r"3 NaN/Inf values"):
        NpyChannels(tmp_path / "nan.npy", rate_hz=RATE).spool(tmp_path / "s")
    r = NpyChannels(tmp_path / "nan.npy", rate_hz=RATE,
                    columns=["gyro_x", "gyro_y", "gyro_z", "accel_x", "-", "-"])
    np.testing.assert_array_equal(r.channel("accel_x"), vals[:, 3])
    with pytest.raises(ValueError, match="unknown gyro units"):
        NpyChannels(tmp_path / "nan.npy", rate_hz=RATE, gyro_units="furlong")
    with pytest.raises(FileNotFoundError, match="no such file"):
        NpyChannels(tmp_path / "none.npy", rate_hz=RATE)


_FAULTS_SCRIPT = r"""
import resource, sys
from gyrodrift.io.imu_data import NpyChannels

def faults():
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt

path, spool = sys.argv[1], sys.argv[2]
r = NpyChannels(path, rate_hz=200.0, chunk_rows=1 << 15)
r.channel("gyro_x")  # the first pass (it also counts NaN/Inf in every column)
a = faults(); x = r.channel("gyro_y"); b = faults(); del x
c = faults(); NpyChannels(path, rate_hz=200.0, chunk_rows=1 << 15).spool(spool); d = faults()
print(b - a, d - c)
"""


def test_npy_reader_does_not_fault_in_new_buffers_per_chunk(tmp_path: Path) -> None:
    """A Dask worker runs with MALLOC_TRIM_THRESHOLD_ set by its nanny, which turns off
    glibc's adaptive mmap threshold: every allocation above 128 KiB is a fresh mapping whose
    pages fault in again. The reader allocated its chunk buffers anew per chunk (the old
    spool: 1.5 million minor faults and 4 s of system time per 1e7-sample log in a worker,
    against 3,000 outside it); it now reuses one buffer. Counted, not timed: one channel of
    2^20 samples in 32 chunks may fault in its own 8 MiB (2048 pages) and 512 more pages;
    the spool 512 pages in all (measured: 198 and 193; before: 6,181 and 18,496)."""
    import os
    import subprocess
    import sys

    n = 1 << 20
    np.save(tmp_path / "r.npy", np.random.default_rng(1).standard_normal((n, 6),
                                                                          dtype=np.float32))
    env = {**os.environ, "MALLOC_TRIM_THRESHOLD_": "65536"}
    proc = subprocess.run([sys.executable, "-c", _FAULTS_SCRIPT, str(tmp_path / "r.npy"),
                           str(tmp_path / "spool")], capture_output=True, text=True,
                          check=False, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    channel_faults, spool_faults = map(int, proc.stdout.split())
    assert channel_faults < n * 8 // 4096 + 512, channel_faults
    assert spool_faults < 512, spool_faults
