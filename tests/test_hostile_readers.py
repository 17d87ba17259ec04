"""Readers never guess silently: hostile and careless inputs, each with its verdict.

The text cases are files in tests/data/hostile/readers with their verdicts in verdicts.toml
(time columns in other units than seconds, headers that name no channel, byte-order marks,
text named .npy, empty files); binary cases (truncated and corrupt .npy files and ROS bags,
topics of the wrong message type, a FIFO) are made here. Every error is one
GyrodriftError naming the file, and one line with exit code 2 on the command line.
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import tomllib
from cli_units import with_units
from gyrodrift.cli import main
from gyrodrift.errors import GyrodriftError
from gyrodrift.io.imu_data import load_imu
from gyrodrift.io.records import load_record
from test_imu_io import _data, write_bag

CORPUS = Path(__file__).parent / "data" / "hostile" / "readers"
CASES: list[dict[str, Any]] = tomllib.loads((CORPUS / "verdicts.toml").read_text())["case"]


def _read(reader: str, path: Path, kwargs: dict[str, Any]) -> Any:
    return (load_imu if reader == "imu" else load_record)(path, **kwargs)


def _cli(reader: str, path: Path, kwargs: dict[str, Any]) -> list[str]:
    """The command line that reads `path` with the same options."""
    argv = ["characterize" if reader == "imu" else "allan", str(path)]
    for k, v in kwargs.items():
        flag = {"columns": "--column-channels", "column": "--column"}.get(
            k, "--" + k.replace("_", "-"))
        argv += [flag, ",".join(v) if isinstance(v, list) else str(v)]
    return argv


def _first_column(path: Path, name: str) -> np.ndarray:
    """A CSV column parsed by the csv module (an oracle independent of the readers)."""
    with path.open(newline="", encoding="utf-8-sig") as fh:
        rows = list(csv.DictReader(fh))
    return np.array([float(r[name]) for r in rows])


@pytest.mark.parametrize("case", CASES, ids=[f"{c['file']}-{c['reader']}-{i}"
                                             for i, c in enumerate(CASES)])
def test_corpus_verdicts(case: dict[str, Any], capsys: pytest.CaptureFixture[str]) -> None:
    path = CORPUS / case["file"]
    kwargs = dict(case.get("kwargs", {}))
    if case["verdict"] == "ok":
        rec = _read(case["reader"], path, kwargs)
        assert rec.rate_hz == pytest.approx(case["rate_hz"], rel=1e-9)
        assert rec.n == case["n"]
        if case["reader"] == "imu":  # rad/s in, rad/s out: the file's numbers exactly
            with path.open(encoding="utf-8-sig") as fh:
                header = next(csv.reader(fh))  # the second column is gyro x in every case
            np.testing.assert_array_equal(rec.channels["gyro_x"], _first_column(path, header[1]))
        else:  # deg/h in, deg/h out
            np.testing.assert_array_equal(rec.rate_deg_h, _first_column(path, "gyro"))
        return
    with pytest.raises(GyrodriftError) as exc:
        _read(case["reader"], path, kwargs)
    msg = str(exc.value)
    assert "\n" not in msg
    for m in case["match"]:
        assert m in msg, (m, msg)
    # The command line: one line, exit code 2, the same message.
    code = main(with_units(_cli(case["reader"], path, kwargs)))
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert case["match"][-1] in err


def test_every_corpus_file_has_a_verdict() -> None:
    named = {c["file"] for c in CASES}
    on_disk = {p.name for p in CORPUS.iterdir() if p.name != "verdicts.toml"}
    assert named == on_disk


# -------------------------------------------------------------------------------- .npy


@pytest.mark.parametrize("reader", ["imu", "record"])
def test_damaged_npy_names_the_file(tmp_path: Path, reader: str) -> None:
    short = tmp_path / "short.npy"
    np.save(short, np.zeros((100, 3)))
    short.write_bytes(short.read_bytes()[:200])  # header kept, most of the data gone
    obj = tmp_path / "objects.npy"
    np.save(obj, np.array([{"a": 1}, None], dtype=object), allow_pickle=True)
    for p, want in ((short, "short.npy"), (obj, "objects.npy")):
        kw: dict[str, Any] = {"rate_hz": 100.0}
        if reader == "record":
            kw["column"] = "0"
        with pytest.raises(GyrodriftError, match=want):
            _read(reader, p, kw)


# -------------------------------------------------------------------------------- FIFO


@pytest.mark.parametrize("argv", [["characterize", "{p}"], ["allan", "{p}", "--rate-hz", "100"],
                                  ["characterize", "{b}"]])
def test_fifo_input_is_refused_without_hanging(tmp_path: Path, argv: list[str]) -> None:
    """Before: characterize opened the FIFO and waited for a writer forever."""
    fifo = tmp_path / "stream.csv"
    os.mkfifo(fifo)
    bag = tmp_path / "stream.bag"
    os.mkfifo(bag)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    # Generous for a loaded machine: the command itself returns in about a second.
    res = subprocess.run([sys.executable, "-m", "gyrodrift",
                          *(a.format(p=fifo, b=bag) for a in argv)],
                         env=env, capture_output=True, text=True, timeout=300, check=False)
    assert res.returncode == 2, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1 and "not a regular file" in res.stderr


# ---------------------------------------------------------------------------- ROS bags


def _storage(bag: Path, kind: str) -> Path:
    if kind == "rosbag1":
        return bag
    return next(bag.glob("*.db3" if kind == "sqlite3" else "*.mcap"))


@pytest.mark.parametrize("kind", ["rosbag1", "sqlite3", "mcap"])
@pytest.mark.parametrize("cut", [100, 4096 + 7, "half", "garbage"])
def test_damaged_bags_are_one_line_errors(tmp_path: Path, kind: str, cut: int | str,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    """Before: tracebacks of the bag parser; and a .db3 with its last 100 bytes cut loaded
    every message, one of them with the accelerometer read as 0.0."""
    _, vals = _data(n=200)
    bag = write_bag(tmp_path / ("imu.bag" if kind == "rosbag1" else "imu"), kind, vals)
    f = _storage(bag, kind)
    data = f.read_bytes()
    if cut == "half":
        data = data[:len(data) // 2]
    elif cut == "garbage":
        data = bytes(range(256)) * 16
    else:
        assert isinstance(cut, int)
        data = data[:-cut]
    f.write_bytes(data)
    with pytest.raises(GyrodriftError) as exc:
        load_imu(f)
    assert f.name in str(exc.value)
    if kind == "sqlite3" and isinstance(cut, int):
        assert "truncated rosbag2 storage" in str(exc.value)
    code = main(with_units(["characterize", str(f)]))
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err


def test_topic_of_another_message_type(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                       ) -> None:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    string = ts.types["std_msgs/msg/String"]
    p = tmp_path / "wrong.bag"
    with Writer(p) as w:
        note = w.add_connection("/note", "std_msgs/msg/String", typestore=ts)
        # a connection that says Imu but carries strings
        liar = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
        for k in range(10):
            raw = ts.serialize_ros1(string(data="x" * k), "std_msgs/msg/String")
            w.write(note, 10**18 + k * 10**7, raw)
            w.write(liar, 10**18 + k * 10**7, raw)
    with pytest.raises(GyrodriftError, match="topic '/note' carries std_msgs/msg/String, not "
                                             "sensor_msgs/msg/Imu"):
        load_imu(p, topic="/note")
    with pytest.raises(GyrodriftError, match=r"/imu: message 0 is not a valid "
                                             r"sensor_msgs/msg/Imu"):
        load_imu(p, topic="/imu")
    for topic in ("/note", "/imu"):
        assert main(["characterize", str(p), "--topic", topic]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err


def test_intact_db3_still_loads_exactly(tmp_path: Path) -> None:
    """The truncation check looks at the SQLite header only: an intact bag is read as it
    was, every value the one written."""
    _, vals = _data(n=200)
    bag = write_bag(tmp_path / "imu", "sqlite3", vals)
    rec = load_imu(_storage(bag, "sqlite3"))
    got = np.column_stack([rec.channels[c] for c in rec.names])
    np.testing.assert_array_equal(got, vals)
