"""Characterize a fleet of IMU logs on Dask (`gyrodrift fleet`).

One task per log, run by `characterize_log` inside a worker: the worker reads its own log
(a .npy record in chunks of rows: one channel at a time into memory when a channel fits
`FleetOptions.memory_budget_mib`, else spooled to one float64 file per channel that the Allan
code reads in chunks; bounded memory either way), characterizes it and writes
`<out>/units/<name>/result.json` and its plots itself; only the small per-unit summary goes
back through the scheduler. `result.json` is written last (atomic rename), so a unit with it
is done: a resumed run skips it unless `force`, or unless it is stale. Each result stores what
it was computed from (`provenance`): the options that change a result (`result_options`, with
the package version) and a fingerprint of its log (`input_fingerprint`: size, modification
and status-change times, inode and a BLAKE2b hash of the whole file). A resumed run redoes a
unit whose options differ, or whose log differs (by size, or by content when its times or
inode differ), and says which and why. A failed log's one-line reason is written to
`failed.json` beside it and listed in the summary, never dropped.

The fleet summary (`summary.json`, `summary.html`, `boxplot.png`) gives per parameter and axis
the distribution over units (count, min, quartiles, max) and flags units outside a spec file:
JSON ``{"gyroscope_noise_density": {"max": 2e-4}, "gyro_B": {"min": 0, "max": 1e-5}}``, keys
either the Kalibr names (checked on every axis) or ``<sensor>_<term>`` (gyro_N, accel_K, ...).

Examples
--------
>>> unit_name("/data/unit 7/imu.npy", "/data")
'unit_7__imu'
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import re
import sys
import tempfile
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gyrodrift.errors import GyrodriftError, GyrodriftValueError
from gyrodrift.io.atomic import atomic_output, atomic_write_text
from gyrodrift.io.json_text import json_text
from gyrodrift.stability import DEFAULT_IDENTIFIER

__all__ = ["DEFAULT_MEMORY_BUDGET_MIB", "FleetOptions", "characterize_log", "check_spec",
           "input_fingerprint", "load_spec", "result_options", "run_fleet", "unit_name",
           "write_summary"]

PARAMS: tuple[tuple[str, str, str], ...] = (
    ("gyro", "N", "gyroscope_noise_density"), ("gyro", "K", "gyroscope_random_walk"),
    ("gyro", "B", "gyro_bias_instability"), ("accel", "N", "accelerometer_noise_density"),
    ("accel", "K", "accelerometer_random_walk"), ("accel", "B", "accel_bias_instability"),
)


#: A .npy log's channel (float64, 8 bytes per sample) is read into memory when it fits this
#: many MiB (a task then holds one channel at a time: 76 MiB at 1e7 samples), and spooled to
#: a float64 file per channel beyond it (3.4e7 samples: 9.3 h at 1 kHz). 0: always spool.
DEFAULT_MEMORY_BUDGET_MIB = 256.0


@dataclass(frozen=True)
class FleetOptions:
    """What every task does (picklable: sent once per task, small).

    Examples
    --------
    >>> opts = FleetOptions(rate_hz=400.0, terms=("N", "K"))
    >>> opts.method, opts.taus, opts.terms, opts.memory_budget_mib
    ('allan-nnls', 'octave', ('N', 'K'), 256.0)
    """

    rate_hz: float | None = None
    columns: tuple[str, ...] | None = None
    time_column: str | None = None
    time_units: str = "s"
    topic: str | None = None
    gyro_units: str = "rad/s"
    accel_units: str = "m/s^2"
    ci: float = math.erf(1.0 / math.sqrt(2.0))
    taus: str = "octave"
    terms: tuple[str, ...] = ("Q", "N", "B", "K", "R")
    method: str = DEFAULT_IDENTIFIER
    chunk_rows: int = 1 << 18
    plots: bool = True
    memory_budget_mib: float = DEFAULT_MEMORY_BUDGET_MIB

    def __post_init__(self) -> None:
        if not (math.isfinite(self.memory_budget_mib) and self.memory_budget_mib >= 0):
            raise GyrodriftValueError(
                f"memory_budget_mib must be >= 0 and finite, got {self.memory_budget_mib!r}")


#: FleetOptions fields that change how a log is read, not what comes out (the in-memory and
#: the spooled reader give the same numbers): a change of these does not make a result stale.
READING_OPTIONS = frozenset({"chunk_rows", "memory_budget_mib"})


def result_options(opts: FleetOptions) -> dict[str, Any]:
    """Everything that a unit's result depends on besides its log: the options (all fields
    but READING_OPTIONS, tuples as lists) and the package version, as stored with the result
    and compared by a resumed run.

    Examples
    --------
    >>> r = result_options(FleetOptions(rate_hz=400.0, terms=("N", "K")))
    >>> r["rate_hz"], r["terms"], "chunk_rows" in r, "version" in r
    (400.0, ['N', 'K'], False, True)
    """
    from gyrodrift.workflows.characterize import version

    out: dict[str, Any] = {"version": version()}
    for f in dataclasses.fields(opts):
        if f.name not in READING_OPTIONS:
            v = getattr(opts, f.name)
            out[f.name] = list(v) if isinstance(v, tuple) else v
    # Through canonical JSON and back: what a resumed run reads from result.json compares
    # equal to what it computes now.
    loaded: dict[str, Any] = json.loads(json.dumps(out, sort_keys=True))
    return loaded


#: Bytes read per step while hashing a log.
_HASH_BLOCK = 1 << 20


def input_fingerprint(path: str | Path) -> dict[str, Any]:
    """What identifies a log's content: size, st_mtime_ns, st_ctime_ns, inode and the
    BLAKE2b (128-bit) hash of the whole file, streamed in 1 MiB blocks (about 1 s per GB,
    paid once per log by the task that characterizes it; the size and times alone would miss
    a log replaced by one of the same size whose modification time was set back).

    Examples
    --------
    >>> import os, tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = os.path.join(d, "log.npy")
    ...     _ = open(p, "wb").write(b"abc")
    ...     fp = input_fingerprint(p)
    >>> fp["size"], fp["blake2b"][:8]
    (3, 'cf4ab791')
    """
    st = os.stat(path)
    h = hashlib.blake2b(digest_size=16)
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(_HASH_BLOCK), b""):
            h.update(block)
    return {"size": st.st_size, "mtime_ns": st.st_mtime_ns, "ctime_ns": st.st_ctime_ns,
            "inode": st.st_ino, "blake2b": h.hexdigest()}


def _stale_reason(payload: dict[str, Any], path: str, opts: FleetOptions) -> str | None:
    """Why a finished unit's result no longer answers for `path` under `opts` (None: it
    does). The hash is computed only when the size matches but the times or inode do not."""
    prov = payload.get("provenance")
    if not isinstance(prov, dict) or "options" not in prov or "input" not in prov:
        return "no record of its options and input (an older result)"
    now = result_options(opts)
    old = prov["options"]
    if old != now:
        keys = sorted(k for k in set(old) | set(now) if old.get(k) != now.get(k))
        return f"options changed ({', '.join(keys)})"
    fp = prov["input"]
    try:
        st = os.stat(path)
    except OSError:
        return "input missing"
    if st.st_size != fp.get("size"):
        return "input changed (size)"
    if (st.st_mtime_ns, st.st_ctime_ns, st.st_ino) == (
            fp.get("mtime_ns"), fp.get("ctime_ns"), fp.get("inode")):
        return None
    if input_fingerprint(path)["blake2b"] != fp.get("blake2b"):
        return "input changed (content)"
    return None


def unit_name(path: str | Path, root: str | Path | None = None) -> str:
    """A directory name for a log, unique within a fleet: its path relative to `root` with
    separators as '__' and anything but [A-Za-z0-9._-] as '_' (suffix dropped).

    Examples
    --------
    >>> unit_name("/data/bench 7/imu.npy", "/data"), unit_name("/logs/a.b/run.csv")
    ('bench_7__imu', 'run')
    """
    p = Path(path)
    rel = p.relative_to(root) if root is not None and p.is_relative_to(root) else Path(p.name)
    rel = rel.with_suffix("") if rel.suffix else rel
    return re.sub(r"[^A-Za-z0-9._-]", "_", "__".join(rel.parts))


def _status_mib(field: str) -> float | None:
    """A memory line of /proc/self/status (VmRSS, VmHWM) in MiB; None off Linux."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


def _start_peak_window() -> str:
    """Start measuring this task's peak resident memory; returns the scope measured.

    ``ru_maxrss`` is no measure of a task: Linux keeps it across ``execve``, so a worker
    spawned by a process that once held 500 MiB reports >= 500 MiB before it has read a
    byte (and it never falls after an earlier, larger task). On Linux the high-water mark of
    the process's own address space (VmHWM) is reset here (``/proc/self/clear_refs`` "5":
    resets the peak only, no other state) and read when the task ends: "task". Elsewhere
    ``ru_maxrss`` is the fallback: "process" (an upper bound)."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
    except OSError:
        return "process"
    return "task" if _status_mib("VmHWM") is not None else "process"


def _peak_rss_mib(scope: str) -> float:
    import resource

    hwm = _status_mib("VmHWM") if scope == "task" else None
    return hwm if hwm is not None else (
        resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0)


def _thread_cpu() -> tuple[float, float] | None:
    """(user, system) CPU seconds of this thread (the task's: a Dask worker runs it in one
    executor thread, beside its own event-loop threads); None where RUSAGE_THREAD is missing."""
    import resource

    who = getattr(resource, "RUSAGE_THREAD", None)
    if who is None:
        return None
    r = resource.getrusage(who)
    return r.ru_utime, r.ru_stime


def _cpu_since(start: tuple[float, float] | None) -> dict[str, float]:
    """The task's CPU time split, for the benchmark (no result depends on it)."""
    end = _thread_cpu()
    if start is None or end is None:
        return {}
    return {"cpu_user_s": end[0] - start[0], "cpu_sys_s": end[1] - start[1]}


def _start_environ(name: str) -> str | None:
    """A variable of the environment this process started with (/proc/self/environ: what
    glibc's malloc read at start-up; os.environ elsewhere)."""
    try:
        with open("/proc/self/environ", "rb") as fh:
            for item in fh.read().split(b"\0"):
                key, _, value = item.partition(b"=")
                if key == name.encode():
                    return value.decode(errors="replace")
        return None
    except OSError:
        return os.environ.get(name)


def _process_cpu() -> dict[str, float]:
    """CPU seconds (user, system) of this whole process so far: a worker's start-up, imports,
    event loop and tasks (for the benchmark's accounting; no result depends on it)."""
    t = os.times()
    return {"process_cpu_user_s": t.user, "process_cpu_sys_s": t.system}


def characterize_log(path: str, unit_dir: str, opts: FleetOptions) -> dict[str, Any]:
    """The task: characterize one log, write its outputs into unit_dir; return the summary
    (unit, status, kalibr-style parameters per channel). Never raises for a bad log: the
    failure's one-line reason is returned (and written to failed.json).

    Examples
    --------
    One log with three white gyro channels (rad/s) into its unit directory, without plots:

    >>> import os, tempfile, numpy as np
    >>> tmp = tempfile.TemporaryDirectory(); log = os.path.join(tmp.name, "unit1.npy")
    >>> np.save(log, np.random.default_rng(0).normal(0.0, 1e-4, (4096, 3)))
    >>> s = characterize_log(log, os.path.join(tmp.name, "u1"), FleetOptions(rate_hz=100.0,
    ...                                                                      plots=False))
    >>> s["status"], sorted(os.listdir(os.path.join(tmp.name, "u1")))
    ('done', ['imu.yaml', 'result.json'])
    >>> tmp.cleanup()
    """
    t_start = time.time()  # before the first task's imports: all of the task's time
    from gyrodrift.workflows import characterize as ch

    d = Path(unit_dir)
    d.mkdir(parents=True, exist_ok=True)
    (d / "failed.json").unlink(missing_ok=True)
    t_ready = time.time()  # the imports done
    rss_scope = _start_peak_window()
    rss_start = _status_mib("VmRSS")
    cpu_start = _thread_cpu()
    try:
        # Before the log is read: a log replaced while it is read is then seen as changed.
        provenance = {"options": result_options(opts), "input": input_fingerprint(path)}
        res, reader = _characterize_record(path, d, opts)
        if opts.plots:
            ch.write_outputs(res, kalibr=None, kalibr_path=None, html_path=None, out_dir=str(d))
        kal = ch.kalibr_yaml(res)
        atomic_write_text(d / "imu.yaml", kal)
        summary = {"unit": d.name, "path": str(path), "status": "done",
                   "params": _params(res), "record": res.record,
                   "peak_rss_mib": _peak_rss_mib(rss_scope), "rss_start_mib": rss_start,
                   "peak_rss_scope": rss_scope, "reader": reader,
                   **_cpu_since(cpu_start), "t_start": t_start, "t_ready": t_ready,
                   "t_end": time.time(), "pid": os.getpid(), **_process_cpu(),
                   "malloc_trim_threshold": _start_environ("MALLOC_TRIM_THRESHOLD_")}
        payload = {"summary": summary, "result": res.as_dict(), "provenance": provenance}
        atomic_write_text(d / "result.json", json_text(payload, indent=1))
        return summary
    except Exception as exc:
        reason = f"{type(exc).__name__}: {exc}".splitlines()[0]
        info = {"unit": d.name, "path": str(path), "status": "failed", "reason": reason,
                "traceback": traceback.format_exc(limit=4)}
        atomic_write_text(d / "failed.json", json_text(info, indent=1))
        return {k: info[k] for k in ("unit", "path", "status", "reason")}


def _characterize_record(path: str, d: Path, opts: FleetOptions) -> tuple[Any, str]:
    """The analysis of one log and how it was read: "memory" (a .npy log whose channel fits
    opts.memory_budget_mib: one channel at a time in memory), "spool" (a larger .npy log:
    float64 files per channel in a temporary directory under d, read in chunks), or "whole"
    (text, logs, bags: read by load_imu, which parses them in blocks into temporary files
    from 2^20 samples on, outside the fleet's channel budget). "memory" and "spool" give the
    same numbers."""
    from gyrodrift.io.imu_data import NpyChannels, check_reader_options, load_imu
    from gyrodrift.workflows import characterize as ch

    kw: dict[str, Any] = {"ci": opts.ci, "taus": opts.taus, "terms": opts.terms,
                          "method": opts.method, "threads": 1}
    # options the log cannot use are refused, not ignored
    if check_reader_options(path, opts.time_units, opts.time_column, opts.topic) == "npy":
        reader = NpyChannels(path, rate_hz=opts.rate_hz, columns=opts.columns,
                             gyro_units=opts.gyro_units, accel_units=opts.accel_units,
                             chunk_rows=opts.chunk_rows)
        if reader.n * 8 <= opts.memory_budget_mib * 2.0**20:
            return ch.characterize_channels(reader.names, reader.channel, reader.rate_hz,
                                            reader.summary(), **kw), "memory"
        with tempfile.TemporaryDirectory(dir=d, prefix="spool.") as spool:
            rec = reader.spool(spool)
            res = ch.characterize(rec, **kw)
            del rec
        return res, "spool"
    rec = load_imu(path, rate_hz=opts.rate_hz, columns=opts.columns,
                   time_column=opts.time_column, time_units=opts.time_units, topic=opts.topic,
                   gyro_units=opts.gyro_units, accel_units=opts.accel_units)
    return ch.characterize(rec, **kw), "whole"


def _params(res: Any) -> dict[str, dict[str, dict[str, float]]]:
    """parameter name -> channel -> {value, ci_low, ci_high} (SI units)."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for sensor, term, key in PARAMS:
        for c in res.channels:
            if c.sensor == sensor and term in c.terms:
                t = c.terms[term]
                out.setdefault(key, {})[c.channel] = {"value": t.value, "ci_low": t.ci_low,
                                                      "ci_high": t.ci_high, "unit": t.unit}
    return out


def load_spec(path: str | Path) -> dict[str, dict[str, float]]:
    """A spec file: JSON {parameter: {"min": x, "max": y}} (module docstring).

    Examples
    --------
    A spec file with an upper limit on the gyro noise density:

    >>> import tempfile
    >>> import os
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = os.path.join(d, "spec.json")
    ...     with open(path, "w") as fh:
    ...         _ = fh.write('{"gyroscope_noise_density": {"max": 2e-4}}')
    ...     print(load_spec(path))
    {'gyroscope_noise_density': {'max': 0.0002}}
    """
    try:
        spec = json.loads(Path(path).read_text())
    except json.JSONDecodeError as exc:
        raise GyrodriftValueError(f"{path}: not JSON: {exc}") from exc
    except UnicodeDecodeError as exc:
        raise GyrodriftValueError(f"{path}: not JSON: not UTF-8 text") from exc
    return check_spec(spec, str(path))


def check_spec(spec: Any, source: str = "spec") -> dict[str, dict[str, float]]:
    """`spec` if it is a valid spec, else a GyrodriftValueError naming `source` and the first
    fault: an unknown parameter, a limit other than "min"/"max", a limit that is not a finite
    number (a string, a boolean, NaN, inf), or min > max. Checked before any work.

    Examples
    --------
    >>> check_spec({"gyro_N": {"min": 0, "max": 2e-4}})
    {'gyro_N': {'min': 0, 'max': 0.0002}}
    >>> check_spec({"gyro_N": {"max": "1e-4"}}, "spec.json")
    Traceback (most recent call last):
    ...
    gyrodrift.errors.GyrodriftValueError: spec.json: gyro_N: max must be a finite number, got '1e-4'
    """
    names = {k for _, _, k in PARAMS} | {f"{s}_{t}" for s, t, _ in PARAMS}
    if not isinstance(spec, dict):
        raise GyrodriftValueError(f"{source}: expected an object of parameter limits")
    for k, lim in spec.items():
        if k not in names:
            raise GyrodriftValueError(
                f"{source}: unknown parameter {k!r}; use one of {sorted(names)}")
        if not isinstance(lim, dict) or not set(lim) <= {"min", "max"} or not lim:
            raise GyrodriftValueError(
                f"{source}: {k}: give limits as {{\"min\": x, \"max\": y}}")
        for side, v in lim.items():
            if (isinstance(v, bool) or not isinstance(v, (int, float))
                    or not math.isfinite(v)):
                raise GyrodriftValueError(
                    f"{source}: {k}: {side} must be a finite number, got {v!r}")
        if "min" in lim and "max" in lim and lim["min"] > lim["max"]:
            raise GyrodriftValueError(
                f"{source}: {k}: min {lim['min']!r} is above max {lim['max']!r}")
    return spec


def _spec_key(key: str) -> str:
    for s, t, k in PARAMS:
        if k == key:
            return f"{s}_{t}"
    return key


def run_fleet(paths: Sequence[str | Path], out_dir: str | Path, *, opts: FleetOptions,
              workers: int = 2, scheduler: str | None = None, force: bool = False,
              spec: dict[str, dict[str, float]] | None = None, root: str | Path | None = None,
              progress: bool = False, client: Any = None,
              on_result: Callable[[dict[str, Any]], None] | None = None,
              phases: dict[str, dict[str, float]] | None = None) -> dict[str, Any]:
    """Characterize every log on Dask and write the fleet summary (module docstring).

    workers = 0 runs serially in this process (no Dask; the reference the Dask run equals).
    scheduler: address of an existing dask.distributed scheduler; else a LocalCluster of
    `workers` processes (one thread each) on 127.0.0.1 is started and closed. `client`: an
    existing distributed.Client to use instead (tests share one).
    The LocalCluster's worker processes import the main script again when they start (as
    every spawned or forkserver process does): a script calls run_fleet with workers >= 1
    under ``if __name__ == "__main__":``; called at a script's top level without it, it
    raises GyrodriftError before any worker starts.
    A finished unit is skipped unless `force` or stale (module docstring); the returned
    summary counts the skipped (n_skipped), the run (n_run) and, among these, the stale ones
    redone with their reason (n_redone, redone: [{unit, path, reason}]).
    Returns the summary dict (also written to out_dir/summary.json). `phases`, if given, is
    filled with this process's cost per phase (plan, cluster_start, submit, tasks, summary,
    close: what remains of the close after the summary, which it overlaps): {"wall_s",
    "cpu_s" (all its threads: client, and a LocalCluster's scheduler and nannies),
    "main_cpu_s" (the calling thread)}; no result depends on it.

    Examples
    --------
    A fleet of two copies of one log, run in this process (workers=0: no Dask):

    >>> import os, shutil, tempfile, numpy as np
    >>> d = tempfile.mkdtemp()
    >>> logs = [os.path.join(d, f"unit{k}.npy") for k in (1, 2)]
    >>> for log in logs:
    ...     np.save(log, np.random.default_rng(0).normal(0.0, 1e-4, (4096, 3)))
    >>> s = run_fleet(logs, os.path.join(d, "out"), opts=FleetOptions(rate_hz=100.0), workers=0)
    >>> s["n_done"], s["n_failed"], sorted(os.listdir(os.path.join(d, "out")))
    (2, 0, ['boxplot.png', 'summary.html', 'summary.json', 'units'])
    >>> shutil.rmtree(d)
    """
    lap = _Laps(phases)
    out = Path(out_dir)
    (out / "units").mkdir(parents=True, exist_ok=True)
    path_strs = [str(p) for p in paths]
    if not path_strs:
        raise GyrodriftValueError("no logs to characterize")
    names = [unit_name(p, root) for p in path_strs]
    if len(set(names)) != len(names):
        raise GyrodriftValueError("two logs map to the same unit name; pass a common root")
    if spec is not None:
        check_spec(spec)
    results: dict[str, dict[str, Any]] = {}
    todo: list[tuple[str, str]] = []
    redone: list[dict[str, str]] = []
    for p, n in zip(path_strs, names, strict=True):
        done = out / "units" / n / "result.json"
        if done.is_file() and not force:
            try:
                payload = json.loads(done.read_text())
                why = _stale_reason(payload, p, opts)
                if why is None:
                    results[n] = {**payload["summary"], "skipped": True}
                    continue
                redone.append({"unit": n, "path": p, "reason": why})
            except (json.JSONDecodeError, KeyError, TypeError, AttributeError):
                redone.append({"unit": n, "path": p, "reason": "result damaged"})
        todo.append((p, n))

    def record(r: dict[str, Any]) -> None:
        results[r["unit"]] = r
        if on_result is not None:
            on_result(r)

    lap("plan")
    close: Callable[[], None] | None = None
    if todo and workers == 0 and scheduler is None and client is None:
        from tqdm import tqdm

        for p, n in tqdm(todo, disable=not progress, desc="fleet", unit="log"):
            record(characterize_log(p, str(out / "units" / n), opts))
        lap("tasks")
    elif todo:
        # The summary's libraries load here while the workers run, not after the last task
        # (about 1 s of the parent's time that would otherwise end every run serially).
        import threading

        threading.Thread(target=_import_summary_libraries, daemon=True).start()
        close = _run_dask(todo, out, opts, workers, scheduler, progress, client, record, lap)
    ordered = [results[n] for n in names]
    # Every result is written: the cluster (if this run started one) closes while the summary
    # is written, and is closed before this returns.
    closing = _InThread(close)
    try:
        summary = write_summary(ordered, out, spec)
        lap("summary")
    finally:
        closing.join()
        lap("close")
    summary["n_skipped"] = sum(1 for r in ordered if r.get("skipped"))
    summary["n_run"] = len(todo)
    summary["n_redone"] = len(redone)
    summary["redone"] = redone
    return summary


#: Environment variables the fleet's own LocalCluster does not set in its workers, although
#: dask.distributed's nanny does by default (config distributed.nanny.pre-spawn-environ).
#: MALLOC_TRIM_THRESHOLD_ turns off glibc's adaptive mmap threshold: every allocation above
#: 128 KiB becomes a fresh mapping whose pages fault in again, and the chunked Allan reads of
#: a spooled log then cost 1.2 million minor faults and 4 s of system time per 1e7 samples
#: (2 s of user time), the two workers contending in the kernel's page allocator.
UNSET_WORKER_ENV = ("MALLOC_TRIM_THRESHOLD_",)


#: What the forkserver of the fleet's own LocalCluster imports once before forking the workers.
#: Not "__main__": a forked worker runs the parent's main script again (as a spawned one
#: does; cheap when its imports are these), and a forkserver that imported it itself would
#: run an unguarded one, such as `python -m gyrodrift`'s, in the server.
WORKER_PRELOAD = ("distributed", "gyrodrift.workflows._fleet_worker")


def _worker_environment() -> dict[str, str]:
    """The variables a spawned worker would get from its nanny before it starts
    (distributed.nanny.pre-spawn-environ, this process's values first, PYTHONHASHSEED 6640 as
    the nanny sets it), without UNSET_WORKER_ENV."""
    import dask

    cfg = dask.config.get("distributed.nanny.pre-spawn-environ")
    env = {k: os.environ.get(k, str(v)) for k, v in cfg.items()
           if v is not None and k not in UNSET_WORKER_ENV}
    if env.get("PYTHONHASHSEED") in (None, "0"):
        env["PYTHONHASHSEED"] = "6640"
    return env


def _start_forkserver() -> None:
    """Start (if not yet running) the forkserver that the fleet's own workers are forked from,
    importing WORKER_PRELOAD once, with _worker_environment() and without UNSET_WORKER_ENV in
    its environment (which forked workers inherit: the nanny's pre-spawn variables do not
    reach a forked process). It returns at once: the server imports in its own process while
    this one goes on (scheduler, nannies); the nannies' fork requests wait for it. It serves
    this process until it exits; a forkserver that is already running (an earlier fleet run
    in this process) is reused as it is."""
    import multiprocessing
    from multiprocessing import forkserver

    multiprocessing.get_context("forkserver").set_forkserver_preload(list(WORKER_PRELOAD))
    env = _worker_environment()
    saved = {k: os.environ.get(k) for k in (*env, *UNSET_WORKER_ENV)}
    for k in UNSET_WORKER_ENV:
        os.environ.pop(k, None)
    os.environ.update(env)
    try:
        forkserver.ensure_running()
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _main_script_rerun_by_workers() -> str | None:
    """The file of the main module when the worker processes of a LocalCluster would run it
    again, else None.

    A worker process started by ``spawn`` or ``forkserver`` (what dask.distributed's nanny
    uses) first imports the parent's main module as ``__mp_main__``: a script given by its
    path (``python script.py``) or a module run with ``python -m module`` (not a package's
    ``__main__``). Interactive sessions, ``python -c`` and notebooks have no such file."""
    main = sys.modules.get("__main__")
    if main is None:
        return None
    spec_name = getattr(getattr(main, "__spec__", None), "name", None)
    if spec_name is not None:
        if spec_name == "__main__" or spec_name.endswith(".__main__"):
            return None
        origin = getattr(main.__spec__, "origin", None)
        return origin if isinstance(origin, str) else None
    path = getattr(main, "__file__", None)
    return path if isinstance(path, str) else None


def _is_main_guard(test: Any) -> bool:
    """Whether an ``if`` test is ``__name__ == "__main__"`` (either order)."""
    import ast

    if not (isinstance(test, ast.Compare) and len(test.ops) == 1
            and isinstance(test.ops[0], ast.Eq)):
        return False
    sides = [test.left, test.comparators[0]]
    return (any(isinstance(e, ast.Name) and e.id == "__name__" for e in sides)
            and any(isinstance(e, ast.Constant) and e.value == "__main__" for e in sides))


def _unguarded_main_line() -> tuple[str, int] | None:
    """(file, line) of the main script's top-level statement that led to this call when that
    statement is not under ``if __name__ == "__main__":``, else None.

    A worker process of the fleet's own LocalCluster runs such a script again from the top
    (_main_script_rerun_by_workers): it would start a cluster of its own while it starts, which
    multiprocessing refuses, and the nanny reports only that the worker failed to start."""
    import ast

    path = _main_script_rerun_by_workers()
    if path is None:
        return None
    main_globals = sys.modules["__main__"].__dict__
    frame: Any = sys._getframe(1)
    while frame is not None and not (frame.f_globals is main_globals
                                     and frame.f_code.co_name == "<module>"):
        frame = frame.f_back
    if frame is None:  # not called from the script's top level (a thread, a callback)
        return None
    line = frame.f_lineno
    try:
        tree = ast.parse(Path(path).read_text(), path)
    except (OSError, SyntaxError, ValueError):
        return None
    for node in tree.body:
        end = getattr(node, "end_lineno", None) or node.lineno
        if node.lineno <= line <= end:
            guarded = isinstance(node, ast.If) and _is_main_guard(node.test)
            return None if guarded else (path, line)
    return None


def _local_cluster(workers: int) -> Any:
    """A LocalCluster of `workers` processes (one thread each) on 127.0.0.1, no dashboard (the
    scheduler's HTTP endpoint for health and metrics listens on a free 127.0.0.1 port),
    workers forked from the fleet's forkserver (_start_forkserver: imports done once, not per
    worker; a forked worker also exits without the interpreter's teardown of
    those modules, which took a spawned one 1 s at the cluster's close) and without
    UNSET_WORKER_ENV, without the workers' statistical profiler (a stack sample every
    10 ms for a dashboard that this cluster does not have), and with its servers' event-loop
    tick every 1 s instead of 20 ms.

    The nanny writes its variables into this process's os.environ before starting a worker
    (so any earlier default LocalCluster in the process has left MALLOC_TRIM_THRESHOLD_ there)
    and prefers os.environ over its configuration: the variables are taken out of both while
    the workers are started, and os.environ is restored afterwards."""
    import dask
    from distributed import LocalCluster

    cfg: dict[str, Any] = {f"distributed.nanny.pre-spawn-environ.{k}": None
                           for k in UNSET_WORKER_ENV}
    cfg["distributed.worker.multiprocessing-method"] = "forkserver"
    cfg["distributed.worker.profile.enabled"] = False
    # Every server (scheduler, nannies, workers) times its event loop every tick (20 ms by
    # default) to warn when it was blocked for seconds (tick.limit, 3 s): 1 s detects the same.
    # Measured idle, 2 workers, 8 s: this process 0.28 -> 0.15 s CPU, each worker 0.17 ->
    # 0.05 s; CPU the tasks get back on a machine with as many cores as workers.
    cfg["distributed.admin.tick.interval"] = "1s"
    _start_forkserver()
    saved = {k: os.environ.pop(k) for k in UNSET_WORKER_ENV if k in os.environ}
    try:
        with dask.config.set(cfg):
            # The scheduler's HTTP endpoint (health, metrics; no dashboard) on a free loopback
            # port: its default 8787 is taken by any other cluster on the machine, and dask
            # then warns and takes a free port anyway.
            return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                host="127.0.0.1", dashboard_address=None,
                                scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
    finally:
        os.environ.update(saved)


def _import_summary_libraries() -> None:
    import jinja2  # noqa: F401  (fleet_html imports it at its first call: 0.05-0.07 s)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot

    import gyrodrift.report.html  # noqa: F401


class _Laps:
    """Wall and CPU time of this process per phase of a run, into `phases` (or nothing)."""

    def __init__(self, phases: dict[str, dict[str, float]] | None) -> None:
        self.phases = phases
        self.last = self._now()

    @staticmethod
    def _now() -> tuple[float, float, float]:
        return time.perf_counter(), time.process_time(), time.thread_time()

    def __call__(self, name: str) -> None:
        if self.phases is None:
            return
        now = self._now()
        self.phases[name] = {"wall_s": now[0] - self.last[0], "cpu_s": now[1] - self.last[1],
                             "main_cpu_s": now[2] - self.last[2]}
        self.last = now


def _run_dask(todo: list[tuple[str, str]], out: Path, opts: FleetOptions, workers: int,
              scheduler: str | None, progress: bool, client: Any,
              record: Callable[[dict[str, Any]], None],
              lap: _Laps) -> Callable[[], None] | None:
    """Run the tasks; returns how to close the client and cluster this call opened (None
    when the caller's client is used), or closes them itself on an error."""
    from distributed import Client, as_completed
    from tqdm import tqdm

    cluster = None
    own_client = client is None
    if client is None:
        if scheduler is None:
            if workers < 1:
                raise GyrodriftValueError(f"workers must be >= 1, got {workers}")
            unguarded = _unguarded_main_line()
            if unguarded is not None:
                raise GyrodriftError(
                    f"{unguarded[0]}, line {unguarded[1]}: run_fleet with workers >= 1 starts "
                    "worker processes that run the main script again; put the script's work "
                    "under 'if __name__ == \"__main__\":' (or pass scheduler= or client=)")
            cluster = _local_cluster(workers)
            client = Client(cluster)
        else:
            client = Client(scheduler)
    lap("cluster_start")
    try:
        futures = {client.submit(characterize_log, p, str(out / "units" / n), opts, pure=False,
                                 key=f"characterize-{n}"): (p, n) for p, n in todo}
        lap("submit")
        with tqdm(total=len(futures), disable=not progress, desc="fleet", unit="log") as bar:
            for fut in as_completed(futures):
                p, n = futures[fut]
                try:
                    r = fut.result()
                except Exception as exc:
                    reason = f"{type(exc).__name__}: {exc}".splitlines()[0]
                    r = {"unit": n, "path": p, "status": "failed", "reason": reason}
                    d = out / "units" / n
                    d.mkdir(parents=True, exist_ok=True)
                    atomic_write_text(d / "failed.json", json_text(r, indent=1))
                record(r)
                bar.update(1)
        lap("tasks")
    except BaseException:
        if own_client:
            _close(client, cluster)
        raise
    return (lambda: _close(client, cluster)) if own_client else None


def _silence_distributed_logging() -> None:
    """Run in each worker of the fleet's own cluster once every result is in, before the
    cluster closes: a worker that is still sending its periodic heartbeat when the scheduler
    shuts down logs the closed connection (CommClosedError) with a traceback, on the
    command's stderr. That race is part of every close, not a fault of the run: the
    workers' distributed loggers report only critical records from here on."""
    import logging

    for log in _distributed_loggers():
        log.setLevel(logging.CRITICAL)


def _distributed_loggers() -> list[Any]:
    """The "distributed" logger and those below it that exist (some carry their own level)."""
    import logging

    names = [n for n in list(logging.root.manager.loggerDict)
             if n == "distributed" or n.startswith("distributed.")]
    return [logging.getLogger(n) for n in ("distributed", *names)]


def _close(client: Any, cluster: Any) -> None:
    """Close the client, then the cluster this run started (if any): its workers told first to
    keep shutdown races off stderr (_silence_distributed_logging), and this process's
    scheduler and nannies likewise while the cluster closes. An exception still propagates."""
    import contextlib
    import logging

    if cluster is None:
        client.close()
        return
    with contextlib.suppress(Exception):  # a worker already gone needs no telling
        client.run(_silence_distributed_logging)
    levels = [(log, log.level) for log in _distributed_loggers()]
    for log, _ in levels:
        log.setLevel(logging.CRITICAL)
    try:
        client.close()
        cluster.close()
    finally:
        for log, level in levels:
            log.setLevel(level)


class _InThread:
    """Run `fn` (if any) in a thread now; join() waits for it and raises what it raised."""

    def __init__(self, fn: Callable[[], None] | None) -> None:
        import threading

        self.error: BaseException | None = None
        self.thread = None
        if fn is not None:
            def run() -> None:
                try:
                    fn()
                except BaseException as exc:  # handed to join()
                    self.error = exc

            self.thread = threading.Thread(target=run, name="gyrodrift-fleet-close")
            self.thread.start()

    def join(self) -> None:
        if self.thread is not None:
            self.thread.join()
        if self.error is not None:
            raise self.error


def _quantiles(v: np.ndarray) -> dict[str, float]:
    q = np.quantile(v, [0.0, 0.25, 0.5, 0.75, 1.0])
    return {"n": int(v.size), "min": float(q[0]), "q1": float(q[1]), "median": float(q[2]),
            "q3": float(q[3]), "max": float(q[4]), "mean": float(v.mean())}


def write_summary(units: Sequence[dict[str, Any]], out: Path,
                  spec: dict[str, dict[str, float]] | None) -> dict[str, Any]:
    """summary.json, boxplot.png and summary.html of the fleet (module docstring).

    Examples
    --------
    The summary of a fleet whose one unit failed:

    >>> import tempfile
    >>> import os
    >>> from pathlib import Path
    >>> with tempfile.TemporaryDirectory() as d:
    ...     s = write_summary([{"unit": "u1", "path": "u1.npy", "status": "failed",
    ...                         "reason": "no data"}], Path(d), None)
    ...     print(s["n_done"], s["n_failed"], sorted(os.listdir(d)))
    0 1 ['summary.html', 'summary.json']
    """
    from gyrodrift.report.html import fleet_html
    from gyrodrift.workflows.characterize import png_data_uri, version

    done = [u for u in units if u["status"] == "done"]
    failed = [{"unit": u["unit"], "path": u["path"], "reason": u["reason"]}
              for u in units if u["status"] != "done"]
    dist: dict[str, dict[str, dict[str, float]]] = {}
    series: dict[tuple[str, str], list[float]] = {}
    for u in done:
        for key, per in u["params"].items():
            for chan, t in per.items():
                series.setdefault((key, chan), []).append(float(t["value"]))
    for (key, chan), vals in series.items():
        dist.setdefault(key, {})[chan] = _quantiles(np.asarray(vals))
    flagged = []
    for u in done:
        for key, per in u["params"].items():
            for k in (key, _spec_key(key)):
                lim = (spec or {}).get(k)
                if not lim:
                    continue
                for chan, t in per.items():
                    v = float(t["value"])
                    if "max" in lim and v > lim["max"]:
                        flagged.append({"unit": u["unit"], "parameter": k, "channel": chan,
                                        "value": v, "limit": f"max {lim['max']:g}"})
                    if "min" in lim and v < lim["min"]:
                        flagged.append({"unit": u["unit"], "parameter": k, "channel": chan,
                                        "value": v, "limit": f"min {lim['min']:g}"})
    summary = {"version": version(), "n_units": len(units), "n_done": len(done),
               "n_failed": len(failed), "failed": failed, "flagged": flagged,
               "warnings": _warnings(done),
               "distribution": dist,
               "units": [{"unit": u["unit"], "path": u["path"], "status": u["status"]}
                         for u in units]}
    images = []
    if series:
        png = _boxplot(series)
        with atomic_output(out / "boxplot.png") as tmp:
            tmp.write_bytes(png)
        images.append(("Distribution over units per parameter and axis", png_data_uri(png)))
    atomic_write_text(out / "summary.json", json_text(summary, indent=1))
    dist_head = ["parameter", "channel", "unit", "n", "min", "q1", "median", "q3", "max"]
    units_si = {}
    for u in done:
        for key, per in u["params"].items():
            for t in per.values():
                units_si[key] = t["unit"]
    dist_rows = [[key, chan, units_si.get(key, ""), d["n"]] + [f"{d[s]:.4g}" for s in
                                                               ("min", "q1", "median", "q3",
                                                                "max")]
                 for key, per in dist.items() for chan, d in per.items()]
    flagged_units = {f["unit"] for f in flagged}
    page = fleet_html(
        version=version(), n_done=len(done), n_failed=len(failed), n_flagged=len(flagged_units),
        spec_name="spec" if spec else "", dist_head=dist_head, dist_rows=dist_rows,
        images=images, flagged=flagged, failed=failed,
        units=[{"name": u["unit"], "status": u["status"],
                "link": f"units/{u['unit']}/result.json" if u["status"] == "done" else
                f"units/{u['unit']}/failed.json"} for u in units])
    atomic_write_text(out / "summary.html", page)
    return summary


def _warnings(done: Sequence[dict[str, Any]]) -> list[str]:
    """What the user should know about how the units ran (not about their results): spooled
    logs characterized by workers started with MALLOC_TRIM_THRESHOLD_ (dask's nanny sets it
    in workers that the fleet does not start itself, `--scheduler`)."""
    slow = sorted(u["unit"] for u in done
                  if u.get("reader") == "spool" and u.get("malloc_trim_threshold"))
    if not slow:
        return []
    return [f"{len(slow)} spooled log(s) ({', '.join(slow[:3])}{', ...' if len(slow) > 3 else ''})"
            " ran in workers started with MALLOC_TRIM_THRESHOLD_ (dask's nanny default): each "
            "costs about 4 s of system time per 1e7 samples in page faults; start the workers "
            "with distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_ set to null, or "
            "raise --memory-budget-mib (documentation: validation, characterization and fleets)"]


def _boxplot(series: dict[tuple[str, str], list[float]]) -> bytes:
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = sorted({k for k, _ in series}, key=lambda k: [p[2] for p in PARAMS].index(k))
    fig, axes = plt.subplots(1, len(keys), figsize=(3.0 * len(keys), 4.2), dpi=90,
                             squeeze=False)
    for ax, key in zip(axes[0], keys, strict=True):
        chans = sorted(c for k, c in series if k == key)
        ax.boxplot([series[(key, c)] for c in chans])
        ax.set_xticks(range(1, len(chans) + 1), [c.split("_")[1] for c in chans])
        ax.set_title(key.replace("_", " "), fontsize=8)
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 3))
        ax.grid(True, alpha=0.3)
    fig.subplots_adjust(left=0.06, right=0.98, bottom=0.08, top=0.9, wspace=0.45)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()
