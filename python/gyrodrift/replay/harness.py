"""The replay harness: sends a record into the loop program (or a running target) over a
serial line or CAN, paced like the real link, captures every output, and checks each output
against the reference processor run offline on exactly the samples the target received.

Accounting: every transmitted unit (one serial frame, or one sample's four CAN frames) ends
in exactly one of: an output frame received, rejected on the link (CRC / malformed line),
or rejected by the processor (duplicate, out of order, ...). `unaccounted` must be 0.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import numpy as np

from gyrodrift.codecs import FRAME_SIZE, OUTPUT_BASE_ID, TYPE_OUTPUT, SampleAssembler, encode_sample
from gyrodrift.codecs import encode_frames as codec_encode_frames
from gyrodrift.codecs.can_signals import (
    SignalSample,
    SignalSampleAssembler,
    decode_table_text,
    encode_sample_frames,
    load_signal_map,
)
from gyrodrift.codecs.wire import Samples, decode_stream
from gyrodrift.errors import GyrodriftError, GyrodriftValueError
from gyrodrift.imu.config import ProcessorConfig, default_config, dumps_config, write_config
from gyrodrift.imu.contract import (
    FLAG_CONFIG_ERROR,
    FLAG_DUPLICATE,
    FLAG_OUT_OF_ORDER,
    FLAG_REJECTED,
)
from gyrodrift.imu.processor import ImuConfig
from gyrodrift.reference.imu import process_imu
from gyrodrift.replay.faults import (
    FaultSpec,
    TransmissionPlan,
    corrupt_serial_frame,
    corrupt_slcan_line,
    plan_transmission,
)
from gyrodrift.replay.firmware import QEMU_MACHINE, FirmwareImage, QemuTarget, cached_firmware
from gyrodrift.replay.transport import (
    CAN_FRAME_BITS,
    UART_BITS_PER_BYTE,
    CanLink,
    PtyPair,
    SerialLink,
    set_thread_normal,
    set_thread_realtime,
    sleep_until_ns,
)

__all__ = [
    "LOOP_RELATIVE",
    "SLCAN_LINE_BYTES",
    "TARGETS",
    "TRANSPORTS",
    "ReplayError",
    "ReplayOptions",
    "ReplayResult",
    "find_loop_binary",
    "run_replay",
]

TRANSPORTS = ("serial", "slcan", "socketcan")
# What a started replay runs: the host loop program, or the firmware image on QEMU's
# netduinoplus2 board (STM32F405).
TARGETS = ("loop", "qemu")
# Image outputs vs the host loop's, per channel, relative to the channel's largest |input|:
# both run the same float processor, but the host loop computes the wavelet prefilter's FIR
# taps itself in float while the image takes the generated header's taps (computed in
# double, rounded once), so taps may differ by an ulp (6e-8 relative). The 256-tap sum then
# differs by at most 6e-8 x sum|taps| (about 2) x max|input|; the steady-state Kalman stage
# does not amplify it. 1e-6 leaves a margin of 8; channels without a wavelet stage are
# bit-identical.
HOST_LOOP_RELATIVE_TOLERANCE = 1e-6
LOOP_RELATIVE = Path("cpp") / "programs" / "gyrodrift-loop" / "gyrodrift-loop"
# SCHED_FIFO priority of the harness's sender and receiver threads: below the loop's 80
# (cpp/programs/gyrodrift-loop), above everything SCHED_OTHER (a CPU hog like stress-ng).
HARNESS_RT_PRIORITY = 70
HARNESS_SWITCH_INTERVAL_S = 1e-4  # GIL hand-over bound while the harness runs real time
# An SLCAN line for one standard 8-byte frame: "t" + 3 id + 1 dlc + 16 hex + CR.
SLCAN_LINE_BYTES = 22


class ReplayError(GyrodriftError, RuntimeError):
    """The replay could not run (no loop binary, target did not start, bad options).

    Examples
    --------
    >>> try:
    ...     find_loop_binary("/nonexistent/gyrodrift-loop")
    ... except ReplayError as exc:
    ...     print(exc, isinstance(exc, RuntimeError))
    loop binary /nonexistent/gyrodrift-loop does not exist or is not executable True
    """


def find_loop_binary(explicit: str | os.PathLike[str] | None = None) -> Path:
    """The gyrodrift-loop executable: `explicit`, $GYRODRIFT_LOOP, the C++ build named by
    $GYRODRIFT_CPP_BUILD_DIR, the repo's ``build/*/`` trees, the scripts directory of this
    installation (where the wheel installs it, beside the `gyrodrift` command), or
    `gyrodrift-loop` on PATH.

    Examples
    --------
    >>> find_loop_binary().name
    'gyrodrift-loop'
    """
    if explicit:
        path = Path(explicit)
        if path.is_file() and os.access(path, os.X_OK):
            return path
        raise ReplayError(f"loop binary {explicit} does not exist or is not executable")
    cands: list[Path] = []
    if os.environ.get("GYRODRIFT_LOOP"):
        cands.append(Path(os.environ["GYRODRIFT_LOOP"]))
    if os.environ.get("GYRODRIFT_CPP_BUILD_DIR"):
        cands.append(Path(os.environ["GYRODRIFT_CPP_BUILD_DIR"]) / LOOP_RELATIVE)
    repo = Path(__file__).resolve().parents[3]
    cands += sorted((repo / "build").glob(f"*/{LOOP_RELATIVE.as_posix()}"),
                    key=lambda p: p.stat().st_mtime, reverse=True)
    import sysconfig

    cands.append(Path(sysconfig.get_path("scripts")) / "gyrodrift-loop")  # pip install
    cands.append(Path(sys.executable).parent / "gyrodrift-loop")
    on_path = shutil.which("gyrodrift-loop")
    if on_path:
        cands.append(Path(on_path))
    for c in cands:
        if c.is_file() and os.access(c, os.X_OK):
            return c
    raise ReplayError("cannot find gyrodrift-loop: `pip install` the package (the wheel "
                      "installs it), or build it (scripts/dev-build NAME gyrodrift-loop or cmake "
                      "-DGYRODRIFT_BUILD_PROGRAMS=ON) and pass --loop-binary, or set "
                      "GYRODRIFT_LOOP")


@dataclass
class ReplayOptions:
    """How to replay: link and pacing, the loop program, fault injection and the processor.

    Examples
    --------
    >>> opt = ReplayOptions(transport="slcan", speed=0.0, faults=FaultSpec(drop=0.01))
    >>> opt.can, opt.baud
    (True, 921600)
    >>> ReplayOptions(transport="socketcan")
    Traceback (most recent call last):
    ...
    gyrodrift.errors.GyrodriftValueError: socketcan replays attach to a running target ...
    """
    transport: str = "serial"  # serial | slcan | socketcan (socketcan: attach to a real bus)
    speed: float = 1.0  # 1 = original timestamps, k = k times faster, 0 = as fast as possible
    baud: int = 921600  # serial line rate (frame pacing; a pty ignores it)
    can_bitrate: int = 500000  # CAN bit rate (frame pacing)
    pace_link: bool = True  # hold each unit back by its time on the wire (paced modes)
    loop_binary: str | None = None
    loop_realtime: bool = True  # ask the loop for SCHED_FIFO + mlockall
    # The harness's sender and receiver threads SCHED_FIFO too (when permitted; the report's
    # "harness_realtime" says per thread whether it was granted or refused).
    harness_realtime: bool = True
    attach: str | None = None  # device path / CAN interface of a running target
    faults: FaultSpec = field(default_factory=FaultSpec)
    # The processor of the loop and of the reference alike; its timing gives the sample rate
    # (CAN timestamps, the time checks) and the loop rate.
    processor: ProcessorConfig = field(default_factory=default_config)
    settle_s: float = 1.0  # stop waiting after this long without new output
    timeout_s: float = 0.0  # 0: record duration / speed + 30 s
    batch_frames: int = 256  # as-fast-as-possible: serial frames per write
    # The local link to a started loop: "pty" (a tty, as a real serial port) or "socketpair"
    # (serial only; bypasses the kernel's tty layer, to tell its delays from the harness's).
    local_link: str = "pty"
    # CAN replays in a user's DBC layout: the signal map (TOML path) whose DBC encodes the
    # frames sent, and whose decode table the started loop gets (--can-signals).
    can_signals: str | None = None
    # A progress bar of the units sent (tqdm, on stderr), drawn by its own thread so the
    # sender only stores a count; the command line sets it from --progress.
    progress: bool = False
    # "loop" (gyrodrift-loop on a pty) or "qemu" (the firmware image on the emulated board,
    # built from `processor` unless `firmware_image` names a built one).
    target: str = "loop"
    firmware_image: FirmwareImage | None = None
    # qemu: replay the same transmission into the host loop too and compare (outputs and
    # counters).
    compare_host_loop: bool = True
    # qemu: count instructions (-icount; the emulated clock then runs on the instruction
    # count and may fall behind real time on a loaded host) or run on the host's clock.
    qemu_icount: bool = True

    def __post_init__(self) -> None:
        if self.transport not in TRANSPORTS:
            raise GyrodriftValueError(f"transport must be one of {TRANSPORTS}, got "
                                      f"{self.transport!r}")
        if not (self.speed >= 0 and np.isfinite(self.speed)):
            raise GyrodriftValueError(f"speed must be >= 0 (0 = as fast as possible), got "
                                      f"{self.speed}")
        if self.transport == "socketcan" and self.attach is None:
            raise GyrodriftValueError("socketcan replays attach to a running target on a real "
                                      "interface: pass attach='can0'")
        if self.local_link not in ("pty", "socketpair"):
            raise GyrodriftValueError(f"local_link must be 'pty' or 'socketpair', got "
                                      f"{self.local_link!r}")
        if self.local_link == "socketpair" and self.transport != "serial":
            raise GyrodriftValueError("local_link='socketpair' carries the serial transport only")
        if self.can_signals is not None:
            if not self.can:
                raise GyrodriftValueError("can_signals applies to the slcan and socketcan "
                                          "transports")
            f = self.faults
            if any((f.drop, f.corrupt, f.duplicate, f.reorder, f.delay)):
                raise GyrodriftValueError("fault injection needs the project's CAN frames; a "
                                          "replay in a "
                                          "user's DBC layout (can_signals) runs clean")
        if self.baud <= 0 or self.can_bitrate <= 0:
            raise GyrodriftValueError("baud and can_bitrate must be > 0")
        if self.target not in TARGETS:
            raise GyrodriftValueError(f"target must be one of {TARGETS}, got {self.target!r}")
        if self.target == "qemu" and (self.transport != "serial" or self.attach is not None
                                      or self.local_link != "pty"):
            raise GyrodriftValueError("the firmware image on QEMU speaks serial frames on its "
                                      "own pty: transport 'serial', no attach")

    @property
    def can(self) -> bool:
        return self.transport in ("slcan", "socketcan")


@dataclass(frozen=True)
class ReplayResult:
    """The outcome of a replay: the report (accounting, comparison, latency, throughput; the
    JSON file's content), per-output latencies and arrival times, and the loop's statistics.

    Examples
    --------
    >>> from gyrodrift.codecs.wire import make_samples
    >>> s = make_samples(np.arange(40) / 400.0, np.zeros((40, 3)), np.tile([0, 0, 9.8], (40, 1)))
    >>> res = run_replay(s, ReplayOptions(speed=0.0, loop_realtime=False, harness_realtime=False))
    >>> res.ok, res.latency_us.shape, res.as_dict()["accounting"]["outputs_received"]
    (True, (40,), 40)
    """

    report: dict[str, Any]
    latency_us: np.ndarray  # per received output, in output order
    output_arrival_s: np.ndarray  # arrival time of each output, from the first write
    loop_stats: dict[str, Any] | None
    outputs: Samples | None = None  # the output frames received, in arrival order

    @property
    def ok(self) -> bool:
        return bool(self.report["ok"])

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready values: the report (what report.json holds)."""
        return dict(self.report)


def _unit_wire_time_ns(opt: ReplayOptions) -> int:
    """Time one unit occupies its link: serial frame at the baud, or a sample's 4 CAN frames
    at the bit rate (and, for SLCAN, its 4 lines at the tty baud: the slower one counts)."""
    if opt.transport == "serial":
        return int(FRAME_SIZE * UART_BITS_PER_BYTE * 1e9 / opt.baud)
    can_ns = 4 * CAN_FRAME_BITS * 1e9 / opt.can_bitrate
    if opt.transport == "slcan":
        can_ns = max(can_ns, 4 * SLCAN_LINE_BYTES * UART_BITS_PER_BYTE * 1e9 / opt.baud)
    return int(can_ns)


def _delivered(samples: Samples, plan: TransmissionPlan, opt: ReplayOptions
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What reaches the processor, in order: unit positions, seq, t_us, values (float64).

    CAN has no timestamp field: the loop derives t_us from the unwrapped sequence number
    (signed 16-bit steps) at the nominal sample rate, and so does this."""
    pos = np.array([k for k, u in enumerate(plan.units) if not u.corrupt], dtype=np.int64)
    idx = np.array([plan.units[k].index for k in pos], dtype=np.int64)
    seq = samples.seq[idx] if idx.size else np.zeros(0, np.uint16)
    if opt.can:
        unwrapped = np.zeros(seq.size, dtype=np.int64)
        acc = 0
        for k in range(seq.size):
            if k == 0:
                acc = int(seq[0])
            else:
                step = (int(seq[k]) - int(seq[k - 1])) % 65536
                acc += step - 65536 if step >= 32768 else step
            unwrapped[k] = acc
        t_us = np.where(unwrapped <= 0, 0,
                        np.floor(unwrapped * 1e6 / opt.processor.timing.sample_rate_hz + 0.5)
                        ).astype(np.uint64)
    else:
        t_us = samples.t_us[idx] if idx.size else np.zeros(0, np.uint64)
    values = samples.channels[idx].astype(np.float64) if idx.size else np.zeros((0, 6))
    return pos, seq, t_us, values


def _config_file(config: ProcessorConfig) -> Path:
    """The configuration's canonical text in a content-named temporary file, for the loop's
    --config (its reader takes the canonical TOML subset, whatever layout a user's file has)."""
    text = dumps_config(config)
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    path = Path(tempfile.gettempdir()) / f"gyrodrift-config-{digest}.toml"
    if not path.exists():
        write_config(config, path)
    return path


class _Target:
    """The loop program started on a pty (or nothing, when attaching to a running one)."""

    def __init__(self, opt: ReplayOptions) -> None:
        self.opt = opt
        self.proc: subprocess.Popen[bytes] | None = None
        self.pty: PtyPair | None = None
        self.device = opt.attach or ""
        self.stderr_lines: list[str] = []
        self.stdout = b""
        self.table_path = ""
        self._stopped = False
        self._stats: dict[str, Any] | None = None

    def start(self) -> None:
        if self.opt.attach is not None:
            return
        binary = find_loop_binary(self.opt.loop_binary)
        self.pty = PtyPair.open() if self.opt.local_link == "pty" else PtyPair.open_socketpair()
        mode = "--serial" if self.opt.transport == "serial" else "--slcan"
        args = [str(binary), mode, f"fd:{self.pty.master_fd}", "--baud", str(self.opt.baud),
                "--config", str(_config_file(self.opt.processor))]
        if not self.opt.loop_realtime:
            args.append("--no-rt")
        if self.opt.can_signals is not None:
            # The loop decodes the user's frames through the table generated from the DBC.
            fd, name = tempfile.mkstemp(suffix=".cansig", prefix="gyrodrift-")
            with os.fdopen(fd, "w") as fh:
                fh.write(decode_table_text(load_signal_map(self.opt.can_signals)))
            self.table_path = name
            args += ["--can-signals", name]
        self.proc = subprocess.Popen(args, pass_fds=[self.pty.master_fd],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        self.pty.close_master()  # the loop owns it now
        self.device = self.pty.slave_path
        ready = threading.Event()
        assert self.proc.stderr is not None

        def pump() -> None:
            assert self.proc is not None and self.proc.stderr is not None
            for raw in self.proc.stderr:
                line = raw.decode(errors="replace").rstrip()
                self.stderr_lines.append(line)
                if '"event": "ready"' in line:
                    ready.set()
            ready.set()

        threading.Thread(target=pump, name="loop-stderr", daemon=True).start()
        if not self._wait_ready(ready, 10.0) or self.proc.poll() is not None:
            err = "\n".join(self.stderr_lines) or "no output"
            self.stop()
            raise ReplayError(f"gyrodrift-loop did not start: {err}")

    def _wait_ready(self, ready: threading.Event, timeout_s: float) -> bool:
        """Wait for the loop's ready line (a method so a test can interrupt it)."""
        return ready.wait(timeout_s)

    def stop(self, timeout_s: float = 10.0) -> dict[str, Any] | None:
        """Close our end (the loop sees end of input), collect its JSON statistics.
        A second call returns the first one's result (start-up failures stop the target
        before run_replay's finally does)."""
        if self._stopped:
            return self._stats
        self._stopped = True
        if self.pty is not None:
            self.pty.close()
        if self.table_path:
            Path(self.table_path).unlink(missing_ok=True)
            self.table_path = ""
        if self.proc is None:
            return None
        try:
            out, _ = self.proc.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            self.proc.send_signal(signal.SIGTERM)
            try:
                out, _ = self.proc.communicate(timeout=5.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                out, _ = self.proc.communicate()
        self.stdout = out
        try:
            self._stats = json.loads(out.decode())
        except (json.JSONDecodeError, UnicodeDecodeError):
            self._stats = None
        return self._stats


def _as_decoded_by_the_loop(samples: Samples, smap: Any) -> Samples:
    """What the loop will decode from a user's DBC frames (rounded to the DBC's resolution),
    found by decoding them the same way: that is the record the reference must see."""
    user_asm = SignalSampleAssembler(smap)
    decoded: list[SignalSample] = []
    for k in range(len(samples)):
        done: SignalSample | None = None
        for m in encode_sample_frames(smap, int(samples.seq[k]), int(samples.t_us[k]),
                                      samples.channels[k]):
            done = user_asm.push(m)
        assert done is not None  # every sample's frames complete exactly that sample
        decoded.append(done)
    return Samples(np.array([d.seq for d in decoded], np.uint16), samples.flags,
                   np.array([samples.t_us[k] if d.t_us is None else d.t_us
                             for k, d in enumerate(decoded)], np.uint64),
                   np.array([d.values for d in decoded], np.float64).astype(np.float32),
                   log_report=samples.log_report)


@dataclass
class _Expected:
    """The reference processor run on exactly what reaches the target: what must come back."""

    ref: Any  # the reference's ImuResult over the delivered samples
    positions: np.ndarray  # unit position of each expected output, in order
    seq: np.ndarray
    flags: np.ndarray
    values: np.ndarray


def _expected_outputs(samples: Samples, plan: TransmissionPlan, opt: ReplayOptions,
                      smap: Any) -> _Expected:
    pos, d_seq, d_t_us, d_values = _delivered(samples, plan, opt)
    if smap is not None and "time" in smap.roles:
        d_t_us = samples.t_us[[plan.units[k].index for k in pos]]  # the IMU's own clock
    # The loop stores every parameter as float32: the reference gets the float32-rounded
    # values too (and runs the same model in double).
    ref = process_imu(d_seq, d_t_us, d_values,
                      ImuConfig.from_processor_config(opt.processor, float32=True))
    accepted = (ref.flags & FLAG_REJECTED) == 0
    return _Expected(ref, pos[accepted], d_seq[accepted], ref.flags[accepted],
                     ref.values[accepted])


def _payloads(samples: Samples, plan: TransmissionPlan, opt: ReplayOptions, smap: Any,
              rng: np.random.Generator) -> list[Any]:
    """The bytes (serial) or frames (CAN, with the corrupt mark) of every unit to send."""
    payload: list[Any] = []
    if opt.transport == "serial":
        raw = codec_encode_frames(samples.seq, samples.t_us, samples.channels)
        for u in plan.units:
            frame = raw[FRAME_SIZE * u.index: FRAME_SIZE * (u.index + 1)]
            payload.append(corrupt_serial_frame(frame, rng) if u.corrupt else frame)
        return payload
    cache: dict[int, list[can.Message]] = {}
    for u in plan.units:
        if u.index not in cache:
            k = u.index
            cache[k] = encode_sample(int(samples.seq[k]), samples.channels[k]) \
                if smap is None else encode_sample_frames(
                    smap, int(samples.seq[k]), int(samples.t_us[k]), samples.channels[k])
        payload.append((cache[u.index], u.corrupt))
    return payload


def _transmit(link: SerialLink | CanLink, payload: list[Any], plan: TransmissionPlan,
              opt: ReplayOptions, rng: np.random.Generator, spin_ns: int, sent: list[int],
              write_ns: np.ndarray) -> tuple[int, int]:
    """Send every unit: paced at `opt.speed` x the record's time (each unit complete at the
    receiver when its last bit has arrived), or as fast as possible. Fills `write_ns` (the
    time before each unit's first byte leaves) and `sent`; returns (start_ns, end_ns)."""
    n_units = len(payload)
    wire_ns = _unit_wire_time_ns(opt) if opt.pace_link else 0
    t_rec = np.array([u.t_s for u in plan.units], dtype=np.float64)
    t0 = time.perf_counter_ns() + 20_000_000  # 20 ms to settle
    sleep_until_ns(t0)
    start_ns = time.perf_counter_ns()
    if opt.speed > 0:
        due = t0 + ((t_rec - t_rec[0]) / opt.speed * 1e9).astype(np.int64)
        link_free = 0
        for k in range(n_units):
            ready_ns = max(int(due[k]), link_free) + wire_ns
            sleep_until_ns(ready_ns, spin_ns)
            # Latency starts before the first byte leaves: stamped after the call, a
            # preempted sender would stamp after the reply arrived (negative latency).
            write_ns[k] = time.perf_counter_ns()
            _send(link, payload[k], rng)
            sent[0] = k + 1
            link_free = ready_ns
    elif opt.transport == "serial":
        assert isinstance(link, SerialLink)
        b = max(1, opt.batch_frames)
        for k0 in range(0, n_units, b):
            chunk = b"".join(payload[k0:k0 + b])
            write_ns[k0:k0 + b] = time.perf_counter_ns()  # before the first byte leaves
            link.write(chunk)
            sent[0] = min(k0 + b, n_units)
    else:
        for k in range(n_units):
            write_ns[k] = time.perf_counter_ns()  # before the first byte leaves
            _send(link, payload[k], rng)
            sent[0] = k + 1
    return start_ns, time.perf_counter_ns()


def _wait_for_outputs(link: SerialLink | CanLink, expected_n: int, plan: TransmissionPlan,
                      opt: ReplayOptions) -> None:
    """Until all expected outputs arrived, or settle_s passed without anything new."""
    t_rec = [u.t_s for u in plan.units]
    duration_s = (t_rec[-1] - t_rec[0]) / opt.speed if opt.speed > 0 else 0.0
    deadline = time.perf_counter() + (opt.timeout_s or duration_s + 30.0)
    last_count, last_change = -1, time.perf_counter()
    while time.perf_counter() < deadline:
        count = _output_count(link)
        if count >= expected_n:
            break
        if count != last_count:
            last_count, last_change = count, time.perf_counter()
        elif time.perf_counter() - last_change > opt.settle_s:
            break
        time.sleep(0.01)
    time.sleep(0.05)  # anything still in flight


def _received(link: SerialLink | CanLink) -> tuple[Samples, np.ndarray, dict[str, int]]:
    """The outputs captured on the link, their arrival times (ns) and the link's issues."""
    if isinstance(link, SerialLink):
        stream = b"".join(c for _, c in link.capture.chunks)
        ends = np.cumsum([len(c) for _, c in link.capture.chunks])
        arrivals = np.array([t for t, _ in link.capture.chunks], dtype=np.int64)
        dec = decode_stream(stream)
        ok_type = dec.frame_type == TYPE_OUTPUT
        got = dec.samples.take(np.nonzero(ok_type)[0])
        got_arrival = arrivals[np.searchsorted(ends, dec.end_offset[ok_type], side="left")] \
            if got.seq.size else np.zeros(0, np.int64)
        return got, got_arrival, {"crc_errors": dec.crc_errors,
                                  "garbage_bytes": dec.garbage_bytes,
                                  "truncated_bytes": dec.truncated_bytes,
                                  "input_type_frames": int(np.count_nonzero(~ok_type))}
    asm = SampleAssembler(base_id=OUTPUT_BASE_ID)
    seqs, flags_l, vals, arr = [], [], [], []
    for t_ns, m in link.capture.messages:
        s = asm.push(m)
        if s is not None:
            seqs.append(s.seq)
            flags_l.append(s.flags)
            vals.append(list(s.values))
            arr.append(t_ns)
    asm.finish()
    got = Samples(np.asarray(seqs, np.uint16), np.asarray(flags_l, np.uint16),
                  np.zeros(len(seqs), np.uint64), np.asarray(vals, np.float32).reshape(-1, 6))
    st = asm.stats
    return got, np.asarray(arr, dtype=np.int64), {
        "can_incomplete": int(st.incomplete_samples),
        "can_foreign_frames": int(st.foreign_frames)}


def _output_jitter_us(got_arrival: np.ndarray, expected_pos: np.ndarray,
                      plan: TransmissionPlan, opt: ReplayOptions) -> dict[str, float]:
    """Each output's inter-arrival time against the spacing of its input in the record
    (paced replays only; 0 for a perfect real-time chain)."""
    n_j = min(got_arrival.size, expected_pos.size)
    if opt.speed > 0 and n_j > 1:
        due_us = np.array([plan.units[k].t_s for k in expected_pos[:n_j]]) / opt.speed * 1e6
        dev_us = np.diff(got_arrival[:n_j]) * 1e-3 - np.diff(due_us)
        return _pct(np.abs(dev_us))
    return _pct(np.zeros(0))


def run_replay(samples: Samples, opt: ReplayOptions) -> ReplayResult:
    """Replay `samples` into the target and check everything that comes back.

    Examples
    --------
    >>> from gyrodrift.codecs.wire import make_samples
    >>> s = make_samples(np.arange(40) / 400.0, np.zeros((40, 3)), np.tile([0, 0, 9.8], (40, 1)))
    >>> opt = ReplayOptions(speed=0.0, loop_realtime=False, harness_realtime=False,
    ...                     faults=FaultSpec(corrupt=0.1, seed=1))
    >>> res = run_replay(s, opt)  # the loop program on a pty, as fast as possible
    >>> acc = res.report["accounting"]
    >>> res.ok, acc["sent"], acc["rejected_on_link"]["crc"] + acc["outputs_received"]
    (True, 40, 40)
    """
    if len(samples) == 0:
        raise GyrodriftValueError("nothing to replay: the record is empty")
    if not np.all(np.diff(samples.t_us.astype(np.int64)) >= 0):
        raise GyrodriftValueError("record timestamps go backwards: cannot pace a replay")
    plan = plan_transmission(samples.t_s, opt.faults)
    rng = np.random.default_rng(opt.faults.seed + 1)
    smap = load_signal_map(opt.can_signals) if opt.can_signals is not None else None
    if smap is not None:
        samples = _as_decoded_by_the_loop(samples, smap)
    exp = _expected_outputs(samples, plan, opt, smap)
    payload = _payloads(samples, plan, opt, smap, rng)

    image = None
    if opt.target == "qemu":
        image = opt.firmware_image or cached_firmware(opt.processor)
    target: _Target | QemuTarget = _Target(opt) if image is None else \
        QemuTarget(image, opt.processor.timing.loop_hz, icount=opt.qemu_icount)
    link: SerialLink | CanLink | None = None
    write_ns = np.zeros(plan.sent_units, dtype=np.int64)
    # Sender and receiver run SCHED_FIFO just below the loop (80): each thread asks for
    # itself, so a refusal is reported per thread and nothing else inherits the policy.
    rt_prio = HARNESS_RT_PRIORITY if opt.harness_realtime else None
    harness_rt = {"sender": "not requested", "receiver": "not requested"}
    switch_interval_s = sys.getswitchinterval()
    sent = [0]  # units written so far, read by the progress thread
    bar = _ProgressThread(plan.sent_units, lambda: sent[0]) if opt.progress else None
    try:
        # Start-up inside the try: a Ctrl-C or failure while waiting for the loop's ready
        # line must end the child too (no loop program left running).
        target.start()
        if opt.transport == "serial":
            link = SerialLink(target.device, opt.baud, realtime_priority=rt_prio)
        else:
            link = CanLink(opt.transport, target.device, bitrate=opt.can_bitrate,
                           tty_baud=opt.baud, realtime_priority=rt_prio)
        if rt_prio is not None:
            harness_rt["sender"] = set_thread_realtime(rt_prio)
            # Sender and receiver share one GIL: a receiver woken by an output would wait up
            # to the switch interval (5 ms by default) for the sender to let go of it.
            sys.setswitchinterval(HARNESS_SWITCH_INTERVAL_S)
        # A SCHED_FIFO sender wakes from an OS sleep within tens of us: spin less.
        spin_ns = 50_000 if harness_rt["sender"].startswith("SCHED_FIFO") else 200_000
        start_ns, end_write_ns = _transmit(link, payload, plan, opt, rng, spin_ns, sent,
                                           write_ns)
        _wait_for_outputs(link, int(exp.seq.size), plan, opt)
    finally:
        if bar is not None:
            bar.stop()
        if link is not None:
            link.close()
        if opt.harness_realtime:
            set_thread_normal()
            sys.setswitchinterval(switch_interval_s)
        loop_stats = target.stop()
        if link is not None:
            harness_rt["receiver"] = link.receiver_realtime

    capture_error = link.capture.error
    got, got_arrival, link_issues = _received(link)
    report = _build_report(samples, plan, opt, exp, got, got_arrival, write_ns, start_ns,
                           end_write_ns, loop_stats, link_issues, capture_error, target)
    report["harness_realtime"] = harness_rt
    if image is not None:
        report["target"] = f"qemu {QEMU_MACHINE}: firmware image {image.elf}"
        report["firmware"] = {"image": image.as_dict(),
                              "step_cost": (loop_stats or {}).get("step_cost")}
        if opt.compare_host_loop:
            _compare_host_loop(samples, opt, got, loop_stats, report)
        report["ok"] = all(report["checks"].values())
    report["output_jitter_us"] = _output_jitter_us(got_arrival, exp.positions, plan, opt)
    if samples.log_report is not None:  # a CAN log: where every frame of it went
        report["input_log"] = samples.log_report.as_dict()
    n_cmp = min(got.seq.size, exp.positions.size)
    lat = (got_arrival[:n_cmp] - write_ns[exp.positions[:n_cmp]]) * 1e-3
    arrival_s = (got_arrival - start_ns) * 1e-9
    return ReplayResult(report, lat, arrival_s, loop_stats, got)


def _compare_host_loop(samples: Samples, opt: ReplayOptions, got: Samples,
                       image_stats: dict[str, Any] | None, report: dict[str, Any]) -> None:
    """The same transmission (same faults, same order) into the host loop, as fast as
    possible: its outputs and counters against the image's."""
    from dataclasses import replace

    host = run_replay(samples, replace(opt, target="loop", speed=0.0, loop_realtime=False,
                                       harness_realtime=False, progress=False,
                                       firmware_image=None))
    h = host.outputs
    assert h is not None
    n = min(h.seq.size, got.seq.size)
    seq_equal = bool(h.seq.size == got.seq.size and np.array_equal(h.seq, got.seq))
    flags_equal = bool(seq_equal and np.array_equal(h.flags, got.flags))
    a = got.channels[:n].astype(np.float64)
    b = h.channels[:n].astype(np.float64)
    both_nan = np.isnan(a) & np.isnan(b)
    diff = np.where(both_nan, 0.0, np.abs(a - b))
    identical = (a == b) | both_nan
    max_diff = [float(np.max(diff[:, c])) if n else float("nan") for c in range(6)]
    inputs = samples.channels.astype(np.float64)
    scale = [float(np.max(np.abs(inputs[:, c][np.isfinite(inputs[:, c])]), initial=0.0))
             for c in range(6)]
    tol = [HOST_LOOP_RELATIVE_TOLERANCE * max(sc, float(np.finfo(np.float32).tiny))
           for sc in scale]
    hs, fs = host.loop_stats or {}, image_stats or {}
    counters: dict[str, list[int]] = {}
    for k in ("frames_in", "frames_out"):
        counters[k] = [int(hs.get(k, -1)), int(fs.get(k, -2))]
    for group in ("rejected", "health"):
        for k, v in hs.get(group, {}).items():
            if k in fs.get(group, {}) or group == "health":
                counters[f"{group}.{k}"] = [int(v), int(fs.get(group, {}).get(k, -1))]
    unequal = {k: v for k, v in counters.items() if v[0] != v[1]}
    report["host_loop"] = {
        "outputs": int(h.seq.size),
        "seq_equal": seq_equal,
        "flags_equal": flags_equal,
        "values_bit_identical": int(np.count_nonzero(np.all(identical, axis=1))),
        "max_abs_difference": max_diff,
        "tolerance": tol,
        "relative_tolerance": HOST_LOOP_RELATIVE_TOLERANCE,
        "counters_compared": len(counters),
        "counters_unequal": unequal,
        "host_loop_ok": host.ok,
    }
    checks = report["checks"]
    checks["host_loop_outputs_equal"] = bool(
        seq_equal and flags_equal and n == got.seq.size
        and all(d <= t for d, t in zip(max_diff, tol, strict=True)))
    checks["host_loop_counters_equal"] = not unequal


class _ProgressThread:
    """A tqdm bar on stderr over `total` units, moved every 0.1 s by its own thread from
    `count()`: the real-time sender only stores an integer."""

    def __init__(self, total: int, count: Callable[[], int]) -> None:
        from tqdm import tqdm

        self._count = count
        self._bar = tqdm(total=total, desc="replay", unit="sample", file=sys.stderr,
                         mininterval=0.1)
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._run, name="replay-progress", daemon=True)
        self._thread.start()

    def _move(self) -> None:
        n = self._count()
        if n > self._bar.n:
            self._bar.update(n - self._bar.n)

    def _run(self) -> None:
        while not self._done.wait(0.1):
            self._move()

    def stop(self) -> None:
        self._done.set()
        self._thread.join()
        self._move()
        self._bar.close()


def _send(link: SerialLink | CanLink, unit: Any, rng: np.random.Generator) -> None:
    if isinstance(link, SerialLink):
        link.write(unit)
        return
    msgs, corrupt = unit
    for j, m in enumerate(msgs):
        if corrupt and j == 1:  # the GyroZ line (carries Seq) takes the line error
            line = f"t{m.arbitration_id:03X}{m.dlc:d}{bytes(m.data).hex().upper()}\r".encode()
            link.send_raw_line(corrupt_slcan_line(line, rng))
        else:
            link.send(m)


def _output_count(link: SerialLink | CanLink) -> int:
    if isinstance(link, SerialLink):
        return link.received_bytes() // FRAME_SIZE
    return len(link.capture.messages) // 4


def _pct(x: np.ndarray) -> dict[str, float]:
    if x.size == 0:
        return {"n": 0, "min": float("nan"), "p50": float("nan"), "p90": float("nan"),
                "p99": float("nan"), "max": float("nan")}
    return {"n": int(x.size), "min": float(np.min(x)), "p50": float(np.percentile(x, 50)),
            "p90": float(np.percentile(x, 90)), "p99": float(np.percentile(x, 99)),
            "max": float(np.max(x))}


def _max_abs_errors(got: Samples, exp_values: np.ndarray, n_cmp: int) -> list[float]:
    """Per channel, the largest |output - reference| over the first n_cmp outputs (NaN where
    both are NaN, a channel that never had a good value, counts as equal)."""
    if not n_cmp:
        return [float("nan")] * 6
    err = np.abs(got.channels[:n_cmp].astype(np.float64) - exp_values[:n_cmp])
    both_nan = np.isnan(got.channels[:n_cmp]) & np.isnan(exp_values[:n_cmp])
    err = np.where(both_nan, 0.0, err)
    return [float(np.max(err[:, c])) if not np.any(np.isnan(err[:, c])) else float("inf")
            for c in range(6)]


def _loop_checks(loop: dict[str, Any], opt: ReplayOptions, ref: Any, sent: int,
                 corrupted: int, proc_rejected: dict[str, int], n_exp: int) -> dict[str, bool]:
    """The loop's own statistics against what was sent and what the reference did."""
    checks: dict[str, bool] = {}
    rej = loop.get("rejected", {})
    loop_link = int(rej.get("crc", 0)) if opt.transport == "serial" else \
        int(rej.get("can_incomplete", 0))
    checks["loop_frames_in"] = int(loop["frames_in"]) == sent - corrupted
    checks["loop_link_rejections"] = loop_link == corrupted
    checks["loop_processor_rejections"] = all(
        int(rej.get(k, -1)) == v for k, v in proc_rejected.items())
    checks["loop_frames_out"] = int(loop["frames_out"]) == n_exp
    checks["loop_health_matches_reference"] = all(
        int(loop.get("health", {}).get(k, -1)) == int(ref.health[k])
        for k in ("samples_in", "samples_accepted", "seq_gaps", "missing_samples",
                  "seq_resyncs", "time_jumps", "non_finite_samples", "saturated_values",
                  "stuck_values"))
    other = {k: v for k, v in rej.items()
             if k not in (*proc_rejected, "crc", "can_incomplete") and v}
    if opt.transport == "slcan":
        # A line error costs the sample's GyroZ line (malformed), orphans its GyroXY
        # frame and leaves the accel half (2 frames) incomplete: 3 frames dropped.
        expect = {"slcan_malformed": corrupted, "can_orphan_frames": corrupted,
                  "can_frames_dropped": 3 * corrupted}
        checks["loop_slcan_line_errors"] = all(
            int(rej.get(k, 0)) == v for k, v in expect.items())
        other = {k: v for k, v in other.items() if k not in expect}
    checks["loop_no_other_rejections"] = not other
    return checks


def _build_report(samples: Samples, plan: TransmissionPlan, opt: ReplayOptions,
                  exp: _Expected, got: Samples, got_arrival: np.ndarray, write_ns: np.ndarray,
                  start_ns: int, end_write_ns: int, loop: dict[str, Any] | None,
                  link_issues: dict[str, int], capture_error: str,
                  target: _Target | QemuTarget) -> dict[str, Any]:
    ref, exp_seq, expected_pos = exp.ref, exp.seq, exp.positions
    corrupted = sum(1 for u in plan.units if u.corrupt)
    rej_flags = ref.flags[(ref.flags & FLAG_REJECTED) != 0]
    proc_rejected = {
        "duplicate": int(np.count_nonzero(rej_flags & FLAG_DUPLICATE)),
        "out_of_order": int(np.count_nonzero(rej_flags & FLAG_OUT_OF_ORDER)),
        "config": int(np.count_nonzero(rej_flags & FLAG_CONFIG_ERROR)),
    }
    link_reason = "crc" if opt.transport == "serial" else "can_incomplete"
    n_got = int(got.seq.size)
    n_exp = int(exp_seq.size)
    n_cmp = min(n_got, n_exp)
    seq_equal = bool(n_got == n_exp and np.array_equal(got.seq, exp_seq))
    flags_equal = bool(n_got == n_exp and np.array_equal(got.flags, exp.flags))
    max_err = _max_abs_errors(got, exp.values, n_cmp)
    sent = plan.sent_units
    rejected_total = corrupted + sum(proc_rejected.values())
    unaccounted = sent - rejected_total - n_got
    lat_us = (got_arrival[:n_cmp] - write_ns[expected_pos[:n_cmp]]) * 1e-3
    if n_got:
        dur_s = (int(got_arrival[-1]) - start_ns) * 1e-9
    else:
        dur_s = float("nan")
    send_s = (end_write_ns - start_ns) * 1e-9
    tolerance = 1e-5  # float32 loop vs float64 reference (|values| <= ~10: ~1e-6 rounding)
    accounting = {
        "samples_in_record": len(samples),
        "injected": dict(plan.counts),
        "sent": sent,
        "rejected_on_link": {link_reason: corrupted},
        "rejected_by_processor": proc_rejected,
        "outputs_expected": n_exp,
        "outputs_received": n_got,
        "unaccounted": int(unaccounted),
    }
    checks: dict[str, bool] = {
        "accounting_balances": unaccounted == 0 and n_got == n_exp,
        "output_seq_equal": seq_equal,
        "output_flags_equal": flags_equal,
        "values_within_tolerance": bool(n_cmp == n_exp and all(e <= tolerance for e in max_err)),
        "clean_output_link": not any(link_issues.values()) and not capture_error,
    }
    if loop is not None:
        checks.update(_loop_checks(loop, opt, ref, sent, corrupted, proc_rejected, n_exp))
    else:
        checks["loop_stats_available"] = opt.attach is not None  # attached: none expected
    report: dict[str, Any] = {
        "ok": all(checks.values()),
        "target": f"attached {opt.attach}" if opt.attach else "gyrodrift-loop",
        "transport": opt.transport,
        "device": target.device if opt.attach else f"{opt.local_link} {target.device}",
        "speed": "as fast as possible" if opt.speed == 0 else f"{opt.speed:g}x",
        "baud": opt.baud,
        "can_bitrate": opt.can_bitrate if opt.can else None,
        "loop_rate_hz": opt.processor.timing.loop_hz,
        "faults": opt.faults.to_dict(),
        "processor": {"config": opt.processor.as_dict()},
        "accounting": accounting,
        "comparison": {"n": n_cmp, "max_abs_error": max_err, "tolerance": tolerance,
                       "seq_equal": seq_equal, "flags_equal": flags_equal},
        "latency_us": _pct(lat_us),
        "throughput": {
            "send_s": send_s,
            "end_to_end_s": dur_s,
            "frames_per_s_sent": sent / send_s if send_s > 0 else float("nan"),
            "frames_per_s_end_to_end": n_got / dur_s if n_got and dur_s > 0 else float("nan"),
        },
        "output_link_issues": link_issues,
        "capture_error": capture_error,
        "reference_health": {k: int(v) for k, v in ref.health.items()},
        "checks": checks,
        "loop": loop,
    }
    return report
