"""CAN IMU frames: the DBC (cantools) is the oracle for the C++ encoder/decoder, hand-checked
bytes, and reassembly by Seq (C++ and Python twins) with exact frame accounting."""

from __future__ import annotations

import can
import numpy as np
import pytest
from gyrodrift import _core
from gyrodrift.codecs import (
    INPUT_BASE_ID,
    OUTPUT_BASE_ID,
    SampleAssembler,
    encode_sample,
    load_dbc,
)


def test_dbc_describes_the_wire_table() -> None:
    db = load_dbc()
    expected = {
        "GyroXY": [("GyroX", 0), ("GyroY", 32)],
        "GyroZ": [("GyroZ", 0), ("Seq", 32), ("Flags", 48)],
        "AccelXY": [("AccelX", 0), ("AccelY", 32)],
        "AccelZ": [("AccelZ", 0), ("Seq", 32), ("Flags", 48)],
    }
    for prefix, base in (("IMU", 0x100), ("OUT", 0x180)):
        for k, (role, sigs) in enumerate(expected.items()):
            msg = db.get_message_by_frame_id(base + k)
            assert msg.name == f"{prefix}_{role}"
            assert msg.length == 8 and not msg.is_extended_frame
            got = [(s.name, s.start) for s in msg.signals]
            assert got == sigs
            for s in msg.signals:
                assert s.byte_order == "little_endian"
                if s.name in ("Seq", "Flags"):
                    assert (s.length, s.is_signed, s.is_float) == (16, False, False)
                else:
                    assert (s.length, s.is_float) == (32, True)  # SIG_VALTYPE_ ... : 1


def test_hand_checked_sample_bytes() -> None:
    # seq 0x1234, flags 0x0081, values 1.0, -2.0, 0.5, 0.0, 2.0, -1.0 (float32 LE bit patterns
    # 3F800000, C0000000, 3F000000, 00000000, 40000000, BF800000).
    values = (1.0, -2.0, 0.5, 0.0, 2.0, -1.0)
    expected = [
        (0x100, bytes.fromhex("0000803F000000C0")),
        (0x101, bytes.fromhex("0000003F34128100")),
        (0x102, bytes.fromhex("0000000000000040")),
        (0x103, bytes.fromhex("000080BF34128100")),
    ]
    assert _core.can_encode_sample(0x1234, 0x0081, values, 0x100) == expected
    py = encode_sample(0x1234, values, flags=0x0081)
    assert [(m.arbitration_id, bytes(m.data)) for m in py] == expected
    out = _core.can_encode_sample(0x1234, 0x0081, values, 0x180)
    assert [fid for fid, _ in out] == [0x180, 0x181, 0x182, 0x183]


def test_cpp_frames_decode_with_cantools(rng: np.random.Generator) -> None:
    db = load_dbc()
    for base in (INPUT_BASE_ID, OUTPUT_BASE_ID):
        for _ in range(200):
            seq = int(rng.integers(0, 65536))
            flags = int(rng.integers(0, 65536))
            vals = rng.normal(0, 5, 6).astype(np.float32)
            frames = _core.can_encode_sample(seq, flags, [float(v) for v in vals], base)
            decoded: dict[str, float] = {}
            for fid, data in frames:
                sig = db.decode_message(fid, data)
                if "Seq" in sig:
                    assert (sig["Seq"], sig["Flags"]) == (seq, flags)
                decoded.update({k: v for k, v in sig.items() if k not in ("Seq", "Flags")})
            got = [decoded[k] for k in ("GyroX", "GyroY", "GyroZ", "AccelX", "AccelY", "AccelZ")]
            # cantools returns the float32 value widened to float: exact equality.
            assert got == [float(v) for v in vals]
            # and cantools encoding of the same signals gives the same bytes
            py = encode_sample(seq, vals, flags=flags, base_id=base)
            assert [(m.arbitration_id, bytes(m.data)) for m in py] == frames


def test_cpp_decoder_agrees_with_cantools_on_cantools_frames(rng: np.random.Generator) -> None:
    """Frames built by cantools -> C++ assembler: the samples cantools decodes from them."""
    db = load_dbc()
    msgs = []
    truth = []
    for seq in range(100):
        frames = encode_sample(seq, rng.normal(0, 1, 6), flags=7)
        sig: dict[str, float] = {}
        for m in frames:
            sig.update(db.decode_message(m.arbitration_id, bytes(m.data)))
        names = ("GyroX", "GyroY", "GyroZ", "AccelX", "AccelY", "AccelZ")
        truth.append((sig["Seq"], sig["Flags"], tuple(sig[k] for k in names)))
        msgs += frames
    samples, stats = _core.can_assemble([(m.arbitration_id, bytes(m.data)) for m in msgs])
    assert samples == truth
    assert stats["complete_samples"] == 100 and stats["frames_used"] == 400
    assert stats["frames_dropped"] == stats["incomplete_samples"] == 0


def to_tuple(m: can.Message) -> tuple[int, bytes, bool, bool]:
    return (m.arbitration_id, bytes(m.data), m.is_extended_id, m.is_remote_frame)


def assemble_both(
    msgs: list[can.Message], base: int = INPUT_BASE_ID
) -> tuple[list, dict, list, dict]:
    cpp, cs = _core.can_assemble([to_tuple(m) for m in msgs], base, True)
    a = SampleAssembler(base_id=base)
    py = []
    for m in msgs:
        s = a.push(m)
        if s is not None:
            py.append((s.seq, s.flags, s.values))
    a.finish()
    ps = vars(a.stats).copy()
    ps["pending_frames"] = a.pending_frames
    return cpp, cs, py, ps


def check_accounting(st: dict) -> None:
    assert st["frames_in"] == (
        st["foreign_frames"] + st["frames_used"] + st["frames_dropped"] + st["pending_frames"]
    )


def test_incomplete_duplicate_foreign_and_bad_dlc_are_counted() -> None:
    s = [encode_sample(k, [k, 0, 0, 0, 0, 9.81]) for k in range(6)]
    foreign = can.Message(arbitration_id=0x7FF, data=b"\x01\x02", is_extended_id=False)
    extended = can.Message(arbitration_id=0x100, data=bytes(8), is_extended_id=True)
    short = can.Message(arbitration_id=0x101, data=bytes(4), is_extended_id=False)
    msgs = (
        s[0]
        + [foreign, extended]
        + [s[1][0], s[1][2], s[1][3]]  # sample 1 lost its GyroZ: XY orphaned, incomplete
        + s[2]
        + s[2][2:]  # duplicate of sample 2's accel half (after it completed: new slot)
        + [s[3][1], s[3][2], s[3][3]]  # sample 3 lost GyroXY: Z without XY, incomplete
        + [short]
        + s[4]
        + s[5][:2]  # sample 5 only half there at end of stream
    )
    cpp, cs, py, ps = assemble_both(msgs)
    assert cpp == py
    assert [x[0] for x in cpp] == [0, 2, 4]
    assert cs == ps
    assert cs["foreign_frames"] == 2
    assert cs["bad_dlc"] == 1
    # incomplete: 1 (accel half only, evicted at finish), 3 (gyro broken), 2-dup (accel only),
    # 5 (gyro only)
    assert cs["incomplete_samples"] == 4
    assert cs["complete_samples"] == 3
    assert cs["pending_frames"] == 0
    check_accounting(cs)


def test_random_faults_cpp_equals_python_and_accounting(rng: np.random.Generator) -> None:
    msgs: list[can.Message] = []
    for seq in range(600):
        frames = encode_sample(seq % 65536, rng.normal(0, 1, 6), flags=0)
        kept = []
        for m in frames:
            u = rng.random()
            if u < 0.03:
                continue  # dropped on the bus
            kept.append(m)
            if u > 0.98:
                kept.append(m)  # duplicated
        if rng.random() < 0.03 and len(kept) > 1:
            kept[0], kept[1] = kept[1], kept[0]  # reordered
        msgs += kept
    cpp, cs, py, ps = assemble_both(msgs)
    assert cpp == py
    assert cs == ps
    check_accounting(cs)
    assert 400 < cs["complete_samples"] < 600
    assert cs["incomplete_samples"] > 0


def test_output_base_ignores_input_frames() -> None:
    msgs = encode_sample(1, [1, 2, 3, 4, 5, 6]) + encode_sample(
        1, [1, 2, 3, 4, 5, 6], base_id=OUTPUT_BASE_ID
    )
    cpp, cs, py, ps = assemble_both(msgs, OUTPUT_BASE_ID)
    assert cpp == py == [(1, 0, (1.0, 2.0, 3.0, 4.0, 5.0, 6.0))]
    assert cs["foreign_frames"] == 4
    assert cs == ps


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="6 channels"):
        encode_sample(0, [1.0])
    with pytest.raises(ValueError, match="base_id"):
        encode_sample(0, [0.0] * 6, base_id=0x200)
    with pytest.raises(ValueError, match="at most 8 bytes"):
        _core.can_assemble([(0x100, bytes(9))])


@pytest.mark.parametrize("base_id", [0x100, 0x180])
def test_every_float32_is_encodable(base_id: int) -> None:
    # The DBC gives float signals no range (cantools' strict encoding would refuse values
    # outside it), so +-FLT_MAX and +-Inf, what a saturated or faulty IMU sends, encode, and
    # the bytes are the C++ encoder's.
    big = float(np.finfo(np.float32).max)
    vals = [big, -big, np.inf, -np.inf, np.nan, 0.0]
    frames = encode_sample(7, vals, base_id=base_id)
    cpp = _core.can_encode_sample(7, 0, vals, base_id)
    assert [bytes(m.data) for m in frames] == [bytes(d) for _, d in cpp]
