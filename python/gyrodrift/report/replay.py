"""The replay report: a terminal table, the JSON file, a PNG of latency and jitter, and, when
the replayed configuration has the gyro monitor enabled, its online estimates over the
replayed record against the offline fit of the same record (one PNG per monitored channel)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from gyrodrift.codecs.wire import Samples
from gyrodrift.imu.config import ProcessorConfig
from gyrodrift.imu.monitor import MonitorTrace
from gyrodrift.io.atomic import atomic_output, atomic_write_text
from gyrodrift.io.json_text import json_text
from gyrodrift.replay.harness import ReplayResult

__all__ = [
    "format_table",
    "monitor_summary",
    "monitor_traces",
    "write_json",
    "write_monitor_pngs",
    "write_png",
]


def _fmt(x: Any, digits: int = 1) -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        if math.isnan(x):
            return "-"
        return f"{x:.{digits}f}" if abs(x) >= 1e-3 or x == 0 else f"{x:.2e}"
    return str(x)


def format_table(result: ReplayResult) -> str:
    """The report as aligned text (what `gyrodrift replay` prints).

    Examples
    --------
    >>> from gyrodrift.replay import ReplayOptions, run_replay
    >>> from gyrodrift.codecs.wire import make_samples
    >>> s = make_samples(np.arange(40) / 400.0, np.zeros((40, 3)), np.tile([0, 0, 9.8], (40, 1)))
    >>> res = run_replay(s, ReplayOptions(speed=0.0, loop_realtime=False, harness_realtime=False))
    >>> print("\\n".join(format_table(res).splitlines()[:1] + format_table(res).splitlines()[8:10]))
    result                             PASS
    outputs expected / received        40 / 40
    unaccounted                        0
    """
    r = result.report
    a = r["accounting"]
    rows: list[tuple[str, str]] = [
        ("result", "PASS" if r["ok"] else "FAIL"),
        ("transport", f"{r['transport']} on {r['device']}, {r['speed']}, baud {r['baud']}"
         + (f", CAN {r['can_bitrate']} bit/s" if r["can_bitrate"] else "")),
        ("loop rate", f"{r['loop_rate_hz']:g} Hz"),
        ("samples in record", str(a["samples_in_record"])),
    ]
    if r.get("input_log"):
        from gyrodrift.io.imu_log import CanLogReport

        rows.append(("input log", CanLogReport(**r["input_log"]).summary()))
    rows += [
        ("injected faults", ", ".join(f"{k} {v}" for k, v in a["injected"].items() if v)
         or "none"),
        ("sent", str(a["sent"])),
        ("rejected on link", ", ".join(f"{k} {v}" for k, v in a["rejected_on_link"].items())),
        ("rejected by processor",
         ", ".join(f"{k} {v}" for k, v in a["rejected_by_processor"].items())),
        ("outputs expected / received", f"{a['outputs_expected']} / {a['outputs_received']}"),
        ("unaccounted", str(a["unaccounted"])),
    ]
    c = r["comparison"]
    rows.append(("max |loop - reference|",
                 " ".join(_fmt(e, 2) for e in c["max_abs_error"])
                 + f" (tol {c['tolerance']:.0e})"))
    lat = r["latency_us"]
    rows.append(("latency us min/p50/p90/p99/max",
                 "/".join(_fmt(lat.get(k)) for k in ("min", "p50", "p90", "p99", "max"))))
    jit = r.get("output_jitter_us")
    if jit and jit["n"]:
        rows.append(("output jitter us p50/p99/max",
                     "/".join(_fmt(jit[k]) for k in ("p50", "p99", "max"))))
    th = r["throughput"]
    rows.append(("frames/s sent, end to end",
                 f"{_fmt(th['frames_per_s_sent'], 0)}, {_fmt(th['frames_per_s_end_to_end'], 0)}"))
    hrt = r.get("harness_realtime")
    if isinstance(hrt, dict):
        rows.append(("harness realtime", f"sender {hrt['sender']}, receiver {hrt['receiver']}"))
    loop = r.get("loop")
    if r.get("firmware"):
        rows += _firmware_rows(r)
    elif loop:
        rt = loop["realtime"]
        rows.append(("loop realtime", f"SCHED_FIFO {'yes' if rt['sched_fifo'] else 'no'}"
                     f", mlockall {'yes' if rt['mlockall'] else 'no'}"))
        for key in ("period_jitter_us", "wake_latency_us", "compute_us", "sample_us"):
            h = loop[key]
            rows.append((f"loop {key.replace('_us', '')} us p50/p99/max",
                         "/".join(_fmt(h[k], 3 if key == "sample_us" else 1)
                                  for k in ("p50", "p99", "max"))))
        rows.append(("loop cycles / overruns", f"{loop['cycles']} / {loop['overruns']}"))
        nz = {k: v for k, v in loop["rejected"].items() if v}
        rows.append(("loop rejected", ", ".join(f"{k} {v}" for k, v in nz.items()) or "none"))
    mon = r.get("monitor")
    if mon:
        rows += _monitor_rows(mon)
    failed = [k for k, v in r["checks"].items() if not v]
    rows.append(("failed checks", ", ".join(failed) or "none"))
    w = max(len(k) for k, _ in rows)
    return "\n".join(f"{k:<{w}}  {v}" for k, v in rows)


def _monitor_rows(mon: dict[str, Any]) -> list[tuple[str, str]]:
    """The gyro monitor's rows: per channel the alarms and the last online estimates, then
    the alarm counts of the host run against the loop's counters."""
    rows = []
    for ch, c in mon["channels"].items():
        last = c["last"] or {}
        alarms = ", ".join(f"{k} at {v:g} s" for k, v in c["alarms"].items()) or "none"
        rows.append((f"monitor {ch}",
                     f"alarms {alarms}; last report N {_fmt(last.get('n_deg_rt_h'), 4)} "
                     f"deg/sqrt(h), B {_fmt(last.get('b_deg_h'), 4)} deg/h, status "
                     f"{last.get('status', '-')}"))
    if mon.get("alarms_loop") is not None:
        rows.append(("monitor alarms host / loop",
                     ", ".join(f"{k} {v}/{mon['alarms_loop'].get(k, '-')}"
                               for k, v in mon["alarms_host"].items())
                     + ("" if mon["agree"] else " (DIFFER)")))
    return rows


def _firmware_rows(r: dict[str, Any]) -> list[tuple[str, str]]:
    """The firmware target's rows: image size against the budget, instructions per step and
    the CPU load they mean, the comparison with the host loop."""
    fw = r["firmware"]
    img = fw["image"]
    rows = [("target", str(r.get("target", ""))),
            ("image flash / RAM",
             f"{img['flash_bytes']} / {img['ram_bytes']} B (budget {img['flash_budget_bytes']}"
             f" / {img['ram_budget_bytes']} B)")]
    cost = fw.get("step_cost")
    if cost:
        rows.append(("instructions per step",
                     f"median {cost['instructions_median']:.0f}, max "
                     f"{cost['instructions_max']:.0f} over {cost['steps']} steps (QEMU -icount)"))
        rows.append((f"CPU load at {cost['loop_rate_hz']:g} Hz",
                     f"median {100 * cost['cpu_load_median']:.2f} %, max "
                     f"{100 * cost['cpu_load_max']:.2f} % of a 168 MHz M4F at CPI "
                     f"{cost['assumed_cpi']:g} (goal < {100 * cost['cpu_load_goal']:g} %)"))
    loop = r.get("loop")
    if loop:
        rows.append(("image cycles / overruns", f"{loop['cycles']} / {loop['overruns']}"))
        nz = {k: v for k, v in loop["rejected"].items() if v}
        rows.append(("image rejected", ", ".join(f"{k} {v}" for k, v in nz.items()) or "none"))
    h = r.get("host_loop")
    if h:
        rows.append(("image vs host loop",
                     f"{h['outputs']} outputs, seq {'equal' if h['seq_equal'] else 'DIFFER'}, "
                     f"flags {'equal' if h['flags_equal'] else 'DIFFER'}, "
                     f"{h['values_bit_identical']} bit-identical, max |diff| "
                     + " ".join(_fmt(e, 2) for e in h["max_abs_difference"])))
        rows.append(("image vs host loop counters",
                     f"{h['counters_compared']} compared, "
                     + (", ".join(h["counters_unequal"]) or "all equal")))
    return rows


def write_json(result: ReplayResult, path: str | Path) -> Path:
    """Write the replay's report as JSON to `path` (what `gyrodrift replay` saves as report.json).

    Examples
    --------
    >>> import json, tempfile
    >>> from pathlib import Path
    >>> from gyrodrift.replay import ReplayResult
    >>> res = ReplayResult({"ok": True, "transport": "serial"}, np.zeros(0), np.zeros(0), None)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     print(json.loads(write_json(res, Path(d) / "report.json").read_text())["ok"])
    True
    """
    return atomic_write_text(path, json_text(result.report) + "\n")


def _hist(ax: Any, values: np.ndarray, bins: int, **kw: Any) -> None:
    """ax.hist that also draws values of (nearly) one value: numpy refuses `bins` finite-sized
    bins when the span is below the resolution of the values (outputs at an exactly constant
    spacing, a latency that never changes), so such data get one bin of width 1 around it."""
    v = values[np.isfinite(values)]
    if v.size == 0:
        return
    lo, hi = float(v.min()), float(v.max())
    if hi - lo <= 1e-9 * max(1.0, abs(lo), abs(hi)):
        ax.hist(v, bins=1, range=(lo - 0.5, hi + 0.5), **kw)
    else:
        ax.hist(v, bins=bins, **kw)


def write_png(result: ReplayResult, path: str | Path) -> Path:
    """Latency of every output over the run, its distribution, and the output inter-arrival
    jitter seen by the harness with the loop's own period-jitter percentiles.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from gyrodrift.replay import ReplayResult
    >>> rng = np.random.default_rng(0)  # 50 outputs, 2.5 ms apart with some jitter
    >>> res = ReplayResult({"ok": True, "transport": "serial", "speed": "1x"},
    ...                    rng.normal(300.0, 20.0, 50),
    ...                    np.arange(50) * 0.0025 + rng.normal(0.0, 1e-5, 50), None)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     print(write_png(res, Path(d) / "report.png").stat().st_size > 10_000)
    True
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    lat = result.latency_us
    t = result.output_arrival_s[: lat.size]
    fig, ax = plt.subplots(1, 3, figsize=(14, 4))
    if lat.size:
        ax[0].plot(t, lat, ".", ms=2)
        _hist(ax[1], lat, min(100, max(10, lat.size // 20)), log=True)
    ax[0].set(xlabel="time since first write (s)", ylabel="latency (us)",
              title="input written -> output read")
    ax[1].set(xlabel="latency (us)", ylabel="outputs", title="latency distribution")
    arr = result.output_arrival_s
    if arr.size > 2:
        _hist(ax[2], np.diff(arr) * 1e6, 100, log=True, label="output inter-arrival")
    loop = result.loop_stats
    if loop and "period_jitter_us" in loop:  # the host loop's (the firmware has no such clock)
        for key, style in (("p50", ":"), ("p99", "--"), ("max", "-")):
            ax[2].axvline(loop["period_jitter_us"][key], color="k", ls=style,
                          label=f"loop period jitter {key}")
    ax[2].set(xlabel="us", ylabel="count", title="jitter")
    ax[2].legend(fontsize=7)
    fig.suptitle(f"gyrodrift replay: {result.report['transport']}, {result.report['speed']}, "
                 f"{'PASS' if result.ok else 'FAIL'}")
    fig.tight_layout()
    try:
        with atomic_output(path) as tmp:  # the output rule of gyrodrift.io.atomic
            fig.savefig(tmp, dpi=100)
    finally:
        plt.close(fig)
    return path


def monitor_traces(samples: Samples, processor: ProcessorConfig) -> dict[str, MonitorTrace]:
    """The gyro monitor over the replayed record, as the target runs it: per monitored channel
    (:meth:`~gyrodrift.imu.config.ProcessorConfig.monitored_channels`), the configuration's
    ``[monitor]`` settings, the channel's ``ar2_kalman`` model as the reference, its
    saturation and stuck checks, the float state of the target, over the samples as sent
    (float32 on the wire). Empty when the configuration's monitor is not enabled.

    Examples
    --------
    >>> from gyrodrift.codecs.wire import make_samples
    >>> from gyrodrift.imu.config import drift_filter_config
    >>> rng = np.random.default_rng(0)
    >>> s = make_samples(np.arange(4000) / 400.0, rng.normal(0.0, 1e-4, (4000, 3)),
    ...                  np.tile([0.0, 0.0, 9.8], (4000, 1)))
    >>> cfg = drift_filter_config("gz", a1=0.5, a2=0.2, mean=0.0, q=1e-10, r=1e-8,
    ...                           sample_rate_hz=400.0)
    >>> monitor_traces(s, cfg)  # the monitor is off
    {}
    >>> tr = monitor_traces(s, cfg.with_monitor(enabled=True, report_interval_s=5.0))
    >>> list(tr), tr["gz"].t_s.tolist()
    (['gz'], [5.0, 10.0])
    """
    from gyrodrift.imu.monitor import reference_from_config, run_monitor
    from gyrodrift.imu.schema import CHANNEL_NAMES

    mon = processor.monitor
    if not mon.enabled:
        return {}
    rate = float(processor.timing.sample_rate_hz)
    out = {}
    for ch in processor.monitored_channels():
        cc = processor.channel(ch)
        y = samples.channels[:, CHANNEL_NAMES.index(ch)].astype(np.float64)
        out[ch] = run_monitor(y, rate, reference_from_config(processor, ch), settings=mon,
                              dtype=np.float32, saturation=cc.saturation,
                              stuck_samples=cc.stuck_samples)
    return out


def monitor_summary(traces: dict[str, MonitorTrace],
                    loop_stats: dict[str, Any] | None = None) -> dict[str, Any]:
    """The monitor's part of the report: per monitored channel (``channels``) the alarms
    raised (the first report each was raised at, s), the statistic that tripped each, and the
    last report (the JSON row of ``gyrodrift monitor``); the alarms of each kind over the
    channels (``alarms_host``) beside the loop's own counters (``alarms_loop``, its
    ``monitor_<alarm>`` health counters; None when it reports none) and whether they
    agree.

    Examples
    --------
    >>> monitor_summary({})["channels"]
    {}
    """
    from gyrodrift.report.monitor import first_alarms, trace_rows

    channels: dict[str, Any] = {}
    host: dict[str, int] = {}
    for ch, tr in traces.items():
        rows = trace_rows(tr)
        alarms = first_alarms(tr)
        for name in tr.alarm_names:
            host[name] = host.get(name, 0) + (name in alarms)
        channels[ch] = {"alarms": alarms, "trips": dict(tr.trips), "reports": len(rows),
                        "last": rows[-1] if rows else None}
    health = (loop_stats or {}).get("health") or {}
    loop = {name: int(health[f"monitor_{name}"]) for name in host
            if f"monitor_{name}" in health} or None  # None: the loop counts no alarms
    return {"channels": channels, "alarms_host": host, "alarms_loop": loop,
            "agree": None if loop is None else loop == host}


def write_monitor_pngs(traces: dict[str, MonitorTrace], samples: Samples, rate_hz: float,
                       path: str | Path) -> list[Path]:
    """One plot per monitored channel, ``<stem>-<channel><suffix>`` beside ``path``: the online
    N, B and K over the replayed record against the offline fit (``gyrodrift allan``'s
    default) of the whole record and of each half, with the alarms.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     write_monitor_pngs({}, None, 400.0, Path(d) / "monitor.png")  # nothing monitored
    []
    """
    from gyrodrift.imu.schema import CHANNEL_NAMES
    from gyrodrift.report.monitor import plot_monitor, segment_fits

    path = Path(path)
    written = []
    for ch, tr in traces.items():
        y = samples.channels[:, CHANNEL_NAMES.index(ch)].astype(np.float64)
        duration = y.size / rate_hz
        whole, *halves = segment_fits(y, rate_hz, [(0.0, duration), (0.0, duration / 2.0),
                                                   (duration / 2.0, duration)])
        out = path.with_name(f"{path.stem}-{ch}{path.suffix}")
        plot_monitor(tr, out, fits=halves, fits_label="offline fit, each half", whole=whole,
                     title=f"gyrodrift replay: monitor of {ch} (float state, as the target)")
        written.append(out)
    return written
