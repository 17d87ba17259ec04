"""Benchmark: gyrodrift.simulation.records generation speed vs allantools.noise in the same process.

Prints a markdown table (ns/sample, Msamples/s, ratio vs the allantools generator of the same
noise colour, median of repeats) and the machine. Not a test: the machine is shared and noisy.

    PYTHONPATH=python python3 benchmarks/bench_simulate.py [--n 10000000] [--repeats 5]
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import allantools.noise
import gyrodrift
from _bench_util import machine, median_seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=10_000_000, help="samples per record")
    parser.add_argument(
        "--pink-n",
        type=int,
        default=100_000,
        help="samples for allantools.noise.pink (a Python loop: slow)",
    )
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    n, pink_n = args.n, args.pink_n

    cases: list[tuple[str, int, Callable[[], object], str | None]] = [
        ("white rate (ARW N)", n, lambda: gyrodrift.simulate(n=n, n_deg_rt_h=0.01), "white"),
        ("random walk (RRW K)", n, lambda: gyrodrift.simulate(n=n, k_deg_h_rt_h=0.1), "brown"),
        ("flicker (B), FFT-shaped", n, lambda: gyrodrift.simulate(n=n, b_deg_h=0.05), None),
        (
            "flicker (B), FFT-shaped",
            pink_n,
            lambda: gyrodrift.simulate(n=pink_n, b_deg_h=0.05),
            "pink",
        ),
        ("AR(2) drift", n, lambda: gyrodrift.simulate(n=n, ar2=(0.6868, -0.0213, 0.05)), None),
        (
            "ARW + bias, RLG pulse counting (0.1 arcsec)",
            n,
            lambda: gyrodrift.simulate(
                n=n, n_deg_rt_h=0.01, bias_deg_h=15.0, pulse_deg=0.1 / 3600.0
            ),
            None,
        ),
        (
            "all terms Q+N+B+K+R+bias+AR(2)",
            n,
            lambda: gyrodrift.simulate(
                n=n,
                q_deg=0.0035,
                n_deg_rt_h=0.0012,
                b_deg_h=0.0794,
                k_deg_h_rt_h=0.01,
                r_deg_h2=0.001,
                bias_deg_h=0.5,
                ar2=(-0.034, 0.0252, 0.05),
            ),
            None,
        ),
        (
            "static IMU, 3 gyro + 3 accel (N, bias, VRW)",
            n // 3,
            lambda: gyrodrift.simulate_imu(
                n=n // 3, gyro=gyrodrift.NoiseTerms(n_deg_rt_h=0.01), vrw_m_s_rt_h=0.02
            ),
            None,
        ),
    ]
    peers: dict[str, Callable[[int], object]] = {
        "white": lambda k: allantools.noise.white(k),
        "brown": lambda k: allantools.noise.brown(k),
        "pink": lambda k: allantools.noise.pink(k),
    }

    print(f"machine: {machine()}; numpy generation, median of {args.repeats} repeats\n")
    print(
        "| record | samples | gyrodrift ns/sample | gyrodrift Msamples/s "
        "| allantools.noise peer | peer ns/sample | speed-up vs peer |"
    )
    print("| --- | ---: | ---: | ---: | --- | ---: | ---: |")
    for label, count, fn, peer in cases:
        t = median_seconds(fn, args.repeats)
        ns = t / count * 1e9
        row = f"| {label} | {count:.0e} | {ns:.1f} | {count / t / 1e6:.1f} "
        if peer is None:
            row += "| - | - | - |"
        else:
            tp = median_seconds(lambda p=peer, c=count: peers[p](c), args.repeats)
            ns_p = tp / count * 1e9
            row += f"| `{peer}` | {ns_p:.1f} | {ns_p / ns:.2f}x |"
        print(row)


if __name__ == "__main__":
    main()
