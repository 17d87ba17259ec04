"""Benchmark: IMU processor and frame codecs, C++ (via gyrodrift._core) vs the peers run in the
same process: the numpy reference processor, the Python serial twin, cantools (CAN encode and
decode through the DBC). Median of repeats; prints a markdown table and the machine, then the
C++-only table of cpp/bench/bench_imu (single-step distribution) if the build has it.

    PYTHONPATH=python:build/dev-NAME/py GYRODRIFT_CPP_BUILD_DIR=build/dev-NAME \
        python3 benchmarks/bench_imu.py [--samples 100000] [--repeats 5]
"""

from __future__ import annotations

import argparse
import os
import subprocess
from pathlib import Path

import numpy as np
from _bench_util import machine, median_seconds
from gyrodrift import _core
from gyrodrift.codecs import FrameParser, SampleAssembler, encode_frames, encode_sample, load_dbc
from gyrodrift.imu.processor import ImuChannelConfig, ImuConfig, ImuProcessor
from gyrodrift.reference.imu import process_imu


def record(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    x = np.zeros((n, 3))
    e = rng.normal(0, 1e-5, (n, 3))
    for k in range(2, n):
        x[k] = 1.6 * x[k - 1] - 0.65 * x[k - 2] + e[k]
    gyro = 1e-5 + x + rng.normal(0, 1e-5, (n, 3))
    accel = rng.normal([0, 0, 9.81], 0.01, (n, 3))
    return np.arange(n) % 65536, np.arange(n, dtype=np.uint64) * 2500, np.hstack([gyro, accel])


def config() -> ImuConfig:
    gyro = ImuChannelConfig(
        filter="ar2_kalman", a1=1.6, a2=-0.65, sigma2=1e-10, mean=1e-5, q=1e-10, r=1e-9
    )
    return ImuConfig(channels=[gyro] * 3 + [ImuChannelConfig()] * 3)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, default=100_000)
    ap.add_argument("--peer-samples", type=int, default=10_000, help="size for slow Python peers")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    n, m, reps = args.samples, args.peer_samples, args.repeats
    seq, t_us, values = record(n)
    cfg = config()
    print(f"Machine: {machine()}; numpy {np.__version__}")
    print()
    print("| operation | gyrodrift ns/item | items/s | peer | peer ns/item | speed-up |")
    print("| --- | ---: | ---: | --- | ---: | ---: |")

    def line(what: str, ns: float, peer: str, peer_ns: float) -> None:
        print(
            f"| {what} | {ns:.1f} | {1e9 / ns:.3g} | {peer} | {peer_ns:.0f} | {peer_ns / ns:.0f}x |"
        )

    p64 = ImuProcessor(cfg)
    t = median_seconds(lambda: (p64.reset(), p64.process(seq, t_us, values)), reps) / n * 1e9
    t_ref = median_seconds(
        lambda: process_imu(seq[:m], t_us[:m], values[:m], cfg), max(1, reps // 2)
    )
    line("ImuProcessor f64 batch (6 ch)", t, "numpy reference", t_ref / m * 1e9)
    p32 = ImuProcessor(cfg, dtype=np.float32)
    v32 = values.astype(np.float32)
    t = median_seconds(lambda: (p32.reset(), p32.process(seq, t_us, v32)), reps) / n * 1e9
    line("ImuProcessor f32 batch (6 ch)", t, "numpy reference", t_ref / m * 1e9)

    stream = encode_frames(seq, t_us, values)
    t = median_seconds(lambda: _core.serial_parse(stream, 4096, True), reps) / n * 1e9
    sub = stream[: m * 42]
    t_py = median_seconds(lambda: FrameParser().feed(sub), max(1, reps // 2)) / m * 1e9
    line("serial parse (42-B frames)", t, "Python twin", t_py)

    vals = [tuple(float(v) for v in values[k]) for k in range(m)]
    t = median_seconds(
        lambda: [_core.serial_encode_frame(1, k, 0, 2500 * k, vals[k]) for k in range(m)], reps
    )
    t_py = median_seconds(lambda: encode_frames(seq[:m], t_us[:m], values[:m]), reps)
    line("serial encode, per-call binding", t / m * 1e9, "numpy-vectorised twin", t_py / m * 1e9)

    t = median_seconds(
        lambda: [_core.can_encode_sample(k, 0, vals[k], 0x100) for k in range(m)], reps
    )
    t_ct = median_seconds(lambda: [encode_sample(k, vals[k]) for k in range(m)], max(1, reps // 2))
    line("CAN encode sample (4 frames)", t / m * 1e9, "cantools (DBC)", t_ct / m * 1e9)

    frames = [
        (f.arbitration_id, bytes(f.data)) for k in range(m) for f in encode_sample(k, vals[k])
    ]
    msgs = [f for k in range(m) for f in encode_sample(k, vals[k])]
    t = median_seconds(lambda: _core.can_assemble(frames), reps)

    def py_assemble() -> None:
        a = SampleAssembler()
        for msg in msgs:
            a.push(msg)

    t_py = median_seconds(py_assemble, max(1, reps // 2))
    line("CAN reassemble sample", t / m * 1e9, "cantools decode + twin", t_py / m * 1e9)
    db = load_dbc()
    t_dec = median_seconds(lambda: [db.decode_message(i, d) for i, d in frames], max(1, reps // 2))
    line("CAN decode (per sample, 4 frames)", t / m * 1e9, "cantools decode only", t_dec / m * 1e9)

    slc = b"".join(_core.slcan_encode(i, d) for i, d in frames)
    t = median_seconds(lambda: _core.slcan_parse(slc), reps)
    t_py = median_seconds(
        lambda: [
            (int(ln[1:4], 16), bytes.fromhex(ln[5:].decode())) for ln in slc.split(b"\r") if ln
        ],
        reps,
    )
    line(
        "SLCAN parse (per frame)",
        t / len(frames) * 1e9,
        "bytes.split+fromhex",
        t_py / len(frames) * 1e9,
    )
    print()
    print(f"(C++ rows: {n} samples; Python peers on {m}; medians of {reps} / {max(1, reps // 2)})")

    build = os.environ.get("GYRODRIFT_CPP_BUILD_DIR")
    exe = Path(build) / "cpp" / "bench_imu" if build else None
    if exe is not None and exe.exists():
        print()
        out = subprocess.run([str(exe), str(2 * n), str(reps)], capture_output=True, text=True)
        print(out.stdout.rstrip())


if __name__ == "__main__":
    main()
