"""The C++ CAN signal decoder (include/gyrodrift/codecs/can_signal_decode.hpp, through the
binding and the loop) against cantools, the reference, on random frames of a DBC whose
multiplexed message also carries signals outside the multiplexer
(tests/data/can_corpus/mux_plain.dbc: the rates and the counter outside, the accelerations
on page 0, pages 1 and 6 with other data, every other page value undefined).

The rule both decoders follow is cantools': a frame whose multiplexer value the DBC does not
define decodes nothing (cantools raises DecodeError), not even the signals outside the
multiplexer; it is counted in ignored_frames and undefined_page_frames. A CAN FD message
(more than 8 bytes) is refused by the map and by the loop's table reader; a table line whose
signal cannot fit its frame is refused with its line.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import can
import cantools
import numpy as np
import pytest
from gyrodrift import _core
from gyrodrift.codecs.can_signals import (
    MapError,
    SignalSampleAssembler,
    decode_table_text,
    load_signal_map,
)
from gyrodrift.replay.harness import LOOP_RELATIVE

CORPUS = Path(__file__).parent / "data" / "can_corpus"
MAP = CORPUS / "mux_plain_map.toml"
STAT_KEYS = ("frames_in", "frames_used", "frames_dropped", "foreign_frames", "ignored_frames",
             "undefined_page_frames", "bad_dlc", "complete_samples", "incomplete_samples")


def _random_frames(n: int, seed: int) -> list[can.Message]:
    """n frames of the mapped message with random payloads (every page value 0..15, so most
    are pages the DBC does not define), some short, some of another ID."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        data = bytearray(rng.integers(0, 256, 8, dtype=np.uint8).tobytes())
        kind = rng.random()
        if kind < 0.02:
            out.append(can.Message(arbitration_id=0x201, is_extended_id=False, data=bytes(data)))
            continue
        if kind < 0.04:
            data = data[: int(rng.integers(0, 8))]  # shorter than the message: bad DLC
        out.append(can.Message(arbitration_id=0x200, is_extended_id=False, data=bytes(data)))
    return out


def _tuples(msgs: list[can.Message]) -> list[tuple[int, bytes, bool, bool]]:
    return [(m.arbitration_id, bytes(m.data), bool(m.is_extended_id), False) for m in msgs]


def test_cpp_decoder_equals_cantools_on_random_frames() -> None:
    smap = load_signal_map(MAP)
    msgs = _random_frames(6000, seed=20260127)
    cpp = _core.can_signal_decode(decode_table_text(smap), _tuples(msgs))
    msg = smap.db.get_message_by_name("ImuMixed")
    undefined = 0
    for m, got in zip(msgs, cpp, strict=True):
        want = {}
        if m.arbitration_id == msg.frame_id and len(m.data) >= msg.length:
            try:
                sig = msg.decode(bytes(m.data), decode_choices=False, scaling=True)
            except cantools.database.DecodeError:
                sig = {}
                undefined += 1
            want = {role: float(sig[ref.signal]) * ref.factor
                    for role, ref in smap.roles.items() if ref.signal in sig}
        assert got == want, (m, got, want)  # exact: the same double operations
    assert undefined > 3000  # 13 of 16 page values are undefined


def test_cpp_and_python_assemblers_agree_on_random_frames() -> None:
    smap = load_signal_map(MAP)
    msgs = _random_frames(6000, seed=7)
    asm = SignalSampleAssembler(smap)
    py = []
    for m in msgs:
        s = asm.push(m)
        if s is not None:
            py.append((s.seq, s.t_us, tuple(float(np.float32(v)) for v in s.values)))
    asm.finish()
    cpp, stats = _core.can_signal_assemble(decode_table_text(smap), _tuples(msgs))
    assert [(s, t, tuple(v)) for s, t, v in cpp] == py
    for key in STAT_KEYS:
        assert stats[key] == getattr(asm.stats, key), key
    assert asm.stats.undefined_page_frames > 3000 and asm.stats.complete_samples > 0


def _sample_frames(n: int, undefined: int) -> list[can.Message]:
    """n page-0 frames (each a whole sample) with `undefined` frames of page 3 between."""
    db = cantools.database.load_file(str(CORPUS / "mux_plain.dbc"))
    msg = db.get_message_by_name("ImuMixed")
    out = []
    for k in range(n):
        sig = {"Page": 0, "Counter": k % 16, "RateX": k, "RateY": -k, "RateZ": 3, "AccelX": 5,
               "AccelY": -5, "AccelZ": 2}
        out.append(can.Message(arbitration_id=msg.frame_id, is_extended_id=False,
                               data=msg.encode(sig, scaling=False)))
        if k % (n // undefined) == 0 and len(out) < n + undefined:
            data = bytearray(out[-1].data)
            data[0] = (data[0] & 0xF0) | 3  # a page the DBC does not define
            out.append(can.Message(arbitration_id=msg.frame_id, is_extended_id=False,
                                   data=bytes(data)))
    return out


def test_undefined_pages_drop_no_sample() -> None:
    # 100 samples + 10 frames of an undefined page: 100 complete samples in both decoders
    # (the C++ one decoded the rates of the undefined page and lost 10 samples before).
    smap = load_signal_map(MAP)
    msgs = _sample_frames(100, 10)
    assert len(msgs) == 110
    asm = SignalSampleAssembler(smap)
    n_py = sum(asm.push(m) is not None for m in msgs)
    asm.finish()
    cpp, stats = _core.can_signal_assemble(decode_table_text(smap), _tuples(msgs))
    assert n_py == len(cpp) == 100
    assert stats["undefined_page_frames"] == asm.stats.undefined_page_frames == 10
    assert stats["incomplete_samples"] == asm.stats.incomplete_samples == 0


def test_the_loop_counts_undefined_pages(tmp_path: Path, cpp_build_dir: Path,
                                         pass_through_config) -> None:
    import json
    import os
    import select
    import time
    import tty

    smap = load_signal_map(MAP)
    msgs = _sample_frames(100, 10)
    table = tmp_path / "mixed.cansig"
    table.write_text(decode_table_text(smap))
    master, slave = os.openpty()
    tty.setraw(slave)
    proc = subprocess.Popen(
        [str(cpp_build_dir / LOOP_RELATIVE), "--slcan", f"fd:{master}",
         "--config", str(pass_through_config(400.0, 1000.0)), "--no-rt",
         "--can-signals", str(table), "--idle-exit-s", "1.0"],
        pass_fds=[master], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    os.close(master)
    try:
        assert proc.stderr is not None
        assert '"event": "ready"' in proc.stderr.readline().decode()
        os.write(slave, b"S6\rO\r" + b"".join(
            _core.slcan_encode(m.arbitration_id, bytes(m.data), False, False) for m in msgs))
        end = time.monotonic() + 20.0
        while proc.poll() is None and time.monotonic() < end:
            if select.select([slave], [], [], 0.05)[0]:
                os.read(slave, 65536)
    finally:
        os.close(slave)
        stdout, _ = proc.communicate(timeout=20)
    stats = json.loads(stdout)
    assert stats["can"]["frames_in"] == 110
    assert stats["rejected"]["can_undefined_page_frames"] == 10
    assert stats["rejected"]["can_incomplete"] == 0
    assert stats["frames_out"] == 100


def test_can_fd_is_refused_by_both(tmp_path: Path, cpp_build_dir: Path) -> None:
    with pytest.raises(MapError, match=r"ImuFd is a CAN FD message \(64 bytes\)"):
        load_signal_map(CORPUS / "can_fd_map.toml")
    # The table a CAN FD DBC would give, written by hand: refused with its line.
    bad = tmp_path / "fd.cansig"
    bad.write_text("gyrodrift-can-signals 1\ngx 0x300 0 64 0 32 le s 1e-06 0.0 1.0 -\n")
    r = subprocess.run([str(cpp_build_dir / LOOP_RELATIVE), "--slcan", "fd:0", "--no-rt",
                        "--can-signals", str(bad)], capture_output=True, text=True, timeout=10)
    assert r.returncode == 2 and f"{bad}:2: bad dlc (0..8)" in r.stderr, r.stderr


@pytest.mark.parametrize("line", [
    "gx 0x10 0 2 0 32 le s 1 0 1 -",          # 32 bits in a 2-byte message
    "gx 0x10 0 8 60 8 le u 1 0 1 -",          # runs past byte 7
    "gx 0x10 0 4 31 16 be s 1 0 1 -",         # Motorola, continues past byte 3
    "gx 0x10 0 2 0 8 le u 1 0 1 20:8:le:0",   # the selector beyond the message
])
def test_a_signal_that_cannot_fit_is_refused(line: str, tmp_path: Path,
                                             cpp_build_dir: Path) -> None:
    bad = tmp_path / "t.cansig"
    bad.write_text(f"gyrodrift-can-signals 1\n{line}\n")
    r = subprocess.run([str(cpp_build_dir / LOOP_RELATIVE), "--slcan", "fd:0", "--no-rt",
                        "--can-signals", str(bad)], capture_output=True, text=True, timeout=10)
    assert r.returncode == 2 and f"{bad}:2: bad " in r.stderr and "fit" in r.stderr, r.stderr
    assert r.stderr.count("\n") == 1
    with pytest.raises(ValueError, match=r"line 2: bad .*fit"):
        _core.can_signal_table(bad.read_text())
