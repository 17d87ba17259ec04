"""A user's own DBC (tests/data/vendor_imu.dbc: Motorola scaled integer rates on an extended
ID with a 4-bit counter, a multiplexed message with the accelerations on page 0 and a
timestamp on page 1, diagnostic pages and another ECU's message) and its signal map
(tests/data/vendor_imu_map.toml).

cantools is the oracle: the generated decode table must describe cantools' parse of the DBC,
the C++ decoder (include/gyrodrift/codecs/can_signal_decode.hpp, through the binding) must give
exactly cantools' value for every mapped signal of every frame of a test log (including
frames with random payloads), the C++ and Python assemblers must agree sample for sample
and counter for counter, and logs written with python-can in every CAN format must read
back to the values the test encoded, with every frame accounted for, and replay.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import can
import cantools
import numpy as np
import pytest
from gyrodrift import _core
from gyrodrift.codecs.can_signals import (
    CHANNEL_ROLES,
    SignalSampleAssembler,
    decode_table,
    decode_table_text,
    load_signal_map,
)
from gyrodrift.imu.config import default_config, pass_through_config
from gyrodrift.io.imu_log import CAN_FORMATS, read_imu_log
from gyrodrift.replay.harness import LOOP_RELATIVE, ReplayOptions, run_replay

DATA = Path(__file__).parent / "data"
MAP = DATA / "vendor_imu_map.toml"
SUFFIX = {"candump": ".log", "asc": ".asc", "blf": ".blf"}
DEG = math.pi / 180.0
RATE_HZ = 400.0


@pytest.fixture(scope="module")
def smap():  # a SignalMap
    return load_signal_map(MAP)


def _frames(n: int, rng: np.random.Generator, *, noise: bool = True) -> tuple[
        list[can.Message], dict[str, np.ndarray]]:
    """n vendor samples (3 frames each: rates, mux page 0, mux page 1), encoded by cantools
    from raw integers the test chose, with other traffic in between when `noise`."""
    db = cantools.database.load_file(str(DATA / "vendor_imu.dbc"))
    rates = db.get_message_by_name("VendorImu_Rates")
    mux = db.get_message_by_name("VendorImu_Mux")
    eng = db.get_message_by_name("EngineData")
    raw_rate = rng.integers(-32768, 32768, (n, 3))
    raw_acc = rng.integers(-32768, 32768, (n, 3))
    ticks = 1_000_000 + np.arange(n) * 250  # 10 us ticks: 2.5 ms = 400 Hz
    msgs: list[can.Message] = []

    def put(m: cantools.database.can.Message, sig: dict, t: float) -> None:
        sig = {k: v.item() if isinstance(v, np.generic) else v for k, v in sig.items()}
        msgs.append(can.Message(timestamp=t, arbitration_id=m.frame_id,
                                is_extended_id=m.is_extended_frame,
                                data=m.encode(sig, scaling=False), channel=0))

    for k in range(n):
        t = 50.0 + k / RATE_HZ
        put(rates, {"RateX": raw_rate[k, 0], "RateY": raw_rate[k, 1], "RateZ": raw_rate[k, 2],
                    "Counter": k % 16, "Status": 3, "Spare": 0xA5}, t)
        if noise and k % 3 == 0:
            put(eng, {"EngineSpeed": 8000 + k, "CoolantTemp": 90}, t + 1e-4)
        put(mux, {"Page": 0, "AccelX": raw_acc[k, 0], "AccelY": raw_acc[k, 1],
                  "AccelZ": raw_acc[k, 2]}, t + 2e-4)
        if noise and k % 5 == 1:
            put(mux, {"Page": 2, "DiagCode": 0xDEAD0000 + k}, t + 3e-4)
        if noise and k % 7 == 2:
            put(mux, {"Page": 3, "SensorTemp": float(np.float32(25.0 + 0.01 * k))}, t + 3e-4)
        put(mux, {"Page": 1, "TimeStamp": int(ticks[k]), "Temperature": -37}, t + 4e-4)
    # Expected channels, computed the way the DBC defines them (raw * scale + offset), then
    # the map's factor, then float32 (the wire).
    want = np.empty((n, 6))
    want[:, 0] = raw_rate[:, 0] * 0.005 * DEG
    want[:, 1] = raw_rate[:, 1] * 0.005 * DEG
    want[:, 2] = (raw_rate[:, 2] * 0.005 + 0.01) * DEG
    want[:, 3] = raw_acc[:, 0] * 0.0005
    want[:, 4] = raw_acc[:, 1] * 0.0005
    want[:, 5] = raw_acc[:, 2] * 0.0005 + 9.80665
    return msgs, {"values": want.astype(np.float32), "t_us": ticks * 10}


def _tuples(msgs: list[can.Message]) -> list[tuple[int, bytes, bool, bool]]:
    return [(m.arbitration_id, bytes(m.data), bool(m.is_extended_id), bool(m.is_remote_frame))
            for m in msgs]


def test_table_describes_cantools_parse(smap) -> None:
    rows = {r["role"]: r for r in decode_table(smap)}
    assert set(rows) == {*CHANNEL_ROLES, "seq", "time"}
    gx = rows["gx"]
    assert (gx["id"], gx["extended"], gx["start"], gx["length"], gx["order"], gx["type"]) == (
        0x0CFF0123, True, 7, 16, "be", "s")
    assert gx["scale"] == 0.005 and gx["factor"] == DEG and gx["mux"] is None
    az = rows["az"]
    assert (az["id"], az["extended"], az["offset"]) == (0x124, False, 9.80665)
    assert az["mux"] == {"start": 0, "length": 8, "order": "le", "value": 0}
    assert rows["time"]["mux"]["value"] == 1 and rows["time"]["order"] == "le"
    assert rows["seq"]["length"] == 4
    # The C++ parser reads the text back to the same entries, numbers bit for bit.
    cpp = {r["role"]: r for r in _core.can_signal_table(decode_table_text(smap))}
    for role, r in rows.items():
        c = cpp[role]
        for key in ("id", "extended", "dlc", "start", "length", "order", "type", "scale",
                    "offset", "factor"):
            assert c[key] == r[key], (role, key)
        want_mux = None if r["mux"] is None else tuple(r["mux"].values())
        assert c["mux"] == want_mux


def test_cpp_decoder_agrees_with_cantools_on_every_frame(smap, rng: np.random.Generator,
                                                         tmp_path: Path) -> None:
    msgs, _ = _frames(200, rng)
    # And frames of the mapped IDs with random payloads: every bit pattern, sign, page.
    for _ in range(3000):
        ext = bool(rng.integers(0, 2))
        fid = 0x0CFF0123 if ext else 0x124
        data = bytearray(rng.integers(0, 256, 8, dtype=np.uint8).tobytes())
        if not ext:
            data[0] = int(rng.integers(0, 5))  # pages 0..3 and one the DBC does not define
        msgs.append(can.Message(arbitration_id=fid, is_extended_id=ext, data=bytes(data)))
    path = tmp_path / "all.blf"  # through a real log file, as a user's capture would come
    with can.Logger(str(path)) as w:
        for m in msgs:
            w.on_message_received(m)
    frames = list(can.LogReader(str(path)))
    assert len(frames) == len(msgs)
    cpp = _core.can_signal_decode(decode_table_text(smap), _tuples(frames))
    n_values = 0
    for m, got in zip(frames, cpp, strict=True):
        want = {}
        for role, ref in smap.roles.items():
            msg = smap.db.get_message_by_name(ref.message)
            if (msg.frame_id, msg.is_extended_frame) != (m.arbitration_id, m.is_extended_id):
                continue
            try:
                sig = msg.decode(bytes(m.data), decode_choices=False, scaling=True)
            except cantools.database.DecodeError:
                continue  # page 4: not in the DBC, nothing decodes
            if ref.signal in sig:
                want[role] = float(sig[ref.signal]) * ref.factor
        assert got == want, (m, got, want)  # exact: the same double operations
        n_values += len(want)
    assert n_values > 8000  # 200 log samples x 8 roles + ~3000 random frames


@pytest.mark.parametrize("drop_every", [0, 11])
def test_cpp_and_python_assemblers_agree(smap, rng: np.random.Generator,
                                         drop_every: int) -> None:
    msgs, want = _frames(300, rng)
    if drop_every:  # lose some frames: incomplete samples, and the counter skips
        msgs = [m for k, m in enumerate(msgs) if k % drop_every != 5]
    asm = SignalSampleAssembler(smap)
    py_samples = []
    for m in msgs:
        s = asm.push(m)
        if s is not None:
            py_samples.append((s.seq, s.t_us, tuple(float(np.float32(v)) for v in s.values)))
    asm.finish()
    cpp_samples, cpp_stats = _core.can_signal_assemble(decode_table_text(smap), _tuples(msgs))
    assert [(s, t, tuple(v)) for s, t, v in cpp_samples] == py_samples
    st = asm.stats
    for key in ("frames_in", "frames_used", "frames_dropped", "foreign_frames",
                "ignored_frames", "bad_dlc", "complete_samples", "incomplete_samples"):
        assert cpp_stats[key] == getattr(st, key), key
    assert st.frames_in == (st.foreign_frames + st.frames_used + st.frames_dropped
                            + st.ignored_frames + cpp_stats["pending_frames"])
    if not drop_every:
        assert st.complete_samples == 300 and st.incomplete_samples == 0
        assert [s[0] for s in py_samples] == list(range(300))  # 4-bit counter unwrapped
        np.testing.assert_array_equal(np.array([s[2] for s in py_samples], np.float32),
                                      want["values"])
    else:
        assert st.incomplete_samples > 0


@pytest.mark.parametrize("fmt", CAN_FORMATS)
def test_read_a_vendor_log_in_every_format(smap, rng: np.random.Generator, tmp_path: Path,
                                           fmt: str) -> None:
    n = 120
    msgs, want = _frames(n, rng)
    path = tmp_path / f"vendor{SUFFIX[fmt]}"
    with can.Logger(str(path)) as w:
        for m in msgs:
            w.on_message_received(m)
    s = read_imu_log(path, signals=MAP)
    np.testing.assert_array_equal(s.channels, want["values"])
    np.testing.assert_array_equal(s.seq, np.arange(n, dtype=np.uint16))
    np.testing.assert_array_equal(s.t_us, want["t_us"].astype(np.uint64))  # the IMU's clock
    rep = s.log_report.as_dict()
    n_eng = sum(1 for m in msgs if m.arbitration_id == 1000)
    n_pages = sum(1 for m in msgs if m.arbitration_id == 0x124 and m.data[0] >= 2)
    assert rep["frames_total"] == len(msgs)
    assert rep["imu_frames_used"] == 3 * n and rep["imu_samples"] == n
    assert rep["imu_frames_ignored"] == n_pages
    assert rep["foreign_frames_by_id"] == {"0x3e8": n_eng}
    assert rep["imu_frames_dropped"] == 0
    # The loaded map object works as well as its path.
    assert len(read_imu_log(path, signals=smap)) == n


def test_signal_map_errors(tmp_path: Path) -> None:
    text = MAP.read_text()
    (tmp_path / "vendor_imu.dbc").write_text((DATA / "vendor_imu.dbc").read_text())
    cases = {
        'gx = "VendorImu_Rates.RateX"\n': ("", "channels gx are not mapped"),
        '"VendorImu_Rates.RateY"': ('"VendorImu_Rates.Nope"', "no signal 'Nope'"),
        '"VendorImu_Mux.AccelZ"': ('"NoSuch.AccelZ"', "no message 'NoSuch'"),
        'unit = "us"': ('unit = "h"', "timestamp.unit"),
        '"VendorImu_Rates.Counter"': ('"VendorImu_Mux.TimeStamp"', "seq: .* unsigned integer"),
    }
    for old, (new, match) in cases.items():
        bad = tmp_path / "bad.toml"
        bad.write_text(text.replace(old, new))
        with pytest.raises(ValueError, match=match):
            load_signal_map(bad)
    with pytest.raises(ValueError, match=r"line 2: bad id \(a standard id is 11 bits\)"):
        _core.can_signal_table("gyrodrift-can-signals 1\ngx 0x999 0 8 0 16 le s 1 0 1 -\n")
    with pytest.raises(FileNotFoundError):
        load_signal_map(tmp_path / "missing.toml")


def test_signals_refused_for_frame_logs(tmp_path: Path) -> None:
    from gyrodrift.io.imu_log import write_imu_log

    p = write_imu_log(tmp_path / "a.bin", np.arange(3) / 400, np.zeros((3, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="CAN logs"):
        read_imu_log(p, signals=MAP)


def test_replay_of_a_vendor_log(rng: np.random.Generator, tmp_path: Path,
                                cpp_build_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from gyrodrift.cli import replay as replay_cli

    n = 200
    msgs, _ = _frames(n, rng)
    path = tmp_path / "vendor.asc"
    with can.Logger(str(path)) as w:
        for m in msgs:
            w.on_message_received(m)
    loop = str(cpp_build_dir / LOOP_RELATIVE)
    res = run_replay(read_imu_log(path, signals=MAP), ReplayOptions(
        transport="serial", speed=0.0, loop_binary=loop,
        processor=pass_through_config(RATE_HZ).with_timing(loop_rate_hz=1000.0)))
    assert res.ok, {k: v for k, v in res.report["checks"].items() if not v}
    assert res.report["accounting"]["outputs_received"] == n
    assert res.report["input_log"]["imu_frames_used"] == 3 * n
    # And through the command line.
    parser = argparse.ArgumentParser(prog="gyrodrift")
    replay_cli.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["replay", str(path), "--can-signals", str(MAP), "--fast",
                              "--transport", "slcan", "--loop-binary", loop,
                              "--loop-rate-hz", "1000", "--out-dir", str(tmp_path / "rep")])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "PASS" in out and f"{len(msgs)} frames" in out
    rep = json.loads((tmp_path / "rep" / "report.json").read_text())
    assert rep["accounting"]["outputs_received"] == n
    assert rep["loop"]["can"]["user_dbc"] is True  # the CAN replay spoke the vendor's DBC


def test_loop_decodes_a_user_dbc_over_slcan(smap, rng: np.random.Generator, tmp_path: Path,
                                            cpp_build_dir: Path,
                                            pass_through_config) -> None:
    # gyrodrift-loop --can-signals TABLE: the vendor frames as SLCAN lines into the loop,
    # pass-through filters, outputs in the project's frames: every output must equal the
    # sample cantools decodes (Python reader), and the loop's counters the log's content.
    import os
    import select
    import subprocess
    import time
    import tty

    from gyrodrift.codecs import OUTPUT_BASE_ID, SampleAssembler

    n = 100
    msgs, want = _frames(n, rng)
    table = tmp_path / "vendor.cansig"
    table.write_text(decode_table_text(smap))
    master, slave = os.openpty()
    tty.setraw(slave)
    proc = subprocess.Popen(
        [str(cpp_build_dir / LOOP_RELATIVE), "--slcan", f"fd:{master}",
         "--config", str(pass_through_config(RATE_HZ, 1000.0)), "--no-rt",
         "--can-signals", str(table)],
        pass_fds=[master], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    os.close(master)
    try:
        assert proc.stderr is not None
        assert '"event": "ready"' in proc.stderr.readline().decode()
        data = b"S6\rO\r" + b"".join(
            _core.slcan_encode(m.arbitration_id, bytes(m.data), m.is_extended_id, False)
            for m in msgs)
        os.write(slave, data)
        out = bytearray()
        end = time.monotonic() + 10.0
        while out.count(b"\rt18") < 4 * n - 1 and time.monotonic() < end:
            r, _, _ = select.select([slave], [], [], 0.05)
            if r:
                out += os.read(slave, 65536)
    finally:
        os.close(slave)
        stdout, stderr = proc.communicate(timeout=10)
    assert proc.returncode == 0, stderr.decode()
    stats = json.loads(stdout)
    asm = SampleAssembler(base_id=OUTPUT_BASE_ID)
    got = []
    for line in bytes(out).split(b"\r"):
        if line.startswith(b"t18"):
            s = asm.push(can.Message(arbitration_id=int(line[1:4], 16), is_extended_id=False,
                                     data=bytes.fromhex(line[5:].decode())))
            if s is not None:
                got.append(s)
    assert [s.seq for s in got] == list(range(n))
    np.testing.assert_array_equal(np.array([s.values for s in got], np.float32), want["values"])
    n_eng = sum(1 for m in msgs if m.arbitration_id == 1000)
    n_pages = sum(1 for m in msgs if m.arbitration_id == 0x124 and m.data[0] >= 2)
    rej = stats["rejected"]
    assert stats["can"]["user_dbc"] is True
    assert stats["can"]["frames_in"] == len(msgs) and stats["can"]["frames_used"] == 3 * n
    assert rej["can_foreign_frames"] == n_eng and rej["can_ignored_frames"] == n_pages
    assert rej["can_incomplete"] == 0 and stats["frames_out"] == n


def test_loop_refuses_a_bad_table(tmp_path: Path, cpp_build_dir: Path) -> None:
    import subprocess

    bad = tmp_path / "bad.cansig"
    bad.write_text("gyrodrift-can-signals 1\ngx 0x10 0 8 0 16 le s 1 0 1 -\n")
    r = subprocess.run([str(cpp_build_dir / LOOP_RELATIVE), "--slcan", "fd:0", "--no-rt",
                        "--can-signals", str(bad)], capture_output=True, text=True, timeout=10)
    assert r.returncode == 2 and "not all six channels" in r.stderr
    bad.write_text("gx 0x10 0 8 0 16 le q 1 0 1 -\n")
    r = subprocess.run([str(cpp_build_dir / LOOP_RELATIVE), "--slcan", "fd:0", "--no-rt",
                        "--can-signals", str(bad)], capture_output=True, text=True, timeout=10)
    assert r.returncode == 2 and "bad.cansig:1: bad type" in r.stderr


def test_hil_replay_in_the_vendor_layout(rng: np.random.Generator, tmp_path: Path,
                                         cpp_build_dir: Path) -> None:
    # The whole chain in the user's DBC: the harness encodes every sample with cantools in
    # the vendor's frames (rates, accel page, timestamp page), the loop decodes them through
    # the generated table (--can-signals), filters, and answers in the project's frames; the
    # outputs must equal the reference processor run on what the loop decoded.
    n = 200
    msgs, _ = _frames(n, rng)
    path = tmp_path / "vendor.blf"
    with can.Logger(str(path)) as w:
        for m in msgs:
            w.on_message_received(m)
    samples = read_imu_log(path, signals=MAP)
    res = run_replay(samples, ReplayOptions(
        transport="slcan", speed=0.0, can_signals=str(MAP),
        loop_binary=str(cpp_build_dir / LOOP_RELATIVE),
        processor=default_config(sample_rate_hz=RATE_HZ).with_timing(loop_rate_hz=1000.0)))
    rep = res.report
    assert rep["ok"], ({k: v for k, v in rep["checks"].items() if not v}, rep["loop"])
    assert rep["accounting"]["outputs_received"] == n
    loop = res.loop_stats
    assert loop is not None and loop["can"]["user_dbc"] is True
    assert loop["can"]["frames_in"] == 3 * n == loop["can"]["frames_used"]
    with pytest.raises(ValueError, match="runs clean"):
        from gyrodrift.replay.faults import FaultSpec

        ReplayOptions(transport="slcan", can_signals=str(MAP), faults=FaultSpec(drop=0.1))
    with pytest.raises(ValueError, match="slcan and socketcan"):
        ReplayOptions(transport="serial", can_signals=str(MAP))


def test_allan_reads_a_vendor_log(rng: np.random.Generator, tmp_path: Path,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    from gyrodrift.cli import main

    n = 400
    msgs, _ = _frames(n, rng)
    path = tmp_path / "vendor.log"
    with can.Logger(str(path)) as w:
        for m in msgs:
            w.on_message_received(m)
    rc = main(["allan", str(path), "--can-signals", str(MAP), "--column", "x", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0
    rec = out["record"]
    assert rec["n_used"] == n and rec["rate_hz"] == pytest.approx(RATE_HZ)  # the IMU's clock
    assert f"{len(msgs)} frames: {3 * n} IMU frames used" in rec["log"]
    # Without the map the same capture holds no IMU sample of the project's layout.
    assert main(["allan", str(path)]) == 2
    assert "no IMU samples" in capsys.readouterr().err
