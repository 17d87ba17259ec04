"""Fleet throughput on 1 vs 2 Dask workers (LocalCluster, processes, loopback) and memory per
worker with the chunked .npy reader.

Logs: N_LOGS records of N_SAMPLES x 6 channels (float32 .npy, white noise + random walk),
written once in chunks into --dir (reused when present). Each configuration runs the whole
fleet from scratch (--force semantics: fresh out dir) and reports wall time, logs/s,
samples/s (all channels), the ratio against 1 worker, the largest peak RSS of a worker during
a task (the task's own high-water mark, VmHWM reset when it starts; not ru_maxrss, which a
spawned worker inherits from this process) and the most a task added to the RSS it started
from.

    python benchmarks/bench_fleet.py [--logs 8] [--samples 1e7] [--dir /tmp/gyrodrift-fleet]
        [--workers 1,2] [--memory-budget-mib 256]
"""

from __future__ import annotations

import argparse
import math
import resource
import shutil
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _bench_util import machine
from gyrodrift.fleet import DEFAULT_MEMORY_BUDGET_MIB, FleetOptions, run_fleet


def make_logs(d: Path, n_logs: int, n: int, rate_hz: float) -> list[Path]:
    d.mkdir(parents=True, exist_ok=True)
    paths = []
    dt = 1.0 / rate_hz
    dens = np.array([1.9e-4, 1.9e-4, 1.9e-4, 2.5e-3, 2.5e-3, 2.5e-3])
    walks = np.array([2.6e-6, 2.6e-6, 2.6e-6, 7.0e-5, 7.0e-5, 7.0e-5])
    for i in range(n_logs):
        p = d / f"unit{i:02d}.npy"
        paths.append(p)
        if p.is_file():
            continue
        rng = np.random.default_rng(1000 + i)
        mm = np.lib.format.open_memmap(p.with_suffix(".tmp.npy"), mode="w+",
                                       dtype=np.float32, shape=(n, 6))
        level = np.zeros(6)
        chunk = 1 << 20
        for lo in range(0, n, chunk):
            m = min(chunk, n - lo)
            steps = rng.standard_normal((m, 6)) * (walks * math.sqrt(dt))
            walk = level + np.cumsum(steps, axis=0)
            level = walk[-1]
            mm[lo:lo + m] = walk + rng.standard_normal((m, 6)) * (dens / math.sqrt(dt))
        mm.flush()
        del mm
        p.with_suffix(".tmp.npy").rename(p)
    return paths


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--logs", type=int, default=8)
    ap.add_argument("--samples", type=float, default=1e7)
    ap.add_argument("--rate-hz", type=float, default=200.0)
    ap.add_argument("--dir", default="/tmp/gyrodrift-fleet-bench")
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--memory-budget-mib", type=float, default=DEFAULT_MEMORY_BUDGET_MIB,
                    help="FleetOptions.memory_budget_mib (0: spool every log, the reader "
                         "before issue 14's fix)")
    args = ap.parse_args()
    n = int(args.samples)
    d = Path(args.dir)
    t0 = time.perf_counter()
    paths = make_logs(d / "logs", args.logs, n, args.rate_hz)
    print(f"# logs ready in {time.perf_counter() - t0:.1f} s: {args.logs} x {n} samples x 6 "
          f"channels float32 ({paths[0].stat().st_size / 2**20:.0f} MiB each)")
    print(f"# {machine()}")
    opts = FleetOptions(rate_hz=args.rate_hz, plots=True,
                        memory_budget_mib=args.memory_budget_mib)
    # The parent's one-time imports (dask.distributed, the summary's matplotlib) happen here,
    # before any timing: otherwise the first configuration (1 worker) pays ~1.2-1.8 s that
    # the second does not, which flattered the ratio.
    import distributed  # noqa: F401
    import gyrodrift.fleet as fleet_module
    fleet_module._import_summary_libraries()
    rows = []
    for w in (int(v) for v in args.workers.split(",")):
        out = d / f"out-w{w}"
        shutil.rmtree(out, ignore_errors=True)
        peaks: list[float] = []
        added: list[float] = []
        cpu: list[tuple[float, float]] = []
        readers: set[str] = set()
        spans: list[tuple[float, float]] = []
        pids: list[int] = []

        def keep(r: dict, peaks: list[float] = peaks, added: list[float] = added,
                 cpu: list[tuple[float, float]] = cpu, readers: set[str] = readers,
                 spans: list[tuple[float, float]] = spans, pids: list[int] = pids) -> None:
            spans.append((float(r["t_start"]), float(r["t_end"])))
            pids.append(int(r.get("pid", -1)))
            peaks.append(float(r.get("peak_rss_mib", math.nan)))
            added.append(peaks[-1] - float(r.get("rss_start_mib") or math.nan))
            cpu.append((float(r.get("cpu_user_s", math.nan)),
                        float(r.get("cpu_sys_s", math.nan))))
            readers.add(str(r.get("reader")))

        t = time.perf_counter()
        ru0 = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(
            resource.RUSAGE_CHILDREN)
        s = run_fleet(paths, out, opts=opts, workers=w, root=d / "logs", on_result=keep)
        wall = time.perf_counter() - t
        ru1 = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(
            resource.RUSAGE_CHILDREN)
        if s["n_failed"]:
            raise SystemExit(f"failed logs: {s['failed']}")
        # This process (client, progress, results) and its reaped children (the cluster's
        # worker processes, counted when they exit at the cluster's close).
        parent = (ru1[0].ru_utime - ru0[0].ru_utime, ru1[0].ru_stime - ru0[0].ru_stime)
        children = (ru1[1].ru_utime - ru0[1].ru_utime, ru1[1].ru_stime - ru0[1].ru_stime)
        task = (sum(c[0] for c in cpu) / len(cpu), sum(c[1] for c in cpu) / len(cpu))
        # The tasks' phase: from the first task's start to the last one's end (no cluster
        # start and close, no fleet summary).
        tasks_wall = max(e for _, e in spans) - min(b for b, _ in spans)
        # tasks per worker process ("4+4"): a run where one worker took every task is a
        # scheduling anomaly, not the workers' speed
        per = sorted((pids.count(p) for p in set(pids)), reverse=True)
        rows.append((w, wall, max(peaks), max(added), task, parent, children,
                     ",".join(sorted(readers)), tasks_wall, "+".join(map(str, per))))
    base, base_tasks = rows[0][1], rows[0][8]
    print(f"{'workers':>7} {'wall_s':>8} {'logs/s':>8} {'samples/s':>11} {'ratio':>6} "
          f"{'tasks_s':>8} {'ratio':>6} {'peak_rss_MiB/worker':>20} {'task_added_MiB':>15} "
          f"{'task_cpu_u/s':>13} {'parent_cpu_u/s':>15} {'workers_cpu_u/s':>16} "
          f"{'tasks/worker':>12} reader")
    for w, wall, peak, add, task, parent, children, reader, tasks_wall, per_w in rows:
        print(f"{w:7d} {wall:8.1f} {args.logs / wall:8.3f} {args.logs * n * 6 / wall:11.3g} "
              f"{base / wall:6.2f} {tasks_wall:8.1f} {base_tasks / tasks_wall:6.2f} "
              f"{peak:20.0f} {add:15.0f} {task[0]:6.2f}/{task[1]:<6.2f} "
              f"{parent[0]:7.1f}/{parent[1]:<7.1f} {children[0]:8.1f}/{children[1]:<7.1f} "
              f"{per_w:>12} {reader}")
    print("# wall: the whole run_fleet (cluster start and close, summary); tasks: first task "
          "start to last task end; task_cpu: mean CPU seconds (user/system) of one task, its "
          "own thread; parent: this process; workers: the cluster's processes, whole run")
    print(f"# record size {n * 6 * 4 / 2**20:.0f} MiB per log; one float64 channel "
          f"{n * 8 / 2**20:.0f} MiB (memory budget {args.memory_budget_mib:g} MiB: "
          f"{'in memory' if n * 8 <= args.memory_budget_mib * 2**20 else 'spooled'}); the "
          f"chunked reader holds {(1 << 18) * 6 * 8 / 2**20:.0f} MiB of rows at a time")


if __name__ == "__main__":
    main()
