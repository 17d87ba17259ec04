"""The gyrodrift-loop program driven directly over a pty: argument errors, bad input that must
be counted without stopping the loop, SLCAN command replies, signals and the JSON statistics.

Expected values here come from the wire format and the fault we put in, never from the loop.
"""

from __future__ import annotations

import json
import os
import select
import signal
import struct
import subprocess
import time
import tty
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import skip_unless_ci
from gyrodrift.codecs import TYPE_OUTPUT
from gyrodrift.codecs.wire import decode_stream, encode_frames, make_samples
from gyrodrift.replay.harness import LOOP_RELATIVE


@pytest.fixture(scope="module")
def loop_bin(cpp_build_dir: Path) -> Path:
    path = cpp_build_dir / LOOP_RELATIVE
    assert path.is_file(), f"gyrodrift-loop not built at {path}"
    return path


@pytest.fixture()
def pass_args(pass_through_config: Callable[..., Path]) -> list[str]:
    """Pass-through on every channel (the expected outputs equal the inputs, bit-exact float32,
    which is what these transport tests want), samples and cycles at 1 kHz, no real time."""
    return ["--config", str(pass_through_config(1000.0, 1000.0)), "--no-rt"]


class Loop:
    """The loop on a fresh pty (master inherited as fd:N); we hold the slave side."""

    def __init__(self, binary: Path, mode: str, *extra: str) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)
        self.fd = slave
        self.proc = subprocess.Popen(
            [str(binary), mode, f"fd:{master}", *extra],
            pass_fds=[master], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        os.close(master)
        assert self.proc.stderr is not None
        line = self.proc.stderr.readline().decode()
        assert '"event": "ready"' in line, line

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            n = os.write(self.fd, view)
            view = view[n:]

    def read_until(self, nbytes: int, timeout_s: float = 5.0) -> bytes:
        out = bytearray()
        end = time.monotonic() + timeout_s
        while len(out) < nbytes and time.monotonic() < end:
            r, _, _ = select.select([self.fd], [], [], 0.05)
            if r:
                out += os.read(self.fd, 65536)
        return bytes(out)

    def finish(self) -> dict:
        os.close(self.fd)  # end of input: the loop reads EIO on its master
        out, err = self.proc.communicate(timeout=10)
        assert self.proc.returncode == 0, err.decode()
        return json.loads(out)


def _frames(n: int, seq0: int = 0, rate_hz: float = 1000.0) -> tuple[bytes, np.ndarray]:
    rng = np.random.default_rng(7)
    t = np.arange(n) / rate_hz
    s = make_samples(t, rng.normal(0, 1e-3, (n, 3)), rng.normal(0, 1, (n, 3)), seq0=seq0)
    return encode_frames(s).tobytes(), s.channels


def test_argument_errors_exit_2(loop_bin: Path, tmp_path: Path) -> None:
    # A value valid as a double but not as the float processor's float32 (r = 1e-300 is 0 in
    # float): the reader refuses it, naming the key, before any processor is built.
    from gyrodrift.imu.config import default_config, dumps_config

    tiny = tmp_path / "tiny_r.toml"
    tiny.write_text(dumps_config(default_config()).replace("r = 1e-08", "r = 1e-300", 1))
    for args, needle in (
        ([], "exactly one of"),
        (["--serial", "fd:0", "--rate-hz", "1000"], "the rates come from the configuration"),
        (["--serial", "fd:0", "--sample-rate-hz", "400"], "the rates come from the configuration"),
        (["--serial", "fd:0", "--sample-rate-hz", "1e-300"],
         "the rates come from the configuration"),
        (["--serial", "fd:0", "--gyro-filter", "pass_through"], "comes from --config FILE"),
        (["--serial", "fd:0", "--stuck-samples", "5"], "comes from --config FILE"),
        (["--serial", "/nonexistent/tty"], "cannot open serial device"),
        (["--serial", "fd:0", "--config", str(tmp_path / "none.toml")],
         "cannot read the configuration"),
        (["--serial", "fd:0", "--config", str(tiny)],
         "channels.gx.stages[1].r: 1e-300 does not fit a float32"),
        (["--serial", "fd:0", "--bogus"], "unknown argument"),
        (["--serial", "fd:0", "--config"], "--config needs a value"),
        (["--serial", "fd:999"], "not open"),
        (["--check-config", str(tiny), "--serial", "fd:0"], "takes no other option"),
        # every numeric option is range-checked
        (["--serial", "fd:0", "--duration-s", "1e300"], "bad --duration-s (0..1e9)"),
        (["--serial", "fd:0", "--duration-s", "-1"], "bad --duration-s (0..1e9)"),
        (["--serial", "fd:0", "--idle-exit-s", "1e300"], "bad --idle-exit-s (0..1e9)"),
        (["--serial", "fd:0", "--idle-exit-s", "nan"], "bad --idle-exit-s (0..1e9)"),
        (["--serial", "fd:0", "--baud", "-9600"], "bad --baud (50..4000000)"),
        (["--serial", "fd:0", "--baud", "1e300"], "bad --baud (50..4000000)"),
        (["--serial", "fd:0", "--rt-priority", "1000"], "bad --rt-priority (1..99)"),
        (["--serial", "fd:0", "--max-bytes-per-cycle", "1e300"], "bad --max-bytes-per-cycle"),
    ):
        r = subprocess.run([str(loop_bin), *args], capture_output=True, timeout=10, text=True)
        assert r.returncode == 2, args
        assert needle in r.stderr and r.stderr.count("\n") == 1, (args, r.stderr)
    r = subprocess.run([str(loop_bin), "--check-config", str(tiny)], capture_output=True,
                       timeout=10, text=True)
    assert r.returncode == 2 and "channels.gx.stages[1].r: 1e-300" in r.stderr, r.stderr


def test_socketcan_unavailable_is_a_clear_error(loop_bin: Path) -> None:
    # This machine's kernel has no CAN sockets (and no interface by this name anyway).
    r = subprocess.run([str(loop_bin), "--socketcan", "gdcan_missing0"], capture_output=True,
                       timeout=10)
    assert r.returncode == 2
    msg = r.stderr.decode()
    assert "SocketCAN is not available" in msg or "no CAN interface 'gdcan_missing0'" in msg


def test_clean_frames_pass_through_exactly(loop_bin: Path, pass_args: list[str]) -> None:
    loop = Loop(loop_bin, "--serial", *pass_args)
    data, values = _frames(500)
    loop.write(data)
    got = loop.read_until(len(data))
    stats = loop.finish()
    dec = decode_stream(got)
    assert np.all(dec.frame_type == TYPE_OUTPUT)
    np.testing.assert_array_equal(dec.samples.seq, np.arange(500))
    np.testing.assert_array_equal(dec.samples.channels, values)  # pass-through: bit-exact
    assert stats["frames_in"] == stats["frames_out"] == 500
    assert stats["bytes_in"] == stats["bytes_out"] == len(data)
    assert stats["end_reason"] == "end_of_input"
    assert not any(stats["rejected"].values())


def test_bad_input_is_counted_and_never_stops_the_loop(loop_bin: Path,
                                                       pass_args: list[str]) -> None:
    loop = Loop(loop_bin, "--serial", *pass_args)
    good, _ = _frames(300)
    f = [good[42 * k: 42 * (k + 1)] for k in range(300)]
    rng = np.random.default_rng(11)
    garbage = bytes(x for x in rng.integers(0, 256, 500, dtype=np.uint8) if x != 0xA5)
    corrupt = bytearray(f[10])
    corrupt[20] ^= 0x10
    wrong_type = bytearray(f[11])
    wrong_type[2] = 0x81
    wrong_type[40:42] = struct.pack("<H", _crc(bytes(wrong_type[2:40])))
    nan_frame = bytearray(f[12])
    nan_frame[16:20] = struct.pack("<f", float("nan"))
    nan_frame[40:42] = struct.pack("<H", _crc(bytes(nan_frame[2:40])))
    stream = (garbage + b"".join(f[:10]) + bytes(corrupt) + bytes(wrong_type)
              + bytes(nan_frame) + f[12][:20]  # a frame cut short by the next one
              + b"".join(f[13:]) + f[0][:30])  # and a truncated tail
    loop.write(stream)
    out = loop.read_until(42 * 298)
    stats = loop.finish()
    rej = stats["rejected"]
    assert rej["garbage_bytes"] == len(garbage)
    assert rej["crc"] == 1
    assert rej["wrong_type"] == 1
    assert rej["truncated"] == 2  # the cut frame and the tail
    assert stats["health"]["non_finite_samples"] == 1
    # Frames 0..9, the NaN frame 12 and 13..299 come out: 298 outputs, seq gap at 10..11.
    dec = decode_stream(out)
    assert list(dec.samples.seq) == [*range(10), *range(12, 300)]
    assert stats["frames_out"] == 298
    assert stats["health"]["seq_gaps"] == 1 and stats["health"]["missing_samples"] == 2
    # Pass-through holds the last good value of the NaN channel.
    k = list(dec.samples.seq).index(12)
    assert dec.samples.channels[k, 0] == dec.samples.channels[k - 1, 0]


def _crc(body: bytes) -> int:
    import binascii

    return binascii.crc_hqx(body, 0xFFFF)


def test_sigterm_prints_statistics(loop_bin: Path, pass_args: list[str]) -> None:
    loop = Loop(loop_bin, "--serial", *pass_args)
    t0 = time.monotonic()
    time.sleep(0.5)
    loop.proc.send_signal(signal.SIGTERM)
    out, _ = loop.proc.communicate(timeout=10)
    elapsed_s = time.monotonic() - t0
    os.close(loop.fd)
    stats = json.loads(out)
    assert stats["end_reason"] == "signal"
    assert stats["frames_in"] == 0
    # The loop ran (at least one 1 kHz cycle in 0.5 s, however loaded the machine) and never
    # more cycles than the time allows: no rate window, which a loaded machine cannot keep.
    assert 1 <= stats["cycles"] <= 1000.0 * elapsed_s + 2
    for key in ("period_jitter_us", "wake_latency_us", "compute_us", "sample_us"):
        assert set(stats[key]) == {"n", "p50", "p99", "max"}
    assert stats["realtime"]["sched_error"] == "not requested (--no-rt)"
    # The rates and their source: the configuration's [timing].
    assert stats["config"] == pass_args[1]
    assert stats["sample_rate_hz"] == stats["loop_rate_hz"] == 1000.0


def test_idle_exit(loop_bin: Path, pass_args: list[str]) -> None:
    loop = Loop(loop_bin, "--serial", *pass_args, "--idle-exit-s", "0.2")
    out, _ = loop.proc.communicate(timeout=10)
    os.close(loop.fd)
    assert json.loads(out)["end_reason"] == "idle"


def test_slcan_commands_frames_and_errors(loop_bin: Path, pass_args: list[str]) -> None:
    loop = Loop(loop_bin, "--slcan", *pass_args)
    loop.write(b"V\rS6\rO\r")
    assert loop.read_until(len(b"V1013\r\r\r")) == b"V1013\r\r\r"
    # One sample as four frames (GyroXY, GyroZ+Seq, AccelXY, AccelZ+Seq), seq 5.
    gx, gy, gz, ax, ay, az = 0.5, -0.25, 1.0, 0.0, 2.0, 9.75
    payloads = [struct.pack("<ff", gx, gy), struct.pack("<fHH", gz, 5, 0),
                struct.pack("<ff", ax, ay), struct.pack("<fHH", az, 5, 0)]
    lines = b"".join(f"t{0x100 + k:03X}8{p.hex().upper()}\r".encode()
                     for k, p in enumerate(payloads))
    loop.write(lines + b"tXYZ8\r")  # and a malformed line
    expect_out = b"z\r" * 4 + b"".join(f"t{0x180 + k:03X}8{p.hex().upper()}\r".encode()
                                      for k, p in enumerate(payloads))
    got = loop.read_until(len(expect_out) + 1)
    stats = loop.finish()
    assert got == expect_out + b"\a"
    assert stats["frames_in"] == stats["frames_out"] == 1
    assert stats["rejected"]["slcan_malformed"] == 1
    assert stats["can"]["slcan_commands"] == 3


@pytest.mark.parametrize("variant", ["", "-asan"])
@pytest.mark.parametrize("mode", ["--serial", "--slcan"])
def test_random_bytes_never_stop_the_loop(loop_bin: Path, pass_args: list[str], mode: str,
                                          variant: str) -> None:
    # ~130 KiB of random bytes with valid input frames (serial) or lines (SLCAN) spliced in:
    # the loop must keep running, take every byte, and still turn the valid ones into outputs.
    # The -asan variant is the same program under ASan+UBSan (any finding aborts it, and
    # finish() requires exit code 0).
    binary = loop_bin.with_name(loop_bin.name + variant)
    if variant and not binary.is_file():
        skip_unless_ci("gyrodrift-loop-asan is built only with -DGYRODRIFT_SANITIZE=ON "
                    "(scripts/test builds it)")
    rng = np.random.default_rng(99)
    loop = Loop(binary, mode, *pass_args)
    good, _ = _frames(200)
    sent = 0
    for k in range(200):
        junk = bytes(rng.integers(0, 256, int(rng.integers(0, 1300)), dtype=np.uint8))
        if mode == "--serial":
            unit = good[42 * k: 42 * (k + 1)]
        else:
            junk = junk.replace(b"\r", b"").replace(b"\n", b"") + b"\r"  # one garbage line
            payloads = [struct.pack("<ff", 0.5, 0.5), struct.pack("<fHH", 0.25, k, 0),
                        struct.pack("<ff", 1.0, 1.0), struct.pack("<fHH", 9.75, k, 0)]
            unit = b"".join(f"t{0x100 + j:03X}8{p.hex().upper()}\r".encode()
                            for j, p in enumerate(payloads))
        loop.write(junk + unit)
        sent += len(junk) + len(unit)
    time.sleep(0.3)
    loop.read_until(1 << 30, timeout_s=0.5)  # drain the outputs so the loop never blocks
    stats = loop.finish()
    assert stats["end_reason"] == "end_of_input"
    assert stats["bytes_in"] == sent
    # Random junk can contain an accidental frame start that swallows the next valid unit, so
    # allow a few lost units; at least 190 of the 200 valid units must come out.
    assert 190 <= stats["frames_out"] <= 200, stats


def test_unread_output_is_counted_as_dropped_not_sent(loop_bin: Path, pass_args: list[str]) -> None:
    """Issue 13 regression: with a peer that never reads, the loop used to report every
    queued frame as sent (frames_out 20000, bytes_out for 377 frames, output_overflow 0).
    Now frames_queued = frames_out (fully written) + frames_dropped (left at exit), and
    bytes_out covers exactly the written frames (plus at most one partial frame)."""
    loop = Loop(loop_bin, "--serial", *pass_args)
    n = 3000  # 126 kB: far more than a pty holds unread
    data, _ = _frames(n)
    loop.write(data)
    time.sleep(0.5)  # let the loop take all input (1000 Hz); the output stays unread
    stats = loop.finish()
    assert stats["frames_in"] == n
    # frames_out counts only frames whose bytes were all written (the old code failed here)
    assert 42 * stats["frames_out"] <= stats["bytes_out"] < 42 * (stats["frames_out"] + 1)
    assert stats["frames_queued"] == n  # pass-through: one output per input
    assert stats["frames_out"] + stats["frames_dropped"] == stats["frames_queued"]
    assert stats["frames_dropped"] > 0  # the peer never read: not everything went out
    assert stats["rejected"]["output_overflow"] == 0
