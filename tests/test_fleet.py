"""`gyrodrift fleet` on a dask.distributed LocalCluster (2 worker processes, loopback, one
cluster for the module): equal to the serial run, a corrupt log reported as failed, a resumed
run doing no work for finished logs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.workflows.fleet import FleetOptions, load_spec, run_fleet

#: The logs' units (rad/s, m/s^2), stated: a .npy record does not carry them.
UNITS = ("--gyro-units", "rad/s", "--accel-units", "m/s^2")


@pytest.fixture(scope="module")
def client():
    import distributed  # a runtime dependency: a missing one must fail, not skip
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    d = tmp_path_factory.mktemp("logs")
    rng = np.random.default_rng(9)
    paths = []
    for i in range(5):
        scale = np.array([1e-3, 1e-3, 1e-3, 1e-2, 1e-2, 1e-2]) * (1.0 + 0.2 * i)
        x = rng.standard_normal((6000, 6)) * scale + np.cumsum(
            rng.standard_normal((6000, 6)) * scale * 1e-2, axis=0)
        paths.append(d / f"unit{i}.npy")
        np.save(paths[-1], x)
    bad = d / "unit5.npy"
    np.save(bad, np.zeros((6000, 6)))
    bad.write_bytes(bad.read_bytes()[:2000])  # truncated: header says 6000 rows
    paths.append(bad)
    return paths


OPTS = FleetOptions(rate_hz=100.0, plots=True)
NO_PLOTS = FleetOptions(rate_hz=100.0, plots=False)


def _results(out: Path) -> dict[str, dict]:
    return {p.parent.name: json.loads(p.read_text())["result"]
            for p in sorted((out / "units").glob("*/result.json"))}


@pytest.mark.xdist_group("fleet_cluster")
def test_fleet_on_two_workers_equals_serial(client, logs: list[Path], tmp_path: Path) -> None:
    seen: list[str] = []
    dask_sum = run_fleet(logs, tmp_path / "dask", opts=OPTS, client=client,
                         root=logs[0].parent, on_result=lambda r: seen.append(r["unit"]))
    serial_sum = run_fleet(logs, tmp_path / "serial", opts=NO_PLOTS, workers=0,
                           root=logs[0].parent)
    assert sorted(seen) == [f"unit{i}" for i in range(6)]
    for s in (dask_sum, serial_sum):
        assert s["n_done"] == 5 and s["n_failed"] == 1
        assert s["failed"][0]["unit"] == "unit5"
        assert "\n" not in s["failed"][0]["reason"] and s["failed"][0]["reason"]
    dask_res, serial_res = _results(tmp_path / "dask"), _results(tmp_path / "serial")
    assert sorted(dask_res) == [f"unit{i}" for i in range(5)]
    assert dask_res == serial_res  # exact equality of every number
    assert dask_sum["distribution"] == serial_sum["distribution"]
    for i in range(5):
        unit = tmp_path / "dask" / "units" / f"unit{i}"
        assert (unit / "gyro.png").stat().st_size > 1000
        assert (unit / "imu.yaml").is_file()
    failed = json.loads((tmp_path / "dask" / "units" / "unit5" / "failed.json").read_text())
    assert failed["status"] == "failed"
    html = (tmp_path / "dask" / "summary.html").read_text()
    assert "unit5" in html and "data:image/png;base64," in html


@pytest.mark.xdist_group("fleet_cluster")
def test_resumed_run_skips_finished_logs(client, logs: list[Path], tmp_path: Path) -> None:
    out = tmp_path / "out"
    first = run_fleet(logs, out, opts=NO_PLOTS, client=client, root=logs[0].parent)
    assert first["n_run"] == 6
    stamps = {p: p.stat().st_mtime_ns for p in (out / "units").glob("*/result.json")}
    submitted: list[str] = []
    again = run_fleet(logs, out, opts=NO_PLOTS, client=client, root=logs[0].parent,
                      on_result=lambda r: submitted.append(r["unit"]))
    # Only the failed log is tried again; no finished log is redone or rewritten.
    assert submitted == ["unit5"]
    assert again["n_run"] == 1 and again["n_skipped"] == 5 and again["n_done"] == 5
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps
    forced = run_fleet(logs[:2], out, opts=NO_PLOTS, workers=0, root=logs[0].parent, force=True)
    assert forced["n_run"] == 2


def test_spec_flags_units_outside_limits(logs: list[Path], tmp_path: Path) -> None:
    spec_path = tmp_path / "spec.json"
    # unit0 has the smallest noise (scale 1.0); units 1-4 are 1.2-1.8 times noisier.
    spec_path.write_text(json.dumps({"gyroscope_noise_density": {"max": 1.1e-4}}))
    out = tmp_path / "out"
    s = run_fleet(logs[:3], out, opts=NO_PLOTS, workers=0, root=logs[0].parent,
                  spec=load_spec(spec_path))
    flagged_units = {f["unit"] for f in s["flagged"]}
    assert flagged_units == {"unit1", "unit2"}
    assert "unit1" in (out / "summary.html").read_text()
    spec_path.write_text(json.dumps({"gyro_noise": {"max": 1}}))
    with pytest.raises(ValueError, match="unknown parameter"):
        load_spec(spec_path)


@pytest.mark.xdist_group("fleet_cluster")
def test_cli_on_an_existing_scheduler(client, logs: list[Path], tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    from gyrodrift.cli import main

    code = main(["fleet", str(logs[0].parent / "unit[05].npy"), "--out-dir",
                 str(tmp_path / "out"), "--rate-hz", "100", "--scheduler",
                 client.scheduler.address, "--progress", "never", *UNITS])
    assert code == 1  # one failed log
    out = capsys.readouterr().out
    assert "1 done" in out and "1 failed" in out
    assert "failed: " in out and "unit5.npy" in out
    assert (tmp_path / "out" / "units" / "unit0" / "result.json").is_file()



@pytest.mark.xdist_group("fleet_cluster")
def test_existing_scheduler_workers_with_malloc_trim_threshold_are_reported(
        client, logs: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Workers the fleet does not start (`--scheduler`; here the module's default
    LocalCluster, whose nanny sets MALLOC_TRIM_THRESHOLD_=65536 as `dask worker` does) make a
    spooled log cost ~4 s of system time per 1e7 samples: the run says so (stderr and
    summary.json's warnings), naming the units; logs read into memory are not affected and
    give no warning."""
    from gyrodrift.cli import main

    seen = client.run(lambda: b"MALLOC_TRIM_THRESHOLD_=65536" in open(
        "/proc/self/environ", "rb").read().split(b"\0"))
    assert all(seen.values())  # the premise: dask's default nanny environment
    base = ["fleet", str(logs[0].parent / "unit[01].npy"), "--rate-hz", "100", "--scheduler",
            client.scheduler.address, "--progress", "never", *UNITS]
    assert main([*base, "--out-dir", str(tmp_path / "spool"), "--memory-budget-mib", "0"]) == 0
    err = capsys.readouterr().err
    assert "warning: 2 spooled log(s) (unit0, unit1) ran in workers started with " \
        "MALLOC_TRIM_THRESHOLD_" in err
    summary = json.loads((tmp_path / "spool" / "summary.json").read_text())
    assert len(summary["warnings"]) == 1 and "unit0, unit1" in summary["warnings"][0]
    assert main([*base, "--out-dir", str(tmp_path / "mem")]) == 0
    assert "warning" not in capsys.readouterr().err
    assert json.loads((tmp_path / "mem" / "summary.json").read_text())["warnings"] == []

@pytest.mark.parametrize("taus", ["octave", "decade"])
def test_in_memory_reader_equals_the_spool(logs: list[Path], tmp_path: Path, taus: str) -> None:
    """A log whose channel fits the memory budget (one channel at a time in memory, the
    in-memory Allan kernel) gives exactly the numbers of the spooled path (budget 0: float64
    files read back in chunks), which was the only path before: every result, every number.
    The corrupt log fails with the same reason either way."""
    from gyrodrift.workflows.fleet import characterize_log

    for log in logs:
        got = {}
        for budget in (0.0, 64.0):
            opts = FleetOptions(rate_hz=100.0, plots=False, taus=taus, memory_budget_mib=budget)
            unit = tmp_path / f"b{budget:g}" / log.stem
            s = characterize_log(str(log), str(unit), opts)
            if s["status"] == "done":
                assert s["reader"] == ("spool" if budget == 0 else "memory")
                got[budget] = json.loads((unit / "result.json").read_text())["result"]
            else:
                got[budget] = s["reason"]
            assert not list(unit.glob("spool.*"))  # the spool directory is removed
        assert got[0.0] == got[64.0], log.name
    assert isinstance(got[0.0], str) and "unit5" in logs[-1].name


def test_in_memory_reader_equals_the_spool_beyond_one_allan_chunk(tmp_path: Path) -> None:
    """Longer than the Allan code's file chunk (2^20 samples), where the spooled path sums
    each tau's averages across chunk boundaries: still the same numbers, octave and decade
    taus (three float32 gyro channels of 1.2e6 samples, white noise plus a random walk)."""
    from gyrodrift.workflows.fleet import characterize_log

    rng = np.random.default_rng(21)
    n = 1_200_000
    x = (rng.standard_normal((n, 3)) * 2e-3 + np.cumsum(rng.standard_normal((n, 3)) * 1e-6,
                                                         axis=0)).astype(np.float32)
    np.save(tmp_path / "long.npy", x)
    for taus in ("octave", "decade"):
        got = []
        for budget in (0.0, 64.0):
            opts = FleetOptions(rate_hz=200.0, plots=False, taus=taus, memory_budget_mib=budget)
            unit = tmp_path / f"{taus}{budget:g}"
            assert characterize_log(str(tmp_path / "long.npy"), str(unit), opts)["status"] == \
                "done"
            got.append(json.loads((unit / "result.json").read_text())["result"])
        assert got[0] == got[1], taus


def test_memory_budget_is_checked() -> None:
    with pytest.raises(ValueError, match="memory_budget_mib"):
        FleetOptions(rate_hz=100.0, memory_budget_mib=-1.0)
    with pytest.raises(ValueError, match="memory_budget_mib"):
        FleetOptions(rate_hz=100.0, memory_budget_mib=float("nan"))


def test_own_cluster_spawns_workers_without_malloc_trim_threshold(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """dask.distributed's nanny sets MALLOC_TRIM_THRESHOLD_=65536 in its workers, which
    turns off glibc's adaptive mmap threshold: the spooled path's chunk reads then fault in
    1.2 million pages per 1e7-sample log (4 s of system time against 2 s of user time, and
    the two workers contend in the kernel). The fleet's own LocalCluster leaves it unset,
    also when an earlier default cluster has written it into this process's environment
    (the nanny does that, and then prefers it to its configuration); the environment is
    given back afterwards."""
    import os

    from distributed import Client
    from gyrodrift.workflows.fleet import UNSET_WORKER_ENV, _local_cluster

    assert "MALLOC_TRIM_THRESHOLD_" in UNSET_WORKER_ENV
    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "65536")  # as an earlier cluster leaves it
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    cluster = _local_cluster(1)
    try:
        with Client(cluster) as c:
            # The environment the worker process started with (what glibc read), not
            # os.environ, which the nanny updates again inside the worker after the start.
            seen = c.run(lambda: [v for v in open("/proc/self/environ", "rb").read().split(
                b"\0") if v.split(b"=")[0] in (b"MALLOC_TRIM_THRESHOLD_", b"OMP_NUM_THREADS",
                                               b"PYTHONHASHSEED")])
    finally:
        cluster.close()
    # The workers are forked from the fleet's forkserver: the nanny's other pre-spawn
    # variables (set before numpy's import to take effect) reach them as they reach a
    # spawned worker, through the forkserver's environment.
    assert [sorted(v) for v in seen.values()] == [[b"OMP_NUM_THREADS=1",
                                                   b"PYTHONHASHSEED=6640"]]
    assert os.environ["MALLOC_TRIM_THRESHOLD_"] == "65536"


def test_own_cluster_workers_start_with_the_task_libraries_loaded(tmp_path: Path) -> None:
    """The fleet's own workers are forked from a forkserver that imported dask.distributed,
    gyrodrift, scipy and matplotlib once (gyrodrift.workflows._fleet_worker): a worker has them
    loaded
    before its first task (a spawned worker imported them itself, each worker again: 1.3-2 s
    of CPU per worker), runs without the statistical profiler, and the cluster is closed, its
    worker processes gone, when run_fleet returns (the close overlaps the summary); its
    results equal the serial run's."""
    from distributed import Client
    from gyrodrift.workflows.fleet import _local_cluster

    cluster = _local_cluster(1)
    try:
        with Client(cluster) as c:
            state = list(c.run(lambda: (
                sorted(m for m in ("gyrodrift.workflows._fleet_worker",
                "gyrodrift.workflows.characterize",
                                   "matplotlib.pyplot", "scipy.optimize")
                       if m in __import__("sys").modules),
                __import__("dask").config.get("distributed.worker.profile.enabled"),
                __import__("os").getppid() != __import__("os").getpid())).values())
            worker_tick = list(c.run(
                lambda dask_worker: dask_worker.periodic_callbacks["tick"].callback_time).values())
            scheduler_tick = c.run_on_scheduler(
                lambda dask_scheduler: dask_scheduler.periodic_callbacks["tick"].callback_time)
    finally:
        cluster.close()
    assert state[0][0] == ["gyrodrift.workflows._fleet_worker", "gyrodrift.workflows.characterize",
                           "matplotlib.pyplot", "scipy.optimize"]
    assert state[0][1] is False
    # the servers' event-loop tick every 1 s, not dask's 20 ms (idle CPU, _local_cluster)
    assert worker_tick == [1000.0] and scheduler_tick == 1000.0
    log = tmp_path / "u.npy"
    np.save(log, np.random.default_rng(3).standard_normal((4000, 3)) * 1e-3)
    seen: list[dict] = []
    s = run_fleet([log], tmp_path / "out", opts=NO_PLOTS, workers=1, on_result=seen.append)
    assert s["n_done"] == 1 and seen[0]["status"] == "done"
    assert not Path(f"/proc/{seen[0]['pid']}").exists()  # the worker has exited
    # A forked worker gives the serial run's numbers exactly (as the spawned ones do above).
    run_fleet([log], tmp_path / "serial", opts=NO_PLOTS, workers=0)
    assert _results(tmp_path / "out") == _results(tmp_path / "serial")


def test_close_error_is_raised_after_the_summary() -> None:
    """The cluster's close runs in a thread beside the summary; an error in it is not lost."""
    from gyrodrift.workflows.fleet import _InThread

    def fail() -> None:
        raise RuntimeError("close failed")

    t = _InThread(fail)
    with pytest.raises(RuntimeError, match="close failed"):
        t.join()
    _InThread(None).join()


_MEMORY_SCRIPT = r"""
import json, sys, tracemalloc
import numpy as np
import gyrodrift.stability.allan as allan
import gyrodrift.io.imu_data as imu_io
from gyrodrift.workflows.fleet import FleetOptions, characterize_log

def rss_mib():
    with open("/proc/self/status") as fh:
        return next(int(l.split()[1]) for l in fh if l.startswith("VmRSS:")) / 1024.0

# Small chunks, so that records of 2^18 and 2^20 samples are both many chunks long. No plots:
# their memory does not depend on the record length (two more taus per factor 4), and
# matplotlib's caches move the RSS by several MiB from one figure to the next.
allan.DEFAULT_CHUNK_SAMPLES = 1 << 15
budget, copy, warm, logs, out = (float(sys.argv[1]), sys.argv[2] == "copy", sys.argv[3],
                                 sys.argv[4:-1], sys.argv[-1])
opts = FleetOptions(rate_hz=200.0, chunk_rows=1 << 13, plots=False, memory_budget_mib=budget)
held = []
if copy:  # the defect the measure must catch: a reader holding the whole record
    for meth in ("channel", "spool"):
        def whole(self, *a, _orig=getattr(imu_io.NpyChannels, meth)):
            held.append(np.load(self.path))
            return _orig(self, *a)
        setattr(imu_io.NpyChannels, meth, whole)
# Imports, first-use caches and the allocator's pools at these chunk sizes.
characterize_log(warm, out + "/warm", opts)
# History the task must not be charged with: 256 MiB touched and freed (as a parent's
# high-water mark inherited across exec, or an earlier larger task, would be).
big = np.ones(256 << 17)
del big
rows = []
for i, log in enumerate(logs):
    held.clear()
    rss_before = rss_mib()
    tracemalloc.start()
    r = characterize_log(log, f"{out}/u{i}", opts)
    traced = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    rows.append({"status": r["status"], "reason": r.get("reason"), "rss_before": rss_before,
                 "peak": r.get("peak_rss_mib"), "scope": r.get("peak_rss_scope"),
                 "traced": traced, "reader": r.get("reader")})
print(json.dumps(rows))
"""


@pytest.fixture(scope="module")
def float32_logs(tmp_path_factory: pytest.TempPathFactory) -> dict[int, Path]:
    """.npy logs of 2^17, 2^18 and 2^20 samples x 6 channels (float32: 1, 2 and 8 MiB per
    channel as float64)."""
    d = tmp_path_factory.mktemp("f32")
    rng = np.random.default_rng(5)
    paths = {}
    for n in (1 << 17, 1 << 18, 1 << 20):
        x = rng.standard_normal((n, 6), dtype=np.float32)
        x *= np.array([1.9e-3, 1.9e-3, 1.9e-3, 2.5e-2, 2.5e-2, 2.5e-2], dtype=np.float32)
        paths[n] = d / f"log{n}.npy"
        np.save(paths[n], x)
        del x
    return paths


def _memory_rows(budget_mib: float, logs: list[Path], out: Path, copy: bool = False
                 ) -> list[dict]:
    """Each log characterized by one fresh process (after a warm-up task on the first):
    its status, reader, peak RSS (the task's VmHWM) and tracemalloc peak."""
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-c", _MEMORY_SCRIPT, str(budget_mib),
                           "copy" if copy else "-", str(logs[0]), *map(str, logs), str(out)],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = json.loads(proc.stdout.strip().splitlines()[-1])
    for r in rows:
        assert r["status"] == "done", r["reason"]
        assert r["scope"] == "task"  # Linux (/proc): the task's own high-water mark
    return rows


def _bounded(small: dict, large: dict) -> bool:
    """The chunked reader's bound: a task's peak does not grow with the record (RSS within
    4 MiB, Python allocations within 1 MiB; measured 0.1-0.4 and 0.04 MiB apart)."""
    return large["peak"] - small["peak"] < 4.0 and large["traced"] - small["traced"] < 1.0


def test_worker_memory_is_bounded_by_the_chunked_reader(float32_logs: dict[int, Path],
                                                        tmp_path: Path) -> None:
    """Above the memory budget (here 0: every log spooled), a fleet task's peak memory does
    not grow with the log: the same task (in a fresh process) on 2^18 and 2^20 samples x 6
    channels, chunks of 2^15 samples, peaks within 4 MiB of each other in RSS and 1 MiB in
    Python allocations (tracemalloc); one float64 channel of the longer log held in memory,
    or read through a mapping, would add 6 MiB over the shorter one (measured: 0.1-0.4 MiB
    and 0.04 MiB apart). And the reported peak (peak_rss_mib) is the task's own: before, it
    was ru_maxrss, which Linux keeps across exec and which never falls, so a worker reported
    its parent's high-water mark (502 MiB in the benchmark, whose parent had just written
    the logs) or an earlier task's; here 256 MiB touched before the tasks must not show in
    their peaks."""
    small, large = _memory_rows(0.0, [float32_logs[1 << 18], float32_logs[1 << 20]], tmp_path)
    for r in (small, large):
        assert r["reader"] == "spool"
        # Above the RSS the task started from: chunk buffers (~1.2 MiB here), the Allan
        # results and allocator slack, not the 256 MiB of history (measured +0.04..0.4 MiB).
        assert r["peak"] - r["rss_before"] < 32.0, r
    assert large["peak"] - small["peak"] < 4.0, (small, large)
    assert large["traced"] - small["traced"] < 1.0, (small, large)


def test_memory_budget_one_channel_in_memory_below_spooled_above(
        float32_logs: dict[int, Path], tmp_path: Path) -> None:
    """Both sides of FleetOptions.memory_budget_mib. Budget 1 MiB: the 2^17-sample log (one
    float64 channel = 1 MiB, the limit included) is read into memory one channel at a time;
    the 2^18 and 2^20 logs (2 and 8 MiB per channel) are spooled and their peaks stay
    bounded as in the test above. Budget 64 MiB: both in memory, and the longer log's peak
    exceeds the shorter's by one channel (8 - 2 = 6 MiB), not by the record (6 channels:
    36 MiB as float64, 18 MiB as stored)."""
    rows = _memory_rows(1.0, [float32_logs[n] for n in (1 << 17, 1 << 18, 1 << 20)],
                        tmp_path / "b1")
    assert [r["reader"] for r in rows] == ["memory", "spool", "spool"]
    assert _bounded(rows[1], rows[2]), rows
    small, large = _memory_rows(64.0, [float32_logs[1 << 18], float32_logs[1 << 20]],
                                tmp_path / "b64")
    assert small["reader"] == large["reader"] == "memory"
    # One channel: 6 MiB more Python allocations (the channel array; measured 6.0x), and
    # less than two channels' 12 MiB in the RSS as well.
    assert 5.5 < large["traced"] - small["traced"] < 9.0, (small, large)
    assert large["peak"] - small["peak"] < 12.0, (small, large)


def test_the_memory_measure_catches_a_whole_record_copy(float32_logs: dict[int, Path],
                                                        tmp_path: Path) -> None:
    """The tests above can fail: with the reader patched to hold the whole record during the
    task (np.load of the log), the spooled logs' peaks are no longer bounded, and the in-memory
    ones grow by more than one channel."""
    logs = [float32_logs[1 << 18], float32_logs[1 << 20]]
    small, large = _memory_rows(0.0, logs, tmp_path / "spool", copy=True)
    assert not _bounded(small, large), (small, large)
    small, large = _memory_rows(64.0, logs, tmp_path / "mem", copy=True)
    assert large["traced"] - small["traced"] > 9.0, (small, large)


def test_cli_memory_budget(logs: list[Path], tmp_path: Path,
                           capsys: pytest.CaptureFixture[str]) -> None:
    from gyrodrift.cli import main

    base = ["fleet", str(logs[0]), "--rate-hz", "100", "--workers", "0", "--progress", "never",
            *UNITS]
    for budget, reader in (("0", "spool"), ("1", "memory")):  # a channel: 6000 x 8 bytes
        out = tmp_path / f"b{budget}"
        assert main([*base, "--out-dir", str(out), "--memory-budget-mib", budget]) == 0
        done = json.loads((out / "units" / "unit0" / "result.json").read_text())
        assert done["summary"]["reader"] == reader
    assert main([*base, "--out-dir", str(tmp_path / "bad"), "--memory-budget-mib", "-1"]) == 2
    assert "memory_budget_mib must be >= 0" in capsys.readouterr().err


def test_own_cluster_takes_a_free_port_for_its_http_endpoint() -> None:
    """Regression: the fleet's own scheduler bound its HTTP endpoint (health, metrics) to dask's
    default port 8787; beside any other cluster (the tests' shared one, a second fleet in the
    process, a user's dashboard) dask warned "Port 8787 is already in use" on every run."""
    import socket
    import warnings

    from gyrodrift.workflows.fleet import _local_cluster

    held = socket.socket()
    try:
        held.bind(("127.0.0.1", 8787))  # 8787 in use, by this socket or by another cluster
        held.listen(1)
    except OSError:
        pass
    try:
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            cluster = _local_cluster(1)
            try:
                port = cluster.scheduler.http_server.port
            finally:
                cluster.close()
    finally:
        held.close()
    assert not [w for w in seen if "already in use" in str(w.message)]
    assert port not in (8787, 0)


def test_cli_with_its_own_cluster_in_a_fresh_process(logs: list[Path], tmp_path: Path) -> None:
    """`gyrodrift fleet` as a user runs it: a fresh interpreter that has imported nothing of
    dask (this test process has; the other tests here would not see, e.g., a dask setting read
    before dask.distributed is imported), its own LocalCluster forked from the forkserver."""
    import os
    import subprocess
    import sys

    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-m", "gyrodrift", "fleet", str(logs[0]), "--out-dir",
                          str(out), "--rate-hz", "100", "--workers", "1", "--progress", "never",
                          *UNITS],
                         capture_output=True, text=True, env=os.environ.copy(), timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "1 done" in run.stdout
    assert json.loads((out / "summary.json").read_text())["n_done"] == 1


_SCRIPT_BODY = """\
import sys
from gyrodrift.workflows.fleet import FleetOptions, run_fleet
{call}
"""
_CALL = ("s = run_fleet([sys.argv[1]], sys.argv[2], workers=1, progress=False,\n"
         "              opts=FleetOptions(rate_hz=100.0, plots=False))\n"
         "print('done', s['n_done'])")


def _run_script(tmp_path: Path, body: str, log: Path) -> subprocess.CompletedProcess[str]:
    script = tmp_path / "user_script.py"
    script.write_text(body)
    return subprocess.run([sys.executable, str(script), str(log), str(tmp_path / "out")],
                          capture_output=True, text=True, env=os.environ.copy(), timeout=300,
                          cwd=tmp_path)


def test_unguarded_script_with_own_cluster_gets_one_clear_error(logs: list[Path],
                                                                tmp_path: Path) -> None:
    """A script that calls run_fleet(workers >= 1) at its top level, without the
    ``if __name__ == "__main__":`` guard: every worker process runs the script again and would
    start a cluster while it starts. The call is refused before any worker starts, naming the
    script's line and the guard, not a cascade of worker tracebacks ending in "Nanny failed to
    start"."""
    run = _run_script(tmp_path, _SCRIPT_BODY.format(call=_CALL), logs[0])
    assert run.returncode != 0
    last = run.stderr.strip().splitlines()[-1]
    assert last.startswith("gyrodrift.errors.GyrodriftError: "), run.stderr[-3000:]
    assert "user_script.py, line 3" in last and 'if __name__ == "__main__":' in last, last
    assert "Nanny" not in run.stderr and "bootstrapping" not in run.stderr, run.stderr[-3000:]
    assert not (tmp_path / "out" / "summary.json").exists()


def test_guarded_script_runs_on_its_own_cluster(logs: list[Path], tmp_path: Path) -> None:
    """The same call under the guard (inside a function called from it) runs on worker
    processes: the check does not refuse a correct script."""
    body = _SCRIPT_BODY.format(
        call="def main():\n" + "".join(f"    {ln}\n" for ln in _CALL.splitlines())
        + "\n\nif __name__ == \"__main__\":\n    main()")
    run = _run_script(tmp_path, body, logs[0])
    assert run.returncode == 0, run.stderr[-3000:]
    assert "done 1" in run.stdout


# ------------------------------------------------------------------ stale results on resume


def _copy_logs(logs: list[Path], dest: Path, k: int = 2) -> list[Path]:
    dest.mkdir()
    out = []
    for p in logs[:k]:
        out.append(dest / p.name)
        out[-1].write_bytes(p.read_bytes())
    return out


def test_resume_redoes_units_whose_options_changed(logs: list[Path], tmp_path: Path) -> None:
    """A rerun with another sample rate or other fit terms must not report the old numbers
    as "already done"; a rerun with the same options (and a changed reading option only)
    skips them."""
    mine = _copy_logs(logs, tmp_path / "logs")
    out = tmp_path / "out"
    first = run_fleet(mine, out, opts=NO_PLOTS, workers=0, root=mine[0].parent)
    assert first["n_run"] == 2 and first["n_redone"] == 0
    before = _results(out)
    same = run_fleet(mine, out, opts=FleetOptions(rate_hz=100.0, plots=False,
                                                  memory_budget_mib=0.0),
                     workers=0, root=mine[0].parent)
    assert same["n_run"] == 0 and same["n_skipped"] == 2
    rate = run_fleet(mine, out, opts=FleetOptions(rate_hz=200.0, plots=False), workers=0,
                     root=mine[0].parent)
    assert rate["n_run"] == 2 and rate["n_skipped"] == 0 and rate["n_redone"] == 2
    assert all("rate_hz" in r["reason"] for r in rate["redone"]), rate["redone"]
    after = _results(out)
    assert [after[u]["record"]["rate_hz"] for u in ("unit0", "unit1")] == [200.0, 200.0]
    assert before["unit0"]["record"]["rate_hz"] == 100.0
    terms = run_fleet(mine, out, opts=FleetOptions(rate_hz=200.0, plots=False,
                                                   terms=("N", "K")),
                      workers=0, root=mine[0].parent)
    assert terms["n_redone"] == 2 and all("terms" in r["reason"] for r in terms["redone"])
    chan = _results(out)["unit0"]["channels"]["gyro_x"]
    assert set(chan["terms"]) == {"N", "K"}


def test_resume_redoes_a_log_replaced_with_the_same_size_and_mtime(
        logs: list[Path], tmp_path: Path) -> None:
    """A log replaced by another of the same size whose modification time is set back to the
    old one (os.utime) is redone; a log only touched (same content, new time) is not."""
    import os

    mine = _copy_logs(logs, tmp_path / "logs")
    out = tmp_path / "out"
    run_fleet(mine, out, opts=NO_PLOTS, workers=0, root=mine[0].parent)
    old = _results(out)["unit0"]
    st = mine[0].stat()
    rng = np.random.default_rng(123)
    np.save(mine[0], rng.standard_normal((6000, 6)) * 5e-3)  # same shape: same size
    os.utime(mine[0], ns=(st.st_atime_ns, st.st_mtime_ns))
    assert mine[0].stat().st_size == st.st_size
    assert mine[0].stat().st_mtime_ns == st.st_mtime_ns
    os.utime(mine[1])  # touched only
    again = run_fleet(mine, out, opts=NO_PLOTS, workers=0, root=mine[0].parent)
    assert again["n_run"] == 1 and again["n_skipped"] == 1
    assert again["redone"] == [{"unit": "unit0", "path": str(mine[0]),
                                "reason": "input changed (content)"}]
    new = _results(out)["unit0"]
    n_new, n_old = (r["channels"]["gyro_x"]["terms"]["N"]["value"] for r in (new, old))
    assert n_new != n_old
    mine[1].write_bytes(mine[1].read_bytes()[:-8])  # shorter
    third = run_fleet(mine, out, opts=NO_PLOTS, workers=0, root=mine[0].parent)
    assert [r["reason"] for r in third["redone"]] == ["input changed (size)"]


def test_resume_redoes_a_result_without_provenance(logs: list[Path], tmp_path: Path) -> None:
    mine = _copy_logs(logs, tmp_path / "logs", k=1)
    out = tmp_path / "out"
    run_fleet(mine, out, opts=NO_PLOTS, workers=0, root=mine[0].parent)
    res = out / "units" / "unit0" / "result.json"
    payload = json.loads(res.read_text())
    del payload["provenance"]
    res.write_text(json.dumps(payload))
    again = run_fleet(mine, out, opts=NO_PLOTS, workers=0, root=mine[0].parent)
    assert again["n_redone"] == 1 and "older result" in again["redone"][0]["reason"]


def test_cli_says_what_was_redone(logs: list[Path], tmp_path: Path,
                                  capsys: pytest.CaptureFixture[str]) -> None:
    from gyrodrift.cli import main

    mine = _copy_logs(logs, tmp_path / "logs", k=1)
    base = ["fleet", str(mine[0]), "--out-dir", str(tmp_path / "out"), "--workers", "0",
            "--progress", "never", *UNITS]
    assert main([*base, "--rate-hz", "100"]) == 0
    capsys.readouterr()
    assert main([*base, "--rate-hz", "50"]) == 0
    out = capsys.readouterr().out
    assert "1 redone" in out
    assert f"redone: {mine[0]}: options changed (rate_hz)" in out


@pytest.mark.parametrize("spec, message", [
    ({"gyroscope_noise_density": {"max": "1e-4"}}, "max must be a finite number"),
    ({"gyro_N": {"min": True}}, "min must be a finite number"),
    ({"gyro_N": {"max": None}}, "max must be a finite number"),
    ({"gyro_N": {"min": 2e-4, "max": 1e-4}}, "min 0.0002 is above max 0.0001"),
])
def test_bad_spec_is_one_line_before_any_work(tmp_path: Path, logs: list[Path],
                                              capsys: pytest.CaptureFixture[str],
                                              spec: dict, message: str) -> None:
    """A spec limit that is not a number used to fail with a TypeError in the summary, after
    every log was characterized, and leave no summary; NaN disabled its check; min > max was
    accepted. Now: one line, exit 2, nothing characterized."""
    from gyrodrift.cli import main

    path = tmp_path / "spec.json"
    path.write_text(json.dumps(spec))
    out = tmp_path / "out"
    code = main(["fleet", str(logs[0]), "--out-dir", str(out), "--rate-hz", "100",
                 "--workers", "0", "--spec", str(path), "--progress", "never"])
    err = capsys.readouterr().err
    assert code == 2
    key, lim = next(iter(spec.items()))
    got = "" if "above" in message else f", got {next(iter(lim.values()))!r}"
    assert err.strip().splitlines() == [f"gyrodrift fleet: error: {path}: {key}: {message}{got}"]
    assert not (out / "units").exists() or not any((out / "units").iterdir())


def test_nan_spec_limit_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "spec.json"
    path.write_text('{"gyro_N": {"max": NaN}}')  # Python's json reads NaN
    with pytest.raises(ValueError, match="max must be a finite number, got nan"):
        load_spec(path)
    with pytest.raises(ValueError, match="finite number"):
        run_fleet([tmp_path / "x.npy"], tmp_path / "out", opts=NO_PLOTS, workers=0,
                  spec={"gyro_N": {"max": float("nan")}})


def test_resumed_cli_run_closes_its_cluster_without_a_trace(logs: list[Path],
                                                           tmp_path: Path) -> None:
    """A resumed run (one new log, the rest done) with its own 2-worker cluster: a worker
    whose heartbeat was in flight when the scheduler closed used to print a CommClosedError
    traceback on stderr (seen in about 1 of 15 runs on a busy machine; a test cannot force
    that timing, so this runs the case a few times and also checks the mechanism directly:
    a worker's heartbeat error record after the silencing is not emitted)."""
    import logging
    import os
    import subprocess
    import sys

    from gyrodrift.workflows.fleet import _silence_distributed_logging

    mine = _copy_logs(logs, tmp_path / "logs", k=3)
    for k in range(3):
        out = tmp_path / f"out{k}"
        base = [sys.executable, "-m", "gyrodrift", "fleet", "--out-dir", str(out), "--rate-hz",
                "100", "--workers", "2", "--progress", "never", *UNITS]
        first = subprocess.run([*base, str(mine[0]), str(mine[1])], capture_output=True,
                               text=True, env=os.environ.copy(), timeout=300)
        assert first.returncode == 0, first.stderr[-2000:]
        again = subprocess.run([*base, *map(str, mine)], capture_output=True, text=True,
                               env=os.environ.copy(), timeout=300)
        assert again.returncode == 0, again.stderr[-2000:]
        assert "2 already done" in again.stdout
        for err in (first.stderr, again.stderr):
            assert "Traceback" not in err and "CommClosedError" not in err, err[-2000:]
    worker_log = logging.getLogger("distributed.worker")
    saved = [(lg, lg.level) for lg in (logging.getLogger("distributed"), worker_log)]
    try:
        _silence_distributed_logging()
        assert not worker_log.isEnabledFor(logging.ERROR)
    finally:
        for lg, level in saved:
            lg.setLevel(level)


@pytest.mark.parametrize(("option", "flag"), [
    (("--time-units", "ns"), "--time-units"),
    (("--time-column", "t"), "--time-column"),
    (("--topic", "/imu"), "--topic"),
])
def test_reader_options_a_npy_log_cannot_use_are_refused_as_by_characterize(
        tmp_path: Path, logs: list[Path], capsys: pytest.CaptureFixture[str],
        option: tuple[str, str], flag: str) -> None:
    """--time-units and --time-column name a text log's time column, --topic a bag's topic:
    a .npy log has none. `characterize` and the fleet used to accept and ignore them for a
    .npy log (the fleet also ignored --time-units where characterize refused it); now both
    refuse them with the same line, the fleet before any work, and the library refuses them
    for each such log (reported as failed)."""
    from gyrodrift.cli import main

    out = tmp_path / "out"
    argv = [str(logs[0]), "--rate-hz", "100", *UNITS, *option]
    assert main(["characterize", *argv]) == 2
    want = capsys.readouterr().err.strip().splitlines()
    assert len(want) == 1 and flag in want[0] and str(logs[0]) in want[0], want
    code = main(["fleet", *argv, "--out-dir", str(out), "--workers", "0", "--progress",
                 "never"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert err == [want[0].replace("gyrodrift characterize:", "gyrodrift fleet:")]
    assert not (out / "units").exists() or not any((out / "units").iterdir())
    field = {"--time-units": "time_units", "--time-column": "time_column",
             "--topic": "topic"}[flag]
    opts = FleetOptions(rate_hz=100.0, plots=False, **{field: option[1]})
    summary = run_fleet([str(logs[0])], tmp_path / "lib", workers=0, opts=opts)
    assert summary["n_failed"] == 1 and summary["n_done"] == 0
