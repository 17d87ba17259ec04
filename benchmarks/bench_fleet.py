"""Fleet throughput on 1 vs 2 Dask workers (LocalCluster, processes, loopback) and memory per
worker with the chunked .npy reader.

Logs: N_LOGS records of N_SAMPLES x 6 channels (float32 .npy, white noise + random walk),
written once in chunks into --dir (reused when present). Each configuration runs the whole
fleet from scratch (`fleet --redo` semantics: fresh out dir) and reports wall time, logs/s,
samples/s (all channels), the ratio against 1 worker, the largest peak RSS of a worker during
a task (the task's own high-water mark, VmHWM reset when it starts; not ru_maxrss, which a
spawned worker inherits from this process) and the most a task added to the RSS it started
from.

Each configuration runs in a fresh Python process (a child of this one), so that what a
process does once (imports, the fleet's forkserver that its workers are forked from) is paid
by every configuration alike; --repeat N runs the configurations N times in turn and prints
the median ratios. CPU accounting per configuration: this process's CPU (client, scheduler,
nannies, summary) per phase of run_fleet, and the CPU of the cluster's processes (the
workers, whether spawned or forked, and the forkserver's imports), whole run.

    python benchmarks/bench_fleet.py [--logs 8] [--samples 1e7] [--dir /tmp/gyrodrift-fleet]
        [--workers 1,2] [--memory-budget-mib 256] [--repeat 1]
"""

from __future__ import annotations

import argparse
import inspect
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _bench_util import machine
from gyrodrift.workflows.fleet import DEFAULT_MEMORY_BUDGET_MIB, FleetOptions, run_fleet


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


def _children_cpu() -> float:
    """CPU seconds of this process's children: those reaped (spawned workers, after the
    cluster's close) and those still running (the forkserver, with the forked workers it has
    reaped, and multiprocessing's resource tracker), read from /proc."""
    t = os.times()
    total = t.children_user + t.children_system
    tick = os.sysconf("SC_CLK_TCK")
    me = str(os.getpid())
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/stat") as fh:
                f = fh.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if f[1] == me:  # ppid; utime, stime, cutime, cstime
            total += sum(int(v) for v in f[11:15]) / tick
    return total


def run_one(w: int, paths: list[Path], out: Path, opts: FleetOptions,
            root: Path) -> dict[str, Any]:
    """One configuration in this (fresh) process: the fleet of `paths` on `w` workers."""
    # The parent's one-time imports (dask.distributed, the summary's matplotlib) happen here,
    # before any timing: otherwise the first configuration (1 worker) pays ~1.2-1.8 s that
    # the second does not, which flattered the ratio.
    import distributed  # noqa: F401
    import gyrodrift.workflows.fleet as fleet_module
    fleet_module._import_summary_libraries()
    shutil.rmtree(out, ignore_errors=True)
    rs: list[dict[str, Any]] = []
    phases: dict[str, dict[str, float]] = {}
    kw: dict[str, Any] = {}
    if "phases" in inspect.signature(run_fleet).parameters:  # older code: no phases
        kw["phases"] = phases
    t_epoch, t, c0 = time.time(), time.perf_counter(), os.times()
    ch0 = _children_cpu()
    s = run_fleet(paths, out, opts=opts, workers=w, root=root, on_result=rs.append, **kw)
    wall = time.perf_counter() - t
    c1 = os.times()
    helpers = _children_cpu() - ch0
    if s["n_failed"]:
        raise SystemExit(f"failed logs: {s['failed']}")
    pids = [int(r.get("pid", -1)) for r in rs]
    return {
        "workers": w, "wall": wall,
        # The tasks' phase: from the first task's start to the last one's end (no cluster
        # start and close, no fleet summary).
        "tasks_wall": max(r["t_end"] for r in rs) - min(r["t_start"] for r in rs),
        "startup": min(r["t_start"] for r in rs) - t_epoch,
        "tail": t_epoch + wall - max(r["t_end"] for r in rs),
        "peak": max(float(r.get("peak_rss_mib", math.nan)) for r in rs),
        "added": max(float(r.get("peak_rss_mib", math.nan))
                     - float(r.get("rss_start_mib") or math.nan) for r in rs),
        "task_cpu": [statistics.fmean(float(r.get(k, math.nan)) for r in rs)
                     for k in ("cpu_user_s", "cpu_sys_s")],
        "parent_cpu": (c1.user - c0.user) + (c1.system - c0.system),
        "helpers_cpu": helpers,
        "readers": ",".join(sorted({str(r.get("reader")) for r in rs})),
        # tasks per worker process ("4+4"): a run where one worker took every task is a
        # scheduling anomaly, not the workers' speed
        "per_worker": "+".join(map(str, sorted((pids.count(p) for p in set(pids)),
                                               reverse=True))),
        "phases": phases,
        "load": os.getloadavg()[0],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--logs", type=int, default=8)
    ap.add_argument("--samples", type=float, default=1e7)
    ap.add_argument("--rate-hz", type=float, default=200.0)
    ap.add_argument("--dir", default="/tmp/gyrodrift-fleet-bench")
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--repeat", type=int, default=1,
                    help="run the configurations this many times in turn; median ratios")
    ap.add_argument("--memory-budget-mib", type=float, default=DEFAULT_MEMORY_BUDGET_MIB,
                    help="FleetOptions.memory_budget_mib (0: spool every log to disk "
                         "first)")
    ap.add_argument("--run-one", type=int, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    n = int(args.samples)
    d = Path(args.dir)
    opts = FleetOptions(rate_hz=args.rate_hz, plots=True,
                        memory_budget_mib=args.memory_budget_mib)
    if args.run_one is not None:  # a child: one configuration, one JSON line
        paths = make_logs(d / "logs", args.logs, n, args.rate_hz)
        print(json.dumps(run_one(args.run_one, paths, d / f"out-w{args.run_one}", opts,
                                 d / "logs")))
        return
    t0 = time.perf_counter()
    paths = make_logs(d / "logs", args.logs, n, args.rate_hz)
    print(f"# logs ready in {time.perf_counter() - t0:.1f} s: {args.logs} x {n} samples x 6 "
          f"channels float32 ({paths[0].stat().st_size / 2**20:.0f} MiB each)")
    print(f"# {machine()}")
    ws = [int(v) for v in args.workers.split(",")]
    runs: list[list[dict[str, Any]]] = []
    for _ in range(args.repeat):
        rows = []
        for w in ws:
            child = [sys.executable, __file__, "--run-one", str(w), "--logs", str(args.logs),
                     "--samples", str(args.samples), "--rate-hz", str(args.rate_hz),
                     "--dir", str(d), "--memory-budget-mib", str(args.memory_budget_mib)]
            proc = subprocess.run(child, capture_output=True, text=True, check=False)
            if proc.returncode != 0:
                raise SystemExit(proc.stderr[-3000:])
            rows.append(json.loads(proc.stdout.strip().splitlines()[-1]))
        runs.append(rows)
        _print_run(rows, args.logs, n)
    if args.repeat > 1:
        for k, w in enumerate(ws[1:], 1):
            whole = [r[0]["wall"] / r[k]["wall"] for r in runs]
            tasks = [r[0]["tasks_wall"] / r[k]["tasks_wall"] for r in runs]
            print(f"# {w} workers vs {ws[0]}, {args.repeat} repeats: whole run "
                  f"{', '.join(f'{v:.2f}' for v in whole)} (median "
                  f"{statistics.median(whole):.2f}); tasks phase "
                  f"{', '.join(f'{v:.2f}' for v in tasks)} (median "
                  f"{statistics.median(tasks):.2f})")
    print("# wall: the whole run_fleet (cluster start and close, summary); tasks: first task "
          "start to last task end; start: run start to the first task's start; tail: last "
          "task end to run_fleet's return; task_cpu: mean CPU seconds (user/system) of one "
          "task, its own thread; parent_cpu: this process (client, scheduler, nannies, "
          "summary); cluster_cpu: the workers' processes and the forkserver, whole run")
    print(f"# record size {n * 6 * 4 / 2**20:.0f} MiB per log; one float64 channel "
          f"{n * 8 / 2**20:.0f} MiB (memory budget {args.memory_budget_mib:g} MiB: "
          f"{'in memory' if n * 8 <= args.memory_budget_mib * 2**20 else 'spooled'}); the "
          f"chunked reader holds {(1 << 18) * 6 * 8 / 2**20:.0f} MiB of rows at a time")


def _print_run(rows: list[dict[str, Any]], n_logs: int, n: int) -> None:
    base, base_tasks = rows[0]["wall"], rows[0]["tasks_wall"]
    print(f"{'workers':>7} {'wall_s':>7} {'samples/s':>10} {'ratio':>6} {'tasks_s':>8} "
          f"{'ratio':>6} {'start_s':>7} {'tail_s':>6} {'peak_rss_MiB/worker':>19} "
          f"{'task_added_MiB':>14} {'task_cpu_u/s':>12} {'parent_cpu':>10} "
          f"{'cluster_cpu':>11} {'tasks/worker':>12} {'load':>5} reader")
    for r in rows:
        print(f"{r['workers']:7d} {r['wall']:7.1f} {n_logs * n * 6 / r['wall']:10.3g} "
              f"{base / r['wall']:6.2f} {r['tasks_wall']:8.1f} "
              f"{base_tasks / r['tasks_wall']:6.2f} {r['startup']:7.2f} {r['tail']:6.2f} "
              f"{r['peak']:19.0f} {r['added']:14.0f} "
              f"{r['task_cpu'][0]:5.2f}/{r['task_cpu'][1]:<6.2f} {r['parent_cpu']:10.2f} "
              f"{r['helpers_cpu']:11.2f} {r['per_worker']:>12} {r['load']:5.1f} "
              f"{r['readers']}")
    for r in rows:
        if r["phases"]:
            print(f"#   {r['workers']} workers, this process per phase (wall/CPU s): " +
                  ", ".join(f"{k} {v['wall_s']:.2f}/{v['cpu_s']:.2f}"
                            for k, v in r["phases"].items()))


if __name__ == "__main__":
    main()
