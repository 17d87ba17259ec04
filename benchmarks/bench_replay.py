"""Benchmark: hardware-in-the-loop replay through gyrodrift-loop on a pseudo-terminal.

1. Real time: `--duration-s` (default 600 = 10 min) of 400 Hz six-channel data replayed at 1x
   over the serial pty into the loop (SCHED_FIFO + mlockall when permitted): lost frames,
   latency (input written -> output read), the loop's period jitter, compute per sample
   (decode-free ImuProcessor<float> step) and per cycle (read + all steps + write).
2. As fast as possible: serial pty throughput end to end (median of repeats), against the
   peer run in the same process: the same frames parsed (gyrodrift.codecs.FrameParser) and
   filtered (gyrodrift.reference.imu.process_imu) in Python. Plus SLCAN through python-can.

3. Under load (`--stress-cpu 2`): part 1 again while `stress-ng --cpu 2` keeps every core
   of a 2-core machine busy, once with the harness's sender and receiver threads SCHED_FIFO
   (the default, like the loop) and once without (`harness_realtime=False`), so the effect
   of the real-time treatment is measured side by side; and a third time over a socketpair
   instead of the pty, to separate the kernel's tty layer (its flip-buffer work runs at
   normal priority, competing with stress-ng) from the harness and the loop.
   Goal: 0 lost, latency p99 <= 2 ms, loop period jitter p99 <= 200 us.

Set-up for part 3 (only this benchmark needs it, not the tests): stress-ng, from Debian; the
benchmark installs it itself (`apt-get install -y stress-ng`, as root or through sudo) and
stops with that command when it cannot. Real-time scheduling needs root or CAP_SYS_NICE (the
report says when it was refused).

Prints markdown tables and the machine. Not a test: the machine is shared and noisy.

    PYTHONPATH=python:build/dev-NAME/py GYRODRIFT_CPP_BUILD_DIR=build/dev-NAME \
        python3 benchmarks/bench_replay.py [--duration-s 600] [--fast-frames 200000]
    python3 benchmarks/bench_replay.py --skip-fast --duration-s 60 --stress-cpu 2
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from _bench_util import machine, median_seconds
from gyrodrift.codecs import FrameParser
from gyrodrift.codecs.wire import Samples, encode_frames, make_samples
from gyrodrift.imu.config import ProcessorConfig, default_config
from gyrodrift.reference.imu import process_imu
from gyrodrift.replay.harness import ReplayOptions, ReplayResult, find_loop_binary, run_replay
from gyrodrift.simulation.records import NoiseTerms, simulate_imu


def record(n: int, rate_hz: float) -> Samples:
    rec = simulate_imu(n=n, rate_hz=rate_hz, seed=1, vrw_m_s_rt_h=0.02,
                       gyro=NoiseTerms(n_deg_rt_h=0.01, b_deg_h=0.01, ar2=(1.0, -0.25, 0.5)))
    return make_samples(np.arange(n) / rate_hz, rec.gyro_rad_s, rec.accel_m_s2)


def settings(rate_hz: float) -> ProcessorConfig:
    sigma2 = (0.5 * np.pi / 180 / 3600) ** 2
    return default_config(gyro_model=(1.0, -0.25, 0.0, sigma2, 1e-10), sample_rate_hz=rate_hz)


def yes(ok: bool) -> str:
    return "yes" if ok else "**no**"


def real_time(args: argparse.Namespace, *, harness_rt: bool = True, load: str = "",
              local_link: str = "pty") -> tuple[list[str], ReplayResult]:
    rate = 400.0
    n = int(args.duration_s * rate)
    res = run_replay(record(n, rate), ReplayOptions(
        transport="serial", speed=1.0, loop_binary=args.loop_binary,
        processor=settings(rate).with_timing(loop_rate_hz=args.loop_rate_hz),
        harness_realtime=harness_rt,
        local_link=local_link))
    rep, loop = res.report, res.loop_stats or {}
    acc = rep["accounting"]
    lost = acc["sent"] - acc["outputs_received"]
    lat = rep["latency_us"]
    jit = loop.get("period_jitter_us", {})
    step = loop.get("sample_us", {})
    comp = loop.get("compute_us", {})
    rt = loop.get("realtime", {})
    ojit = rep.get("output_jitter_us", {})
    hrt = rep.get("harness_realtime", {})
    rows = [
        f"### Real time: {args.duration_s:g} s of 400 Hz six-channel data at 1x, serial "
        f"{'pty' if local_link == 'pty' else 'over a socketpair (no tty layer)'}, "
        f"loop at {args.loop_rate_hz:g} Hz{load}; harness real time "
        f"{'requested' if harness_rt else 'not requested'}",
        "",
        "| metric | value | target | met |",
        "| --- | --- | --- | --- |",
        f"| frames sent / outputs received | {acc['sent']} / {acc['outputs_received']} | | |",
        f"| lost frames (unaccounted) | {lost} ({acc['unaccounted']}) | 0 | {yes(lost == 0)} |",
        f"| outputs equal to reference (max abs err) | "
        f"{max(rep['comparison']['max_abs_error']):.2e} | <= 1e-5 | "
        f"{yes(rep['checks']['values_within_tolerance'])} |",
        f"| latency p50 / p99 / max (us) | {lat['p50']:.0f} / {lat['p99']:.0f} / "
        f"{lat['max']:.0f} | p99 <= {args.latency_goal_us:g} | "
        f"{yes(lat['p99'] <= args.latency_goal_us)} |",
        f"| latency min (us; never negative) | {lat['min']:.0f} | >= 0 | {yes(lat['min'] >= 0)} |",
        f"| loop period jitter p50 / p99 / max (us) | {jit.get('p50', float('nan')):.1f} / "
        f"{jit.get('p99', float('nan')):.1f} / {jit.get('max', float('nan')):.1f} | "
        f"p99 <= 200 | {yes(jit.get('p99', 1e9) <= 200)} |",
        f"| output inter-arrival jitter at the harness p50 / p99 / max (us) | "
        f"{ojit.get('p50', float('nan')):.1f} / {ojit.get('p99', float('nan')):.1f} / "
        f"{ojit.get('max', float('nan')):.1f} | | |",
        "| compute per sample (6-ch ImuProcessor step + output encode) p50 / p99 / max (us) | "
        f"{step.get('p50', float('nan')):.3f} / {step.get('p99', float('nan')):.3f} / "
        f"{step.get('max', float('nan')):.3f} | max <= 2 | {yes(step.get('max', 1e9) <= 2)} |",
        f"| compute per cycle incl. read/write syscalls p50 / p99 / max (us) | "
        f"{comp.get('p50', float('nan')):.1f} / {comp.get('p99', float('nan')):.1f} / "
        f"{comp.get('max', float('nan')):.1f} | | |",
        f"| cycles / overruns | {loop.get('cycles')} / {loop.get('overruns')} | | |",
        f"| SCHED_FIFO / mlockall | {rt.get('sched_fifo')} / {rt.get('mlockall')} | both | "
        f"{yes(bool(rt.get('sched_fifo') and rt.get('mlockall')))} |",
        f"| harness sender / receiver scheduling | {hrt.get('sender')} / "
        f"{hrt.get('receiver')} | | |",
        f"| all replay checks | {'pass' if res.ok else 'FAIL'} | pass | {yes(res.ok)} |",
    ]
    return rows, res


def fast(args: argparse.Namespace) -> list[str]:
    rate = 400.0
    n = args.fast_frames
    rec = record(n, rate)
    opt = ReplayOptions(transport="serial", speed=0.0, loop_binary=args.loop_binary,
                        processor=settings(rate).with_timing(loop_rate_hz=args.loop_rate_hz))
    rates, oks = [], []
    for _ in range(args.repeats):
        res = run_replay(rec, opt)
        rates.append(res.report["throughput"]["frames_per_s_end_to_end"])
        oks.append(res.ok)
    loop_fps = statistics.median(rates)
    # Peer in the same process: Python parses and filters the same frames (a subset: it is
    # slow), timed the same way (median of repeats).
    n_peer = min(n, args.peer_frames)
    sub = rec.take(np.arange(n_peer))
    data = encode_frames(sub).tobytes()
    cfg = settings(rate).imu_config()

    def peer() -> None:
        frames = FrameParser().feed(data)
        process_imu([f.seq for f in frames], [f.t_us for f in frames],
                    np.array([f.values for f in frames]), cfg)

    peer_fps = n_peer / median_seconds(peer, args.repeats)
    # SLCAN through python-can (the Python peer of the loop's SLCAN side).
    n_can = min(n, args.slcan_frames)
    res_can = run_replay(rec.take(np.arange(n_can)), ReplayOptions(
        transport="slcan", speed=0.0, loop_binary=args.loop_binary,
        processor=settings(rate).with_timing(loop_rate_hz=args.loop_rate_hz)))
    can_fps = res_can.report["throughput"]["frames_per_s_end_to_end"]
    return [
        f"### As fast as possible (median of {args.repeats})",
        "",
        "| path | frames | ns/frame | frames/s | ratio vs Python peer | target | met |",
        "| --- | --- | --- | --- | --- | --- | --- |",
        f"| serial pty -> gyrodrift-loop -> pty, end to end | {n} | {1e9 / loop_fps:.0f} | "
        f"{loop_fps:,.0f} | {loop_fps / peer_fps:.1f} | >= 200,000 | "
        f"{yes(loop_fps >= 200_000 and all(oks))} |",
        f"| Python peer: codecs.FrameParser + reference.imu.process_imu (offline) | {n_peer} | "
        f"{1e9 / peer_fps:.0f} | {peer_fps:,.0f} | 1.0 | | |",
        f"| SLCAN pty via python-can slcan -> gyrodrift-loop -> python-can | {n_can} samples "
        f"({4 * n_can} CAN frames) | {1e9 / can_fps:.0f} | {can_fps:,.0f} samples/s | "
        f"{can_fps / peer_fps:.2f} | | {yes(res_can.ok)} |",
    ]


def cpp_bench(args: argparse.Namespace) -> list[str]:
    """cpp/bench/bench_replay.cpp: the per-sample work with no I/O, SCHED_FIFO if permitted."""
    exe = Path(args.loop_binary).parents[2] / "bench_replay"
    head = ["### Per-sample compute without I/O (cpp/bench/bench_replay.cpp)", ""]
    if not exe.is_file():
        return [*head, f"(not built: {exe})"]
    cmd = [str(exe), str(args.cpp_samples), "5"]
    rt = "SCHED_FIFO 80"
    try:
        out = subprocess.run(["chrt", "-f", "80", *cmd], capture_output=True, text=True,
                             check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        rt = "SCHED_OTHER"
        out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    return [*head, f"Scheduling: {rt}. Per-sample times include two clock_gettime calls.", "",
            "| work | ns/sample (bulk, median) | samples/s | p50 ns | p99 ns | p99.99 ns "
            "| max ns |", "| --- | --- | --- | --- | --- | --- | --- |", out.strip()]


def install_stress_ng() -> str:
    """The benchmark's own set-up (not the tests'): Debian's stress-ng through apt-get, as
    root or through sudo; exits with the command to run when that is not possible."""
    apt = shutil.which("apt-get")
    sudo = [] if os.geteuid() == 0 else ["sudo", "-n"]
    if apt is not None and (not sudo or shutil.which("sudo")):
        print("# installing stress-ng (apt-get install -y stress-ng)", file=sys.stderr)
        env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
        for cmd in ([*sudo, apt, "update", "-qq"],
                    [*sudo, apt, "install", "-y", "-qq", "--no-install-recommends", "stress-ng"]):
            subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, check=False)
    exe = shutil.which("stress-ng")
    if exe is None:
        sys.exit("--stress-cpu needs stress-ng and installing it failed: run "
                 "`apt-get install -y stress-ng` (Debian/Ubuntu) as root")
    return exe


def start_stress(n_cpu: int) -> subprocess.Popen[bytes]:
    """`stress-ng --cpu N` in its own process group (ended by stop_stress)."""
    exe = shutil.which("stress-ng") or install_stress_ng()
    proc = subprocess.Popen([exe, "--cpu", str(n_cpu), "--quiet"], start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(2.0)  # let the workers spin up
    if proc.poll() is not None:
        sys.exit(f"stress-ng exited at once (code {proc.returncode})")
    return proc


def stop_stress(proc: subprocess.Popen[bytes]) -> None:
    os.killpg(proc.pid, signal.SIGTERM)  # its own session: only stress-ng and its workers
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def load_avg() -> str:
    return ", ".join(f"{x:.1f}" for x in os.getloadavg())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--duration-s", type=float, default=600.0)
    parser.add_argument("--loop-rate-hz", type=float, default=2000.0,
                        help="loop rate for both parts (2 kHz: a 400 Hz sample waits < 0.5 ms)")
    parser.add_argument("--fast-frames", type=int, default=200_000)
    parser.add_argument("--peer-frames", type=int, default=20_000)
    parser.add_argument("--slcan-frames", type=int, default=5_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--cpp-samples", type=int, default=1_000_000)
    parser.add_argument("--loop-binary", default=None)
    parser.add_argument("--json", default=None, help="also write the real-time report here")
    parser.add_argument("--skip-real-time", action="store_true")
    parser.add_argument("--skip-fast", action="store_true",
                        help="skip the C++ and as-fast-as-possible parts")
    parser.add_argument("--stress-cpu", type=int, default=0, metavar="N",
                        help="run the real-time part under `stress-ng --cpu N`, with and without "
                             "the harness's real-time threads (needs stress-ng)")
    args = parser.parse_args()
    args.loop_binary = str(find_loop_binary(args.loop_binary))
    args.latency_goal_us = 2000.0 if args.stress_cpu else 1000.0
    print(f"machine: {machine()}; load average at start: {load_avg()}; "
          f"loop: {args.loop_binary}\n")
    if not args.skip_fast:
        for line in cpp_bench(args):
            print(line, flush=True)
        print()
        for line in fast(args):
            print(line, flush=True)
        print()
    if args.skip_real_time:
        return
    if not args.stress_cpu:
        rows, res = real_time(args)
        for line in rows:
            print(line)
        print(f"\nload average at end: {load_avg()}")
        if args.json:
            with open(args.json, "w") as fh:
                json.dump(res.report, fh, indent=1, default=str)
        return
    stress = start_stress(args.stress_cpu)
    reports = {}
    try:
        for name, harness_rt, link in (("harness_rt", True, "pty"),
                                       ("harness_normal", False, "pty"),
                                       ("harness_rt_socketpair", True, "socketpair")):
            print(f"load average before this run (stress-ng --cpu {args.stress_cpu} running): "
                  f"{load_avg()}")
            rows, res = real_time(args, harness_rt=harness_rt, local_link=link,
                                  load=f", under `stress-ng --cpu {args.stress_cpu}`")
            reports[name] = res.report
            for line in rows:
                print(line, flush=True)
            print(f"\nload average at end of run: {load_avg()}\n")
    finally:
        stop_stress(stress)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(reports, fh, indent=1, default=str)


if __name__ == "__main__":
    main()
