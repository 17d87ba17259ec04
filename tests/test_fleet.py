"""`gyrodrift fleet` on a dask.distributed LocalCluster (2 worker processes, loopback, one
cluster for the module): equal to the serial run, a corrupt log reported as failed, a resumed
run doing no work for finished logs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from gyrodrift.fleet import FleetOptions, load_spec, run_fleet


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


def test_cli_on_an_existing_scheduler(client, logs: list[Path], tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    from gyrodrift.cli import main

    code = main(["fleet", str(logs[0].parent / "unit[05].npy"), "--out-dir",
                 str(tmp_path / "out"), "--rate-hz", "100", "--scheduler",
                 client.scheduler.address, "--progress", "never"])
    assert code == 1  # one failed log
    out = capsys.readouterr().out
    assert "1 done" in out and "1 failed" in out
    assert "failed: " in out and "unit5.npy" in out
    assert (tmp_path / "out" / "units" / "unit0" / "result.json").is_file()



_MEMORY_SCRIPT = r"""
import json, sys, tracemalloc
import numpy as np
import gyrodrift.allan as allan
from gyrodrift.fleet import FleetOptions, characterize_log

def rss_mib():
    with open("/proc/self/status") as fh:
        return next(int(l.split()[1]) for l in fh if l.startswith("VmRSS:")) / 1024.0

# Small chunks, so that records of 2^18 and 2^20 samples are both many chunks long. No plots:
# their memory does not depend on the record length (two more taus per factor 4), and
# matplotlib's caches move the RSS by several MiB from one figure to the next.
allan.DEFAULT_CHUNK_SAMPLES = 1 << 15
opts = FleetOptions(rate_hz=200.0, chunk_rows=1 << 13, plots=False)
warm, logs, out = sys.argv[1], sys.argv[2:-1], sys.argv[-1]
# Imports, first-use caches and the allocator's pools at these chunk sizes.
characterize_log(warm, out + "/warm", opts)
# History the task must not be charged with: 256 MiB touched and freed (as a parent's
# high-water mark inherited across exec, or an earlier larger task, would be).
big = np.ones(256 << 17)
del big
rows = []
for i, log in enumerate(logs):
    rss_before = rss_mib()
    tracemalloc.start()
    r = characterize_log(log, f"{out}/u{i}", opts)
    traced = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    rows.append({"status": r["status"], "reason": r.get("reason"), "rss_before": rss_before,
                 "peak": r.get("peak_rss_mib"), "scope": r.get("peak_rss_scope"),
                 "traced": traced})
print(json.dumps(rows))
"""


def test_worker_memory_is_bounded_by_the_chunked_reader(tmp_path: Path) -> None:
    """A fleet task's peak memory does not grow with the log: the same task (in a fresh
    process) on 2^18 and 2^20 samples x 6 channels, chunks of 2^15 samples, peaks within
    4 MiB of each other in RSS and 1 MiB in Python allocations (tracemalloc); one float64
    channel of the longer log held in memory, or read through a mapping, would add 6 MiB
    over the shorter one (measured: 0.1-0.4 MiB and 0.04 MiB apart). And the reported peak
    (peak_rss_mib) is the task's own: before, it was ru_maxrss, which Linux keeps across
    exec and which never falls, so a worker reported its parent's high-water mark (502 MiB
    in the benchmark, whose parent had just written the logs) or an earlier task's; here
    256 MiB touched before the tasks must not show in their peaks."""
    import subprocess
    import sys

    rng = np.random.default_rng(5)
    paths = []
    for i, n in enumerate((1 << 18, 1 << 20)):
        x = rng.standard_normal((n, 6), dtype=np.float32)
        x *= np.array([1.9e-3, 1.9e-3, 1.9e-3, 2.5e-2, 2.5e-2, 2.5e-2], dtype=np.float32)
        paths.append(tmp_path / f"log{i}.npy")
        np.save(paths[-1], x)
        del x
    proc = subprocess.run([sys.executable, "-c", _MEMORY_SCRIPT, str(paths[0]),
                           *map(str, paths), str(tmp_path / "out")],
                          capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    small, large = json.loads(proc.stdout.strip().splitlines()[-1])
    for r in (small, large):
        assert r["status"] == "done", r["reason"]
        assert r["scope"] == "task"  # Linux (/proc): the task's own high-water mark
        # Above the RSS the task started from: chunk buffers (~1.2 MiB here), the Allan
        # results and allocator slack, not the 256 MiB of history (measured +0.04..0.4 MiB).
        assert r["peak"] - r["rss_before"] < 32.0, r
    assert large["peak"] - small["peak"] < 4.0, (small, large)
    assert large["traced"] - small["traced"] < 1.0, (small, large)
