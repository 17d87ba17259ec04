"""Peak resident memory of the analysis commands on a large .npy record.

Writes a float64 white-noise record of N samples (deg/h, 400 Hz) into a temporary directory
in pieces (this process never holds it), and for ``fit-full-rate`` a second one with a random
walk whose Allan minimum lies at 0.13 s (52 samples), so that ``fit`` fits the drift model at
the record's own rate instead of on block averages; runs each command as its own process
(``python -m gyrodrift CMD record.npy ...``) and reads that process's peak resident set size
from ``os.wait4`` (``ru_maxrss``: resident pages, including mapped file pages), then prints
a table: command, samples, peak MB, budget MB, ok. The budgets are stated in BUDGET_MB and
do not depend on the record's length; docs/validation/memory.md holds the table on 1e8 and
1e7 samples, and tests/test_peak_memory.py runs this script on 2e7 samples (fit-full-rate,
about 5 minutes there on a loaded machine, and compare, about 3 minutes, are measured here
only). filter, compare and identify-gmwm-bootstrap also write temporary files (the output,
the filtered records, the bootstrap records) beside the record or in TMPDIR.

Record variants (``--variants``, or ``COMMAND:VARIANT`` in ``--commands``): ``npy`` (the
default: 1-D float64 in deg/h, memory-mapped as it is), and the forms the reader normalizes
in pieces into a temporary file: ``rad-s`` (1-D float64 in rad/s, ``--gyro-units rad/s``),
``float32`` (1-D float32 in deg/h), ``2d`` ((n, 3) float64 in deg/h, the middle column:
``--column 1``, characterize ``--column-channels=-,gyro_z,-``), ``drop-nan`` (1-D float64
with every 1000th sample NaN, ``--drop-nan``) and ``text`` (CSV ``t_s,gyro_z``, the rate from
its time column; parsing it takes about 0.5-1 us per line).
ROS bag variants, for ``characterize`` only (BAG_VARIANTS): ``rosbag1`` (a ``.bag``),
``mcap`` and ``db3`` (a rosbag2 directory with MCAP or SQLite storage), one
``sensor_msgs/msg/Imu`` topic at 400 Hz (gyro white noise of 30 deg/h per sample in rad/s, the
accelerometer 1 g on z plus noise); `write_bag_variant` patches the varying fields into one
message serialized by rosbags (about 6 us per message; the reader deserializes each message,
20-30 us).

IMU log variants (LOG_VARIANTS; they carry their rate and units, so no ``--rate-hz`` or units
flag is given, and the single-channel commands read gyro z): ``bin`` (the replay harness's
binary frame log, 42 bytes per sample), ``blf`` (a Vector BLF CAN log written by python-can,
four frames per sample: about 25 us per sample to write, 60 us to read), ``replay-csv``
(the harness's IMU CSV) and ``psins`` (a PSINS ``.imu`` text log of integer counts). The gyro
holds the same white-noise level as the other variants (30 deg/h per sample, in rad/s), the
accelerometer white noise around 1 g on z.

Usage: python benchmarks/peak_memory.py [--samples N ...] [--commands allan,fit:rad-s,...]
[--variants npy,rad-s,...] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

#: Peak resident memory each command may use, MB (10^6 bytes), whatever the record length:
#: the interpreter with numpy, scipy and the command's libraries (about 100-170 MB) plus the
#: command's bounded working set. A command that held one float64 copy of a 2e7-sample
#: record (160 MB) on top of its libraries would exceed these at that size.
BUDGET_MB: dict[str, float] = {
    "allan": 250.0,
    "identify": 250.0,
    "identify-gmwm": 250.0,
    "fit": 300.0,
    "fit-full-rate": 300.0,
    "characterize": 250.0,
    "psd": 250.0,
    # the record filtered by the AR(2)-Kalman filter (the default), written to a .npy file
    "filter": 250.0,
    # the 2006 paper's Table 1 (five filtered records, their Allan deviations and PSDs)
    "compare": 300.0,
    # two parametric-bootstrap replicates of the record's length
    "identify-gmwm-bootstrap": 250.0,
    # the offline db8 wavelet denoiser in the float32 lifting core (the MCU build's)
    "filter-wavelet-float": 250.0,
}
#: Tighter budgets for a command on one record variant, MB: `allan` on a BLF CAN log reads
#: it at about 60 us per sample (python-can and cantools, four frames per sample), so the
#: test runs it on 2.5e5 samples, where the whole-log read (about 450 bytes of Python
#: objects per sample: 178 MB peak) stays under the command's 250 MB; 160 MB is above the
#: read in blocks (129 MB) and below that.
VARIANT_BUDGET_MB: dict[tuple[str, str], float] = {("allan", "blf"): 160.0}
#: The commands run when --commands is not given (fit-full-rate takes half an hour at 1e8
#: samples on a loaded 2-core machine).
DEFAULT_COMMANDS = ("allan", "identify", "identify-gmwm", "fit", "characterize", "psd")

RATE_HZ = 400.0

#: Record variants: the extra command-line arguments of the single-channel commands and of
#: characterize (module docstring).
VARIANTS: dict[str, tuple[list[str], list[str]]] = {
    "npy": ([], []),
    "rad-s": (["--gyro-units", "rad/s"], ["--gyro-units", "rad/s"]),
    "float32": ([], []),
    "2d": (["--column", "1"], ["--column-channels=-,gyro_z,-"]),
    "drop-nan": (["--drop-nan"], ["--drop-nan"]),
    "text": ([], []),
}
#: ROS bag variants (module docstring): the record's file or directory name.
BAG_VARIANTS: dict[str, str] = {"rosbag1": "record.bag", "mcap": "record-mcap",
                                "db3": "record-db3"}
#: IMU log variants (module docstring) and their file suffixes.
LOG_VARIANTS: dict[str, str] = {"bin": ".bin", "blf": ".blf", "replay-csv": ".csv",
                                "psins": ".imu"}


def command_args(command: str, record: Path, out: Path, variant: str = "npy") -> list[str]:
    """The command line run for `command` (its JSON output, no plots or reports) on the
    record of `variant` (VARIANTS; its units flag replaces deg/h)."""
    if variant in BAG_VARIANTS:
        return bag_command_args(command, record)
    single, multi = VARIANTS.get(variant, ([], []))
    extra = multi if command == "characterize" else single
    units = "rad/s" if variant == "rad-s" else "deg/h"
    rate = ["--rate-hz", f"{RATE_HZ:g}", "--gyro-units", units,
            *[a for a in extra if a not in ("--gyro-units", "rad/s")]]
    if variant in LOG_VARIANTS:
        rate = []  # the log's own time base and units
    walk = str(record.with_name("walk.npy"))
    return {
        "allan": ["allan", str(record), *rate, "--json"],
        "identify": ["identify", str(record), *rate, "--json"],
        "identify-gmwm": ["identify", str(record), *rate, "--identifier", "gmwm", "--json"],
        "fit": ["fit", str(record), *rate, "--json"],
        "fit-full-rate": ["fit", walk, *rate, "--json"],
        "characterize": ["characterize", str(record), *rate, "--json"],
        "psd": ["psd", str(record), *rate, "--json", "--png", str(out.with_suffix(".png"))],
        "filter": ["filter", str(record), *rate, "-o", str(out.with_name("filtered.npy")),
                   "--json"],
        "compare": ["compare", str(record), *rate, "--out-dir", str(out.with_name("compare")),
                    "--json"],
        "identify-gmwm-bootstrap": ["identify", str(record), *rate, "--identifier", "gmwm",
                                    "--bootstrap", "2", "--json"],
        "filter-wavelet-float": ["filter", str(record), *rate, "-o",
                                 str(out.with_name("filtered.npy")), "--filter", "wavelet",
                                 "--core", "float", "--json"],
    }[command]


def bag_command_args(command: str, record: Path) -> list[str]:
    """The command line of `command` on a ROS bag variant: characterize only (the
    single-channel commands read no bags), the rate from the messages' time stamps, the units
    sensor_msgs/msg/Imu carries."""
    if command != "characterize":
        raise SystemExit(f"{command}: ROS bag variants are read by characterize only")
    return ["characterize", str(record), "--gyro-units", "rad/s", "--accel-units", "m/s^2",
            "--json"]


def _imu_template(ts: Any, ros1: bool) -> tuple[bytes, int, list[int]]:
    """One sensor_msgs/msg/Imu serialized by rosbags with marker values, and the byte offsets
    of its header stamp (sec, nanosec) and of its six values."""
    types = ts.types
    vec, marks = types["geometry_msgs/msg/Vector3"], [1.0e300 + k * 1.0e290 for k in range(6)]
    header = {"stamp": types["builtin_interfaces/msg/Time"](sec=0x11223344,
                                                            nanosec=0x05667788),
              "frame_id": "imu", **({"seq": 0} if ros1 else {})}
    z9 = np.zeros(9)
    msg = types["sensor_msgs/msg/Imu"](
        header=types["std_msgs/msg/Header"](**header),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=z9, angular_velocity=vec(x=marks[0], y=marks[1], z=marks[2]),
        angular_velocity_covariance=z9,
        linear_acceleration=vec(x=marks[3], y=marks[4], z=marks[5]),
        linear_acceleration_covariance=z9)
    serialize = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    raw = bytes(serialize(msg, "sensor_msgs/msg/Imu"))
    at_t = raw.find(np.array([0x11223344, 0x05667788], dtype="<u4").tobytes())
    at_v = [raw.find(np.array([m], dtype="<f8").tobytes()) for m in marks]
    assert at_t >= 0 and min(at_v) >= 0, "marker not found in the serialized message"
    return raw, at_t, at_v


def write_bag_variant(path: Path, n: int, variant: str, chunk: int = 1 << 16) -> None:
    """N sensor_msgs/msg/Imu messages on /imu at RATE_HZ in the ROS bag of `variant`
    (BAG_VARIANTS), written by rosbags' writers piece by piece; bag time = header stamp."""
    from rosbags.typesys import Stores, get_typestore

    ros1 = variant == "rosbag1"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:
        from rosbags.rosbag1 import Writer as Writer1

        writer: Any = Writer1(path)
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP
                        if variant == "mcap" else StoragePlugin.SQLITE3)
    raw, at_t, at_v = _imu_template(ts, ros1)
    rng = np.random.default_rng(0)
    to_rad_s = np.pi / 180.0 / 3600.0
    t0_ns, step_ns = 1_700_000_000 * 10**9, round(1e9 / RATE_HZ)
    with writer as w:
        conn = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
        for start in range(0, n, chunk):
            m = min(chunk, n - start)
            msgs = np.frombuffer(raw * m, dtype=np.uint8).reshape(m, len(raw)).copy()
            t_ns = t0_ns + (start + np.arange(m, dtype=np.int64)) * step_ns
            stamp = np.column_stack([t_ns // 10**9, t_ns % 10**9]).astype("<u4")
            msgs[:, at_t:at_t + 8] = stamp.view(np.uint8).reshape(m, 8)
            vals = np.empty((m, 6))
            vals[:, :3] = rng.standard_normal((m, 3)) * 30.0 * to_rad_s
            vals[:, 3:] = rng.standard_normal((m, 3)) * 1e-3 + [0.0, 0.0, 9.80665]
            for j, at in enumerate(at_v):
                msgs[:, at:at + 8] = vals[:, j].astype("<f8").view(np.uint8).reshape(m, 8)
            for k in range(m):
                w.write(conn, int(t_ns[k]), msgs[k].tobytes())


def write_record(path: Path, n: int, walk: bool = False, chunk: int = 1 << 22) -> None:
    """N samples of white noise (30 deg/h per sample) written piece by piece; with `walk`, plus
    a random walk of 1 deg/h per sample (the Allan minimum at sqrt(3) 30 = 52 samples)."""
    mm = np.lib.format.open_memmap(path, mode="w+", dtype=np.float64, shape=(n,))
    rng = np.random.default_rng(1 if walk else 0)
    level = 0.0
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        piece = rng.standard_normal(stop - start) * 30.0
        if walk:
            steps = np.cumsum(rng.standard_normal(stop - start)) + level
            level = float(steps[-1])
            piece += steps
        mm[start:stop] = piece
        mm.flush()
    del mm


def write_variant(path: Path, n: int, variant: str, chunk: int = 1 << 22) -> None:
    """The white-noise record of `write_record` (the same samples, 30 deg/h per sample) in
    the form of `variant` (VARIANTS), written piece by piece."""
    if variant in BAG_VARIANTS:
        write_bag_variant(path, n, variant)
        return
    if variant in LOG_VARIANTS:
        write_log_variant(path, n, variant)
        return
    rng = np.random.default_rng(0)
    if variant == "text":
        with open(path, "w") as fh:
            fh.write("t_s,gyro_z\n")
            for start in range(0, n, chunk):
                stop = min(n, start + chunk)
                t = np.arange(start, stop) / RATE_HZ
                x = rng.standard_normal(stop - start) * 30.0
                np.savetxt(fh, np.column_stack([t, x]), fmt="%.4f,%.6f")
        return
    dtype = np.float32 if variant == "float32" else np.float64
    shape: tuple[int, ...] = (n, 3) if variant == "2d" else (n,)
    mm = np.lib.format.open_memmap(path, mode="w+", dtype=dtype, shape=shape)
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        piece = rng.standard_normal(stop - start) * 30.0
        if variant == "rad-s":
            piece *= np.pi / 180.0 / 3600.0
        if variant == "drop-nan":
            piece[(np.arange(start, stop) % 1000) == 999] = np.nan
        if variant == "2d":
            mm[start:stop, 1] = piece
            mm[start:stop, 0] = -piece
            mm[start:stop, 2] = 0.5 * piece
        else:
            mm[start:stop] = piece
        mm.flush()
    del mm


def write_log_variant(path: Path, n: int, variant: str, chunk: int = 1 << 16) -> None:
    """N samples of the IMU log `variant` (LOG_VARIANTS), written piece by piece: gyro white
    noise of 30 deg/h per sample (in rad/s), accelerometer white noise of 0.01 m/s^2 around
    1 g on z, 400 Hz. The binary log and the CSV through the package's frame encoder and
    column layout, the BLF log through python-can's writer (each sample's four frames in the
    DBC's layout, checked against the package's encoder), the PSINS log as integer counts
    (0.01 arcsec and 1 ug*s per count)."""
    from gyrodrift.codecs import encode_sample
    from gyrodrift.codecs.wire import encode_frames, make_samples
    from gyrodrift.io.imu_log import CSV_COLUMNS

    rng = np.random.default_rng(0)
    arcsec = np.pi / 180.0 / 3600.0
    dt = 1.0 / RATE_HZ

    def pieces() -> Iterator[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
        for start in range(0, n, chunk):
            m = min(n, start + chunk) - start
            gyro = rng.standard_normal((m, 3)) * 30.0 * arcsec  # 30 deg/h = 30 arcsec/s
            accel = rng.standard_normal((m, 3)) * 1e-2 + np.array([0.0, 0.0, 9.80665])
            yield start, (start + np.arange(m)) * dt, gyro, accel

    if variant == "blf":
        import can

        with can.Logger(str(path)) as w:
            for start, t, gyro, accel in pieces():
                values = np.concatenate([gyro, accel], axis=1).astype("<f4")
                seq = ((start + np.arange(t.size)) % 65536).astype("<u2")
                # the DBC layout of the four frames (little-endian: X, Y as float32; Z as
                # float32, then Seq and Flags as uint16), checked against the package's
                # encoder (cantools) on the piece's first sample
                data = np.zeros((t.size, 4, 8), dtype=np.uint8)
                for role, half in enumerate((0, 0, 3, 3)):
                    if role % 2 == 0:
                        data[:, role] = values[:, half:half + 2].view(np.uint8)
                    else:
                        data[:, role, :4] = values[:, half + 2:half + 3].view(np.uint8)
                        data[:, role, 4:6] = seq[:, None].view(np.uint8)
                want = [bytes(m.data) for m in encode_sample(int(seq[0]), values[0])]
                assert [data[0, r].tobytes() for r in range(4)] == want
                for k in range(t.size):
                    for role in range(4):
                        w.on_message_received(can.Message(
                            timestamp=float(t[k]), arbitration_id=0x100 + role,
                            is_extended_id=False, data=data[k, role].tobytes(), channel=0))
        return
    with open(path, "wb") as fh:
        if variant == "psins":
            fh.write(b"% PSINS IMU log (benchmark)\n0 0 0 0 0 0\n"
                     + f"34.2 108.9 380 0 {1e3 * dt:g} 9.79\n".encode()
                     + b"0.01 0.01 0.01 1 1 1\n")
        elif variant == "replay-csv":
            fh.write((",".join(CSV_COLUMNS) + "\n").encode())
        for start, t, gyro, accel in pieces():
            if variant == "psins":
                counts = np.column_stack([np.round(gyro * dt / (0.01 * arcsec)),
                                          np.round(accel * dt / 9.80665e-6)])
                np.savetxt(fh, counts, fmt="%d")
                continue
            s = make_samples(t, gyro, accel, seq0=start)
            if variant == "bin":
                fh.write(encode_frames(s).tobytes())
            else:  # the columns of the harness's CSV; %.9g gives a float32 back exactly
                np.savetxt(fh, np.column_stack([s.t_s, s.seq, s.flags, s.channels]),
                           fmt=["%.6f", "%d", "%d"] + ["%.9g"] * 6, delimiter=",")


def peak_mb(argv: list[str], cwd: Path) -> tuple[float, int, float, str]:
    """(peak RSS MB, exit code, wall s, last stderr line) of one run of `argv`."""
    t0 = time.perf_counter()
    with open(cwd / "stderr.txt", "wb") as err:
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=err, cwd=cwd)
        _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - t0
    lines = (cwd / "stderr.txt").read_text(errors="replace").strip().splitlines()
    return usage.ru_maxrss * 1024 / 1e6, proc.returncode, wall, lines[-1] if lines else ""


def measure(samples: int, commands: list[str]) -> list[dict[str, object]]:
    """Run each command (``COMMAND`` or ``COMMAND:VARIANT``) on a record of `samples`
    samples and return its row (peak MB, budget, ok, exit code, wall time)."""
    rows: list[dict[str, object]] = []
    with tempfile.TemporaryDirectory(prefix="gyrodrift-mem.") as tmp:
        d = Path(tmp)
        rec = d / "record.npy"
        variants = sorted({c.partition(":")[2] or "npy" for c in commands})
        # In a child: Linux carries a process's peak RSS over to the children it forks
        # (and across exec), so this process must never have held the record's pages.
        if any(c.partition(":")[2] in ("", "npy") for c in commands):
            subprocess.run([sys.executable, __file__, "--write", str(rec), str(samples)],
                           check=True)
        if "fit-full-rate" in commands:
            subprocess.run([sys.executable, __file__, "--write-walk", str(d / "walk.npy"),
                            str(samples)], check=True)
        for v in variants:
            if v != "npy":
                subprocess.run([sys.executable, __file__, "--write-variant", v,
                                str(_variant_path(d, v)), str(samples)], check=True)
        for item in commands:
            cmd, _, variant = item.partition(":")
            variant = variant or "npy"
            path = rec if variant == "npy" else _variant_path(d, variant)
            argv = [sys.executable, "-m", "gyrodrift",
                    *command_args(cmd, path, d / "out", variant)]
            peak, code, wall, last = peak_mb(argv, d)
            budget = VARIANT_BUDGET_MB.get((cmd, variant), BUDGET_MB[cmd])
            rows.append({"command": cmd, "samples": samples, "peak_mb": round(peak, 1),
                         "budget_mb": budget, "ok": code == 0 and peak <= budget,
                         "exit": code, "wall_s": round(wall, 1), "stderr": last,
                         "variant": variant})
    return rows


def _variant_path(d: Path, variant: str) -> Path:
    if variant in BAG_VARIANTS:
        return d / BAG_VARIANTS[variant]
    if variant in LOG_VARIANTS:
        return d / f"record-{variant}{LOG_VARIANTS[variant]}"
    return d / (f"record-{variant}.csv" if variant == "text" else f"record-{variant}.npy")


def main() -> int:
    if sys.argv[1:2] in (["--write"], ["--write-walk"]):
        write_record(Path(sys.argv[2]), int(sys.argv[3]), walk=sys.argv[1] == "--write-walk")
        return 0
    if sys.argv[1:2] == ["--write-variant"]:
        write_variant(Path(sys.argv[3]), int(sys.argv[4]), sys.argv[2])
        return 0
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=float, nargs="+", default=[1e8, 1e7])
    ap.add_argument("--commands", default=",".join(DEFAULT_COMMANDS))
    ap.add_argument("--variants", default="npy",
                    help="record variants for the commands without one (VARIANTS)")
    ap.add_argument("--json", action="store_true", help="rows as JSON on stdout")
    a = ap.parse_args()
    commands = [c if ":" in c or v == "npy" else f"{c}:{v}"
                for v in a.variants.split(",") if v for c in a.commands.split(",") if c]
    rows = [r for n in a.samples for r in measure(int(n), commands)]
    if a.json:
        print(json.dumps(rows))
        return 0
    print("| command | variant | samples | peak MB | budget MB | ok | exit | wall s |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['command']} | {r['variant']} | {r['samples']:.0e} | {r['peak_mb']:.0f} | "
              f"{r['budget_mb']:.0f} | {'yes' if r['ok'] else 'NO'} | {r['exit']} | "
              f"{r['wall_s']} |")
    for r in rows:
        if r["exit"] != 0:
            print(f"{r['command']}: {r['stderr']}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
