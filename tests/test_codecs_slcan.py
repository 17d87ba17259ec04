"""SLCAN (Lawicel ASCII): C++ encoder/parser against hand-written lines and against python-can's
`slcan` interface talking over a pseudo-terminal (no traffic leaves the machine)."""

from __future__ import annotations

import os
import select
import tty
from collections.abc import Iterator

import can
import numpy as np
import pytest
from gyrodrift import _core
from gyrodrift.codecs import encode_sample


def test_hand_checked_lines() -> None:
    data = bytes.fromhex("0000003F34128100")
    assert _core.slcan_encode(0x101, data) == b"t10180000003F34128100\r"
    assert _core.slcan_encode(0x7FF, b"") == b"t7FF0\r"
    assert _core.slcan_encode(0x1ABCDEF0, b"\x01\xa2", extended=True) == b"T1ABCDEF0201A2\r"
    assert _core.slcan_encode(0x123, bytes(3), remote=True) == b"r1233\r"
    with pytest.raises(ValueError, match="out of range"):
        _core.slcan_encode(0x800, b"")
    with pytest.raises(ValueError, match="at most 8 bytes"):
        _core.slcan_encode(0x100, bytes(9))


def test_parse_frames_commands_and_errors() -> None:
    data = (
        b"C\rS6\r\rO\r"  # what python-can sends when it opens at 500 kbit/s
        b"t10180000003F34128100\r"
        b"t1018aabbccddeeff0011\r"  # lowercase hex is accepted
        b"T1ABCDEF0201A2\r"
        b"r1233\r"
        b"t1012AABB1234\r"  # with a 4-digit timestamp (Z1 mode)
        b"V\rN\rF\rS9\r"
        b"t10\r"  # too short
        b"t1013AABB\r"  # dlc 3 but 2 data bytes
        b"t1G00\r"  # bad hex
        b"Y\r"  # unknown command
        b"\a"  # BEL from the other side
        b"t" + b"0" * 60 + b"\r"  # overlong line
        b"t1000\r"
    )
    events, stats = _core.slcan_parse(data)
    assert events == [
        ("command", "C", b"", b"\r"),
        ("command", "S", b"6", b"\r"),
        ("command", "O", b"", b"\r"),
        ("frame", 0x101, bytes.fromhex("0000003F34128100"), False, False, b"z\r"),
        ("frame", 0x101, bytes.fromhex("AABBCCDDEEFF0011"), False, False, b"z\r"),
        ("frame", 0x1ABCDEF0, b"\x01\xa2", True, False, b"Z\r"),
        ("frame", 0x123, b"", False, True, b"z\r"),
        ("frame", 0x101, b"\xaa\xbb", False, False, b"z\r"),
        ("command", "V", b"", b"V1013\r"),
        ("command", "N", b"", b"NGD01\r"),
        ("command", "F", b"", b"F00\r"),
        ("command", "S", b"9", b"\a"),  # no such bitrate code
        ("error", b"\a"),
        ("error", b"\a"),
        ("error", b"\a"),
        ("error", b"\a"),
        ("error", b"\a"),  # overlong
        ("frame", 0x100, b"", False, False, b"z\r"),
    ]
    assert stats["frames"] == 6
    assert stats["commands"] == 7
    assert stats["malformed"] == 4
    assert stats["overlong"] == 1
    assert stats["bells"] == 1
    assert stats["buffered"] == 0
    assert stats["bytes_in"] == len(data)


def test_parser_on_random_bytes_never_fails(rng: np.random.Generator) -> None:
    data = rng.integers(0, 256, 20_000, dtype=np.uint8).tobytes()
    events, stats = _core.slcan_parse(data)
    assert stats["bytes_in"] == len(data)
    assert (
        stats["lines"]
        == stats["frames"] + stats["commands"] + stats["malformed"] + stats["overlong"]
    )
    assert len(events) == stats["lines"]


@pytest.mark.parametrize("cut", range(1, 22))
def test_line_that_lost_its_end_costs_only_itself(cut: int) -> None:
    """A frame line cut short (its CR, and possibly more, lost on the serial line) must not
    take the next frame with it: t/T/r/R never occur inside a line, so a frame letter
    starts a new line (issue 13; before, the merged line was one malformed line)."""
    line0 = _core.slcan_encode(0x101, bytes.fromhex("0000003F34128100"))
    line1 = _core.slcan_encode(0x102, bytes.fromhex("AABBCCDDEEFF0011"))
    line2 = _core.slcan_encode(0x1ABCDEF0, b"\x01", extended=True)
    data = line0 + line1[:cut] + line2 + line1
    events, stats = _core.slcan_parse(data)
    frames = [e[1] for e in events if e[0] == "frame"]
    assert frames == [0x101, 0x1ABCDEF0, 0x102]
    assert [e[0] for e in events] == ["frame", "error", "frame", "frame"]
    assert stats["malformed"] == 1 and stats["overlong"] == 0
    assert stats["lines"] == stats["frames"] + stats["commands"] + stats["malformed"]
    assert stats["buffered"] == 0


def test_overlong_junk_then_frame_letter_keeps_the_frame() -> None:
    """Junk longer than the line buffer with no terminator, then a frame: the frame is kept
    and the junk is one overlong line."""
    line = _core.slcan_encode(0x101, bytes(8))
    events, stats = _core.slcan_parse(b"0" * 80 + line)
    assert [e[0] for e in events] == ["error", "frame"]
    assert stats["overlong"] == 1 and stats["frames"] == 1


@pytest.fixture()
def slcan_pty() -> Iterator[tuple[int, can.BusABC]]:
    """python-can's slcan interface on the slave side of a pty; we are the adapter (master)."""
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    bus = can.Bus(interface="slcan", channel=os.ttyname(slave), sleep_after_open=0, bitrate=500_000)
    try:
        yield master, bus
    finally:
        bus.shutdown()
        os.close(master)
        os.close(slave)


def read_available(fd: int, timeout_s: float = 0.2) -> bytes:
    out = b""
    while select.select([fd], [], [], timeout_s)[0]:
        out += os.read(fd, 4096)
        timeout_s = 0.05
    return out


def test_python_can_slcan_writes_what_cpp_encodes_and_parses(
    slcan_pty: tuple[int, can.BusABC], rng: np.random.Generator
) -> None:
    master, bus = slcan_pty
    opening = read_available(master)
    events, _ = _core.slcan_parse(opening)
    commands = [(e[1], e[2]) for e in events if e[0] == "command"]
    assert ("S", b"6") in commands and ("O", b"") in commands  # 500 kbit/s, open
    msgs = encode_sample(0xBEEF, rng.normal(0, 1, 6), flags=0x0003)
    msgs.append(can.Message(arbitration_id=0x7FF, data=b"", is_extended_id=False))
    for m in msgs:
        bus.send(m)
    written = read_available(master)
    expected = b"".join(_core.slcan_encode(m.arbitration_id, bytes(m.data)) for m in msgs)
    assert written == expected
    events, stats = _core.slcan_parse(written)
    assert [(e[1], e[2]) for e in events] == [(m.arbitration_id, bytes(m.data)) for m in msgs]
    assert stats["malformed"] == 0


def test_python_can_slcan_reads_what_cpp_encodes(
    slcan_pty: tuple[int, can.BusABC], rng: np.random.Generator
) -> None:
    master, bus = slcan_pty
    read_available(master)
    frames = _core.can_encode_sample(7, 0, [float(v) for v in rng.normal(0, 1, 6)], 0x180)
    os.write(master, b"".join(_core.slcan_encode(fid, data) for fid, data in frames))
    got = []
    for _ in frames:
        m = bus.recv(timeout=2.0)
        assert m is not None
        got.append((m.arbitration_id, bytes(m.data), m.is_extended_id))
    assert got == [(fid, data, False) for fid, data in frames]
