"""`gyrodrift replay`: replay an IMU record into the loop program (or a running target) over a
serial line or CAN, check every output against the reference processor, and report.

With no input file it simulates a short static IMU record itself, so it runs as a demo.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

from gyrodrift.cli import CliError
from gyrodrift.cli.common import add_json_arg, add_progress_arg, check_out_dir
from gyrodrift.imu.schema import DEFAULT_SAMPLE_RATE_HZ, field_spec
from gyrodrift.io.atomic import atomic_output

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``replay`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["replay", "flight.log", "--transport", "slcan", "--fast"])
    >>> args.input, args.transport, args.fast, args.progress, args.out_dir
    ('flight.log', 'slcan', True, 'auto', 'replay-report')
    """
    p = subparsers.add_parser(
        "replay",
        help="replay an IMU log into gyrodrift-loop (pty), the firmware image on QEMU, or a "
             "target, and verify the outputs",
        description=(
            "Replay an IMU record (binary frame log .bin, .csv, candump .log, Vector .asc, "
            ".blf) over a serial line or CAN into the gyrodrift-loop program on a "
            "pseudo-terminal, or into a running target (--device), and check every output "
            "against the reference processor. Without INPUT a short record is simulated."),
    )
    p.add_argument("input", nargs="?", help="IMU log; omitted: simulate --duration-s of data")
    p.add_argument("--format", dest="fmt", default=None,
                   help="log format (bin, csv, candump, asc, blf); default from the suffix")
    p.add_argument("--can-signals", default=None, metavar="MAP",
                   help="your own DBC: a signal map (TOML naming the DBC and which signals "
                        "are gx gy gz ax ay az, optional sequence and timestamp; see "
                        "gyrodrift.codecs.can_signals). The CAN log is read through it, and a "
                        "CAN replay sends the samples in that DBC's frames")
    p.add_argument("--transport", choices=("serial", "slcan", "socketcan"), default="serial",
                   help="link to the loop: serial frames, SLCAN (CAN over a serial line) or "
                        "SocketCAN (default serial)")
    p.add_argument("--target", choices=("loop", "qemu"), default="loop",
                   help="what a replay without --device starts: the gyrodrift-loop program "
                        "(loop), or the reference firmware image built from the configuration "
                        "and booted on QEMU's netduinoplus2 board, an STM32F405 (qemu; serial "
                        "transport; also replays the same input into the host loop and compares "
                        "outputs and counters) (default loop)")
    p.add_argument("--device", default=None,
                   help="attach to a running target: serial device (/dev/ttyUSB0), SLCAN "
                        "adapter device, or SocketCAN interface (can0); default: start "
                        "gyrodrift-loop on a pty")
    pace = p.add_mutually_exclusive_group()
    pace.add_argument("--speed", type=float, default=1.0,
                      help="pacing: 1 = original timestamps, k = k times faster (default 1)")
    pace.add_argument("--fast", action="store_true", help="as fast as possible")
    p.add_argument("--baud", type=int, default=921600, help="serial baud (default 921600)")
    p.add_argument("--can-bitrate", type=int, default=500000,
                   help="CAN bit rate (default 500000)")
    p.add_argument("--no-link-pacing", action="store_true",
                   help="do not hold frames back by their time on the wire")
    p.add_argument("--loop-rate-hz", type=float, default=None,
                   help="gyrodrift-loop rate, 1..2000 Hz (default: the configuration's "
                        "timing.loop_rate_hz)")
    p.add_argument("--loop-binary", default=None, help="path of gyrodrift-loop")
    p.add_argument("--no-rt", action="store_true",
                   help="do not ask for real-time scheduling: SCHED_FIFO and mlockall for the "
                        "loop, SCHED_FIFO for the harness's sender and receiver threads")
    p.add_argument("--duration-s", type=float, default=5.0,
                   help="length of the simulated record without INPUT (default 5)")
    p.add_argument("--rate-hz", type=float, default=None,
                   help="IMU sample rate, Hz (default: from the record, or the configuration's "
                        "timing.sample_rate_hz when simulating)")
    g = p.add_argument_group("fault injection (rates per sample)")
    for kind, done in (("drop", "dropped"), ("corrupt", "corrupted"),
                       ("duplicate", "duplicated"), ("reorder", "reordered"),
                       ("delay", "delayed")):
        g.add_argument(f"--fault-{kind}", type=float, default=0.0, metavar="P",
                       help=f"fault injection: probability that a sample is {done} (default 0)")
    g.add_argument("--fault-delay-s", type=float, default=0.02,
                   help="fault injection: delay of a delayed sample, s (default 0.02)")
    g.add_argument("--seed", type=int, default=0,
                   help="seed of the fault injection and of the simulated record (default 0)")
    pr = p.add_argument_group("processor (given to the loop and the reference alike)")
    pr.add_argument("--config", default=None, metavar="FILE",
                    help="processor configuration file (TOML; `gyrodrift config`): per-channel "
                         "chains, rates, tolerances (default: the shipped default "
                         "configuration, `gyrodrift config write-default`, with the record's "
                         "timing)")
    p.add_argument("--out-dir", default="replay-report",
                   help="output directory of report.json and report.png (default ./replay-report)")
    add_json_arg(p)
    add_progress_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift replay``; returns the exit code (1 when the replay check fails).

    Examples
    --------
    A simulated record (0.25 s at 400 Hz) into gyrodrift-loop on a pty, as fast as possible:

    >>> import tempfile
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> tmp = tempfile.TemporaryDirectory()
    >>> run(p.parse_args(["replay", "--duration-s", "0.25", "--fast", "--no-rt",
    ...                   "--out-dir", tmp.name]))
    result                             PASS
    ...
    samples in record                  100
    ...
    outputs expected / received        100 / 100
    unaccounted                        0
    ...
    report: .../report.json .../report.png
    0
    >>> tmp.cleanup()
    """
    import numpy as np

    from gyrodrift.cli.common import emit_json, progress_enabled
    from gyrodrift.codecs.wire import make_samples
    from gyrodrift.imu.config import ConfigError, default_config, load_config
    from gyrodrift.io.imu_log import read_imu_log
    from gyrodrift.replay.faults import FaultSpec
    from gyrodrift.replay.firmware import FirmwareError
    from gyrodrift.replay.harness import ReplayError, ReplayOptions, run_replay
    from gyrodrift.report.replay import (
        format_table,
        monitor_summary,
        monitor_traces,
        write_json,
        write_monitor_pngs,
        write_png,
    )

    if args.can_signals and not args.input:
        raise CliError("--can-signals applies to an input CAN log")
    proc_cfg = None
    if args.config:
        try:
            proc_cfg = load_config(args.config)
        except (ConfigError, OSError) as exc:
            raise CliError(str(exc)) from None
    check_out_dir(args.out_dir)  # before the replay, not after it
    if args.input:
        try:
            samples = read_imu_log(args.input, args.fmt, signals=args.can_signals)
        except (OSError, ValueError) as exc:
            raise CliError(str(exc)) from None
        dt = np.diff(samples.t_us.astype(np.float64)) * 1e-6
        rate = args.rate_hz or (1.0 / float(np.median(dt)) if dt.size and
                                np.median(dt) > 0 else DEFAULT_SAMPLE_RATE_HZ)
    else:
        from gyrodrift.simulation.records import NoiseTerms, simulate_imu

        if not (args.duration_s > 0 and math.isfinite(args.duration_s)):
            raise CliError("--duration-s must be > 0")
        rate = args.rate_hz or (proc_cfg.timing.sample_rate_hz if proc_cfg
                                else DEFAULT_SAMPLE_RATE_HZ)
        rec = simulate_imu(args.duration_s, rate_hz=rate, seed=args.seed,
                           gyro=NoiseTerms(n_deg_rt_h=0.01, b_deg_h=0.01, ar2=(1.0, -0.25, 0.5)),
                           vrw_m_s_rt_h=0.02)
        n = rec.gyro_rad_s.shape[0]
        samples = make_samples(np.arange(n) / rate, rec.gyro_rad_s, rec.accel_m_s2)
    if proc_cfg is not None and abs(rate - proc_cfg.timing.sample_rate_hz) > 0.01 * rate:
        raise CliError(f"sample rate {rate:.6g} Hz (record or --rate-hz) contradicts "
                       f"timing.sample_rate_hz {proc_cfg.timing.sample_rate_hz:g} of {args.config}")
    try:
        proc = proc_cfg if proc_cfg is not None else default_config(sample_rate_hz=rate)
        if args.loop_rate_hz is not None:
            spec = field_spec("timing", "loop_rate_hz")
            if not spec.accepts(args.loop_rate_hz):
                raise CliError(f"--loop-rate-hz: expected {spec.bounds_text()}, "
                               f"got {args.loop_rate_hz:g}")
            proc = proc.with_timing(loop_rate_hz=args.loop_rate_hz)
        faults = FaultSpec(drop=args.fault_drop, corrupt=args.fault_corrupt,
                           duplicate=args.fault_duplicate, reorder=args.fault_reorder,
                           delay=args.fault_delay, delay_s=args.fault_delay_s, seed=args.seed)
        opt = ReplayOptions(transport=args.transport, speed=0.0 if args.fast else args.speed,
                            baud=args.baud, can_bitrate=args.can_bitrate,
                            pace_link=not args.no_link_pacing, loop_binary=args.loop_binary,
                            loop_realtime=not args.no_rt,
                            harness_realtime=not args.no_rt,
                            attach=args.device, faults=faults, processor=proc,
                            # CAN replays then speak the user's DBC to the loop as well
                            can_signals=args.can_signals if args.transport != "serial"
                            else None, progress=progress_enabled(args), target=args.target)
    except (ConfigError, ValueError) as exc:
        raise CliError(str(exc)) from None
    try:
        result = run_replay(samples, opt)
    except (ReplayError, FirmwareError, OSError, ValueError) as exc:
        raise CliError(str(exc)) from None
    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    j, png = out / "report.json", out / "report.png"
    monitor_pngs: list[Path] = []
    if proc.monitor.enabled:  # the online estimates against the offline fit of the record
        traces = monitor_traces(samples, proc)
        result = dataclasses.replace(result, report={
            **result.report, "monitor": monitor_summary(traces, result.loop_stats)})
        monitor_pngs = write_monitor_pngs(traces, samples, proc.timing.sample_rate_hz,
                                          out / "monitor.png")
    with atomic_output(j) as tmp_j, atomic_output(png) as tmp_png:
        write_json(result, tmp_j)
        write_png(result, tmp_png)
    if args.json:
        emit_json({**result.report, "files": {"json": str(j), "png": str(png),
                                              "monitor_png": [str(m) for m in monitor_pngs]}})
    else:
        print(format_table(result))
        print(f"report: {j} {png}" + "".join(f" {m}" for m in monitor_pngs))
    return 0 if result.ok else 1
