"""Serial IMU frame: hand-checked bytes, CRC check value, C++ == Python twin byte for byte,
and the resynchronising stream parsers (C++ and Python) on garbage, corrupted, truncated
and chunked streams with exact byte accounting."""

from __future__ import annotations

import binascii
import struct

import numpy as np
import pytest
from gyrodrift import _core
from gyrodrift.codecs import (
    FRAME_SIZE,
    TYPE_HEALTH_REPORT,
    TYPE_HEALTH_REQUEST,
    TYPE_INPUT,
    TYPE_OUTPUT,
    FrameError,
    FrameParser,
    crc16_ccitt_false,
    decode_frame,
    encode_frame,
    encode_frames,
)
from hypothesis import given, settings
from hypothesis import strategies as st

# The catalogue check value of CRC-16/CCITT-FALSE (a.k.a. CRC-16/IBM-3740): CRC of b"123456789".
CHECK_VALUE = 0x29B1


def test_crc_check_value_python_and_cpp() -> None:
    assert crc16_ccitt_false(b"123456789") == CHECK_VALUE
    assert _core.crc16_ccitt_false(b"123456789") == CHECK_VALUE
    assert _core.crc16_ccitt_false(b"") == 0xFFFF  # init value, no xorout


def test_crc_cpp_equals_stdlib_on_random_data(rng: np.random.Generator) -> None:
    for n in (1, 2, 38, 255, 1000):
        data = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
        assert _core.crc16_ccitt_false(data) == binascii.crc_hqx(data, 0xFFFF)


# One frame written out by hand from the wire table:
#   seq 0x0102, flags 0, t_us 0x0000_0001_0203_0405, values 1.0, -2.0, 0.5, 0.0, 2.0, -1.0
# float32 bit patterns: 1.0 = 3F800000, -2.0 = C0000000, 0.5 = 3F000000, 0 = 0,
# 2.0 = 40000000, -1.0 = BF800000 (little-endian on the wire).
HAND_BODY = bytes.fromhex(
    "A5 5A 01 24"  # sync, type input, len 36
    " 02 01 00 00"  # seq LE, flags LE
    " 05 04 03 02 01 00 00 00"  # t_us LE
    " 00 00 80 3F  00 00 00 C0  00 00 00 3F"  # gyro 1.0, -2.0, 0.5
    " 00 00 00 00  00 00 00 40  00 00 80 BF"  # accel 0.0, 2.0, -1.0
)
HAND_VALUES = (1.0, -2.0, 0.5, 0.0, 2.0, -1.0)
HAND_T_US = 0x0000_0001_0203_0405


def hand_frame() -> bytes:
    assert len(HAND_BODY) == 40
    # CRC from the standard library (checked against the catalogue value above), LE.
    crc = binascii.crc_hqx(HAND_BODY[2:], 0xFFFF)
    return HAND_BODY + bytes([crc & 0xFF, crc >> 8])


def test_hand_checked_frame_python_and_cpp() -> None:
    expected = hand_frame()
    assert encode_frame(0x0102, HAND_T_US, HAND_VALUES) == expected
    assert _core.serial_encode_frame(TYPE_INPUT, 0x0102, 0, HAND_T_US, HAND_VALUES) == expected
    f = decode_frame(expected)
    assert (f.seq, f.flags, f.t_us, f.frame_type) == (0x0102, 0, HAND_T_US, TYPE_INPUT)
    assert f.values == HAND_VALUES
    frames, stats = _core.serial_parse(expected)
    assert frames == [(TYPE_INPUT, 0x0102, 0, HAND_T_US, HAND_VALUES)]
    assert stats["frames_ok"] == 1 and stats["discarded_bytes"] == 0


def random_frames(rng: np.random.Generator, n: int) -> list[tuple[int, int, int, int, tuple]]:
    out = []
    for _ in range(n):
        # every frame type of the format (the health request/report frames too)
        ftype = int(rng.choice([TYPE_INPUT, TYPE_OUTPUT, TYPE_HEALTH_REQUEST,
                                TYPE_HEALTH_REPORT]))
        vals = rng.normal(0, 10, 6).astype(np.float32)
        if rng.random() < 0.1:
            vals[rng.integers(6)] = np.inf
        out.append(
            (
                ftype,
                int(rng.integers(0, 65536)),
                int(rng.integers(0, 65536)),
                int(rng.integers(0, 2**63)),
                tuple(float(v) for v in vals),
            )
        )
    return out


def test_cpp_encoding_equals_python_twin(rng: np.random.Generator) -> None:
    for ftype, seq, flags, t_us, vals in random_frames(rng, 300):
        py = encode_frame(seq, t_us, vals, frame_type=ftype, flags=flags)
        assert _core.serial_encode_frame(ftype, seq, flags, t_us, vals) == py
        assert len(py) == FRAME_SIZE


def test_vectorised_encoding_equals_per_frame(rng: np.random.Generator) -> None:
    n = 50
    seq = np.arange(65530, 65530 + n) % 65536
    t_us = np.arange(n, dtype=np.uint64) * 2500 + 10**12
    vals = rng.normal(0, 1, (n, 6)).astype(np.float32)
    flags = rng.integers(0, 65536, n)
    blob = encode_frames(seq, t_us, vals, frame_type=TYPE_OUTPUT, flags=flags)
    per = b"".join(
        encode_frame(
            int(seq[k]), int(t_us[k]), vals[k], frame_type=TYPE_OUTPUT, flags=int(flags[k])
        )
        for k in range(n)
    )
    assert blob == per


def test_decode_frame_rejects_with_reason() -> None:
    good = hand_frame()
    with pytest.raises(FrameError, match="expected 42 bytes"):
        decode_frame(good[:-1])
    with pytest.raises(FrameError, match="bad sync"):
        decode_frame(b"\x00" + good[1:])
    with pytest.raises(FrameError, match="bad header"):
        decode_frame(good[:3] + b"\x25" + good[4:])
    with pytest.raises(FrameError, match="CRC"):
        decode_frame(good[:20] + bytes([good[20] ^ 0x01]) + good[21:])
    with pytest.raises(ValueError, match="6 channels"):
        encode_frame(0, 0, [1.0, 2.0])


def parse_both(data: bytes, chunk: int = 4096) -> tuple[list, dict, list, dict]:
    cpp_frames, cpp_stats = _core.serial_parse(data, chunk, True)
    p = FrameParser()
    py_frames = []
    for i in range(0, len(data), chunk):
        py_frames += p.feed(data[i : i + chunk])
    p.finish()
    py = [(f.frame_type, f.seq, f.flags, f.t_us, f.values) for f in py_frames]
    return cpp_frames, cpp_stats, py, vars(p.stats)


def check_accounting(stats: dict) -> None:
    assert stats["bytes_in"] == FRAME_SIZE * stats["frames_ok"] + stats[
        "discarded_bytes"
    ] + stats.get("buffered", 0)


def test_parser_resyncs_after_garbage_corruption_truncation(rng: np.random.Generator) -> None:
    frames = random_frames(rng, 6)
    enc = [encode_frame(s, t, v, frame_type=ft, flags=fl) for ft, s, fl, t, v in frames]
    garbage = bytes([0x00, 0xA5, 0x00, 0x5A, 0xA5, 0x17])  # contains sync0 but no valid header
    corrupted = bytearray(enc[2])
    corrupted[30] ^= 0x40
    bad_header = enc[4][:2] + b"\x03\x24" + enc[4][4:]  # unknown type 0x03
    stream = (
        garbage
        + enc[0]
        + enc[1][:25]  # truncated: the next frame starts inside it
        + enc[1]
        + bytes(corrupted)
        + enc[3]
        + bad_header
        + enc[5]
        + enc[0][:10]  # truncated at end of stream
    )
    cpp, cs, py, ps = parse_both(stream)
    expected = [frames[i] for i in (0, 1, 3, 5)]
    assert cpp == py == expected
    for key in ("frames_ok", "crc_errors", "truncated", "bad_header", "discarded_bytes"):
        assert cs[key] == ps[key], key
    assert cs["frames_ok"] == 4
    assert cs["crc_errors"] == 1
    assert cs["truncated"] == 2  # mid-stream cut + end of stream
    assert cs["bad_header"] == 1
    assert cs["buffered"] == 0
    check_accounting(cs)
    check_accounting(ps)


@pytest.mark.parametrize("chunk", [1, 7, 41, 42, 43, 300])
def test_parser_chunking_does_not_change_result(rng: np.random.Generator, chunk: int) -> None:
    frames = random_frames(rng, 40)
    stream = bytearray()
    for ft, s, fl, t, v in frames:
        if rng.random() < 0.2:
            stream += rng.integers(0, 256, int(rng.integers(1, 60)), dtype=np.uint8).tobytes()
        stream += encode_frame(s, t, v, frame_type=ft, flags=fl)
    whole_cpp, whole_stats, whole_py, _ = parse_both(bytes(stream), 1 << 20)
    cpp, cs, py, ps = parse_both(bytes(stream), chunk)
    assert cpp == whole_cpp == py == whole_py
    assert {k: cs[k] for k in ps} == {k: whole_stats[k] for k in ps} == ps
    check_accounting(cs)


def test_parser_random_faults_cpp_equals_python(rng: np.random.Generator) -> None:
    """Fault-injected stream (drop bytes, flip bits, duplicate, insert garbage): both parsers
    agree on every frame and every counter, and account for every byte."""
    frames = random_frames(rng, 400)
    stream = bytearray()
    for ft, s, fl, t, v in frames:
        b = bytearray(encode_frame(s, t, v, frame_type=ft, flags=fl))
        u = rng.random()
        if u < 0.05:
            del b[int(rng.integers(0, FRAME_SIZE)) :]
        elif u < 0.10:
            b[int(rng.integers(0, FRAME_SIZE))] ^= 1 << int(rng.integers(8))
        elif u < 0.15:
            b = b + b
        elif u < 0.20:
            b = bytearray(rng.integers(0, 256, 20, dtype=np.uint8).tobytes()) + b
        stream += b
    cpp, cs, py, ps = parse_both(bytes(stream), 97)
    assert cpp == py
    assert {k: cs[k] for k in ps} == ps
    check_accounting(cs)
    assert cs["frames_ok"] >= 300  # at most 20% of frames were touched (and duplicates add)


def test_parser_never_invents_frames_from_random_bytes(rng: np.random.Generator) -> None:
    data = rng.integers(0, 256, 50_000, dtype=np.uint8).tobytes()
    cpp, cs, py, _ = parse_both(data, 1000)
    # A false frame needs sync (2^-16), a valid header (~2^-15) and a CRC match (2^-16).
    assert cpp == py == []
    assert cs["discarded_bytes"] == len(data)
    check_accounting(cs)


def test_frame_struct_layout_matches_table() -> None:
    """Offsets of the wire table, checked with struct on an encoded frame."""
    b = encode_frame(0xBEEF, 123456789, [0.25] * 6, frame_type=TYPE_OUTPUT, flags=0x8001)
    assert struct.unpack_from("<BBBB", b, 0) == (0xA5, 0x5A, 0x81, 36)
    assert struct.unpack_from("<HHQ", b, 4) == (0xBEEF, 0x8001, 123456789)
    assert struct.unpack_from("<6f", b, 16) == (0.25,) * 6
    assert struct.unpack_from("<H", b, 40)[0] == binascii.crc_hqx(b[2:40], 0xFFFF)


_frame_or_junk = st.one_of(
    st.binary(min_size=0, max_size=50),
    st.builds(
        lambda seq, t, v, cut, flip: _mangle(
            encode_frame(seq, t, v, frame_type=TYPE_INPUT), cut, flip
        ),
        st.integers(0, 65535),
        st.integers(0, 2**64 - 1),
        st.lists(st.floats(width=32, allow_nan=False), min_size=6, max_size=6),
        st.integers(0, FRAME_SIZE),
        st.integers(-1, FRAME_SIZE * 8 - 1),
    ),
)


def _mangle(frame: bytes, cut: int, flip: int) -> bytes:
    b = bytearray(frame[: max(cut, 1)] if cut < FRAME_SIZE else frame)
    if 0 <= flip < len(b) * 8:
        b[flip // 8] ^= 1 << (flip % 8)
    return bytes(b)


@settings(max_examples=150, deadline=None)
@given(parts=st.lists(_frame_or_junk, max_size=30), chunk=st.integers(1, 100))
def test_property_cpp_and_python_parsers_agree(parts: list[bytes], chunk: int) -> None:
    """Any mix of intact, cut, bit-flipped frames and junk: same frames, same counters, and
    every byte accounted for, in both parsers and for any chunking."""
    data = b"".join(parts)
    cpp, cs, py, ps = parse_both(data, chunk)
    assert cpp == py
    assert {k: cs[k] for k in ps} == ps
    check_accounting(cs)
    # Resynchronisation loses no intact frame and invents none: the output is exactly the
    # intact frames, in order (a damaged frame never passes CRC-16, which detects every
    # single-bit error; random junk would need a 2^-16 CRC match on top of a valid header).
    expected = []
    for p in parts:
        try:
            f = decode_frame(p)
        except FrameError:
            continue
        expected.append((f.frame_type, f.seq, f.flags, f.t_us, f.values))
    assert cpp == expected


# --- issue 13: resynchronisation after a frame cut short by 1-3 bytes ---------------------


def _frames_seen(data: bytes, chunk: int = 4096) -> tuple[list[int], list[int], list[int]]:
    """seq of every frame found by the C++ parser, the Python twin and replay.wire."""
    from gyrodrift.codecs.wire import decode_stream

    cpp, _, py, _ = parse_both(data, chunk)
    wire = decode_stream(data)
    return [f[1] for f in cpp], [f[1] for f in py], [int(s) for s in wire.samples.seq]


def test_issue13_one_liner_keeps_the_frame_after_a_short_cut() -> None:
    """The issue's reproduction: frame 1 cut to 40 bytes must not take frame 2 with it."""
    f = [_core.serial_encode_frame(1, s, 0, s, [0.1] * 6) for s in range(4)]
    assert [x[1] for x in _core.serial_parse(f[0] + f[1][:40] + f[2] + f[3])[0]] == [0, 2, 3]


@pytest.mark.parametrize("kept", range(1, FRAME_SIZE))
@pytest.mark.parametrize("chunk", [1, 5, 42, 4096])
def test_cut_frame_of_any_length_loses_only_itself(kept: int, chunk: int) -> None:
    f = [encode_frame(s, 1000 * s, [0.5 * s] * 6) for s in range(4)]
    data = f[0] + f[1][:kept] + f[2] + f[3]
    cpp, py, wire = _frames_seen(data, chunk)
    assert cpp == py == wire == [0, 2, 3]
    _, cs, _, ps = parse_both(data, chunk)
    assert {k: cs[k] for k in ps} == ps
    # 1..3 bytes hold no whole header: skipped as junk or a bad header, not a cut frame
    assert cs["truncated"] == (1 if kept >= 4 else 0) and cs["crc_errors"] == 0
    check_accounting(cs)


def test_corrupted_last_frame_is_a_crc_error_at_end_of_stream() -> None:
    """A whole frame whose CRC fails at the very end (the parser waits for 3 more bytes to
    rule out a header inside it) is settled by finish() as a CRC error."""
    good = bytearray(encode_frame(7, 1, [1.0] * 6))
    good[20] ^= 0x01
    for tail in (b"", b"\x00", b"\x00\x00"):
        for chunk in (1, 42, 100):
            _, cs, _, ps = parse_both(encode_frame(6, 0, [0.0] * 6) + bytes(good) + tail, chunk)
            assert {k: cs[k] for k in ps} == ps
            assert (cs["frames_ok"], cs["crc_errors"], cs["truncated"]) == (1, 1, 0)
            check_accounting(cs)


_valid_frame = st.builds(
    lambda ft, seq, fl, t, v: encode_frame(seq, t, v, frame_type=ft, flags=fl),
    st.sampled_from([TYPE_INPUT, TYPE_OUTPUT]),
    st.integers(0, 65535),
    st.integers(0, 65535),
    st.integers(0, 2**64 - 1),
    st.lists(st.floats(width=32, allow_nan=False), min_size=6, max_size=6),
)
# Prefixes: raw junk, or pieces of real frames (cut anywhere, possibly bit-flipped), which
# is what a serial line produces and what finds resync bugs fastest.
_prefix_part = st.one_of(
    st.binary(max_size=90),
    st.builds(lambda f, cut: f[:cut], _valid_frame, st.integers(1, FRAME_SIZE - 1)),
    st.builds(
        lambda f, bit: f[: bit // 8] + bytes([f[bit // 8] ^ (1 << bit % 8)]) + f[bit // 8 + 1 :],
        _valid_frame,
        st.integers(0, FRAME_SIZE * 8 - 1),
    ),
)


@settings(max_examples=400, deadline=None)
@given(prefix=st.lists(_prefix_part, max_size=4), frame=_valid_frame,
       chunk=st.integers(1, 100))
def test_property_valid_frame_after_any_bytes_is_decoded(
    prefix: list[bytes], frame: bytes, chunk: int
) -> None:
    """Any valid frame preceded by any bytes is decoded (it is the last frame found), by
    the C++ parser, the Python twin and replay.wire alike; C++ and Python agree on every
    frame and counter. (Only a CRC-16 collision of junk overlapping the frame could defeat
    this, 2^-16 per false header: not a case hypothesis constructs.)"""
    data = b"".join(prefix) + frame
    f = decode_frame(frame)
    want = (f.frame_type, f.seq, f.flags, f.t_us, f.values)
    cpp, cs, py, ps = parse_both(data, chunk)
    assert cpp == py
    assert {k: cs[k] for k in ps} == ps
    check_accounting(cs)
    assert cpp and cpp[-1] == want
    from gyrodrift.codecs.wire import decode_stream

    wire = decode_stream(data)
    assert wire.samples.seq.size and int(wire.samples.seq[-1]) == f.seq
    assert int(wire.end_offset[-1]) == len(data)



def test_serial_parse_counts_no_overflow_for_bytes_it_refeeds() -> None:
    """serial_parse feeds its 256-byte parser in pieces and re-feeds whatever did not fit: no
    byte is refused for good, so overflow_bytes (bytes refused) must stay 0 and bytes_in
    must equal the input length (issue 13)."""
    data = b"".join(encode_frame(s, s, [0.25] * 6) for s in range(100))
    for chunk in (1, 255, 256, 300, 4096):
        frames, stats = _core.serial_parse(data, chunk)
        assert [f[1] for f in frames] == list(range(100))
        assert stats["overflow_bytes"] == 0
        assert stats["bytes_in"] == len(data)
        check_accounting(stats)
