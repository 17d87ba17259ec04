"""Outputs never replace what is at the target (gyrodrift.io.atomic, docs/guides/output-files.md).

Every kind of target, for several commands: a symbolic link is followed (the file it leads to
is replaced, the link stays), a FIFO gets the bytes and stays a FIFO, a device is written
through and stays a device (``/dev/null``: exit 0; ``/dev/full``: one line, exit 2), a
directory is refused with one line, and ``-o /dev/stdout`` puts the file, and only the file,
on stdout.

The device targets are nodes made in the test's own directory (the same major/minor numbers
as /dev/null and /dev/full), so a regression can never replace the system's devices; where
nodes cannot be made, links to the system's devices stand in (they are followed to the
device), except as root, where that would risk them.
"""

from __future__ import annotations

import errno
import json
import os
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import tomllib
import yaml
from cli_units import with_units
from gyrodrift.cli import main
from gyrodrift.io.atomic import atomic_output, atomic_write_text, output_target

RATE_HZ = "100"


# ------------------------------------------------------------------------------ commands

@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    from gyrodrift.imu.config import default_config, write_config

    d = tmp_path_factory.mktemp("inputs")
    rng = np.random.default_rng(7)
    np.save(d / "rec.npy", rng.normal(0.0, 1.0, 2000))
    np.save(d / "imu.npy", rng.normal(0.0, 1e-4, (2048, 3)))
    write_config(default_config(), d / "processor.toml")
    return {"rec": d / "rec.npy", "imu": d / "imu.npy", "cfg": d / "processor.toml"}


#: command name -> (argv with {out} for the output, the output's suffix)
COMMANDS: dict[str, tuple[tuple[str, ...], str]] = {
    "config-write-default": (("config", "write-default", "-o", "{out}"), ".toml"),
    "config-emit-cpp": (("config", "emit-cpp", "{cfg}", "-o", "{out}"), ".hpp"),
    "simulate": (("simulate", "-o", "{out}", "--samples", "300", "--arw-deg-rt-h", "0.1"),
                 ".npy"),
    "filter": (("filter", "{rec}", "--rate-hz", RATE_HZ, "-o", "{out}"), ".npy"),
    "allan-csv": (("allan", "{rec}", "--rate-hz", RATE_HZ, "--csv", "{out}"), ".csv"),
    "psd-png": (("psd", "{rec}", "--rate-hz", RATE_HZ, "--png", "{out}"), ".png"),
    "fit-json": (("fit", "{rec}", "--rate-hz", RATE_HZ, "-o", "{out}"), ".json"),
    "characterize-kalibr": (("characterize", "{imu}", "--rate-hz", RATE_HZ, "--gyro-units",
                             "rad/s", "--kalibr", "{out}"), ".yaml"),
    "characterize-html": (("characterize", "{imu}", "--rate-hz", RATE_HZ, "--gyro-units",
                           "rad/s", "--html", "{out}"), ".html"),
}
#: the slow commands run for fewer target kinds (the rule is one function for all)
CHEAP = [c for c in COMMANDS if not c.startswith(("characterize", "fit"))]


def run(inputs: dict[str, Path], command: str, out: Path,
        capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    argv, _ = COMMANDS[command]
    code = main(with_units([a.format(out=out, **inputs) for a in argv]))
    o, e = capsys.readouterr()
    return code, o, e


def valid_output(suffix: str, data: bytes) -> None:
    """The bytes are a whole output of the kind the suffix names (parsed, not compared)."""
    assert data, "no bytes arrived"
    if suffix == ".toml":
        assert tomllib.loads(data.decode())["schema"] == "gyrodrift.processor"
    elif suffix == ".hpp":
        assert data.rstrip().endswith(b"}  // namespace gyrodrift_config")
    elif suffix == ".npy":
        import io

        assert np.load(io.BytesIO(data)).ndim == 1
    elif suffix == ".csv":
        lines = data.decode().splitlines()
        assert len(lines) > 3 and lines[0].startswith("tau_s")
    elif suffix == ".png":
        assert data.startswith(b"\x89PNG\r\n\x1a\n") and data.endswith(b"IEND\xaeB`\x82")
    elif suffix == ".json":
        assert "chosen" in json.loads(data)
    elif suffix == ".yaml":
        assert "gyroscope_noise_density" in yaml.safe_load(data)
    elif suffix == ".html":
        assert data.lstrip().lower().startswith(b"<!doctype html") and b"</html>" in data
    else:
        raise AssertionError(suffix)


def one_line_error(code: int, err: str, *needles: str) -> None:
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in lines[0], lines[0]


# ------------------------------------------------------------------------ target kinds

def device(tmp_path: Path, name: str, minor: int) -> Path:
    """A character device with /dev/null's (minor 3) or /dev/full's (minor 7) numbers."""
    node = tmp_path / name
    try:
        os.mknod(node, stat.S_IFCHR | 0o666, os.makedev(1, minor))
        os.close(os.open(node, os.O_WRONLY))  # a file system mounted nodev refuses it
        return node
    except OSError:
        node.unlink(missing_ok=True)
    if os.geteuid() == 0:
        pytest.skip("cannot make a device node here, and as root a regression could replace "
                    "the system's own device")
    system = {3: "/dev/null", 7: "/dev/full"}[minor]
    node.symlink_to(system)
    return node


def is_device(p: Path, minor: int) -> bool:
    st = os.stat(p)
    return stat.S_ISCHR(st.st_mode) and os.minor(st.st_rdev) == minor


class FifoReader:
    """Reads everything written to a FIFO, concurrently (an output larger than the pipe
    buffer must not block the writer). The FIFO is opened non-blocking for reading first, so
    a writer's open never waits; `result()` after the command returns drains the rest."""

    def __init__(self, fifo: Path) -> None:
        self.fd = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)
        self.chunks: list[bytes] = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._loop, daemon=True)
        self.thread.start()

    def _read(self) -> bool:
        try:
            b = os.read(self.fd, 1 << 16)
        except BlockingIOError:
            return False
        if b:
            self.chunks.append(b)
        return bool(b)

    def _loop(self) -> None:
        while not self.stop.is_set():
            if not self._read():
                time.sleep(0.002)

    def result(self) -> bytes:
        self.stop.set()
        self.thread.join()
        while self._read():  # the writer has closed: what is left is in the pipe
            pass
        os.close(self.fd)
        return b"".join(self.chunks)


# ------------------------------------------------------------------------------ the rule

@pytest.mark.parametrize("command", [*CHEAP, "fit-json", "characterize-kalibr"])
def test_symlink_is_followed_and_stays_a_link(tmp_path: Path, inputs: dict[str, Path],
                                              command: str, capsys) -> None:
    """Before: the link was replaced by a regular file and its file kept the old bytes."""
    sfx = COMMANDS[command][1]
    real = tmp_path / "store" / f"real{sfx}"
    real.parent.mkdir()
    real.write_bytes(b"old")
    link = tmp_path / f"out{sfx}"
    link.symlink_to(real)
    code, _, err = run(inputs, command, link, capsys)
    assert code == 0, err
    assert link.is_symlink() and os.readlink(link) == str(real)
    valid_output(sfx, real.read_bytes())
    assert sorted(p.name for p in real.parent.iterdir()) == [real.name]  # no temporary left


@pytest.mark.parametrize("command", [*CHEAP, "characterize-kalibr", "characterize-html"])
def test_fifo_gets_the_bytes_and_stays_a_fifo(tmp_path: Path, inputs: dict[str, Path],
                                              command: str, capsys) -> None:
    """Before: the FIFO was replaced by a regular file; its reader got nothing."""
    sfx = COMMANDS[command][1]
    fifo = tmp_path / f"out{sfx}"
    os.mkfifo(fifo)
    reader = FifoReader(fifo)
    try:
        code, _, err = run(inputs, command, fifo, capsys)
    finally:
        data = reader.result()
    assert code == 0, err
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    valid_output(sfx, data)


@pytest.mark.parametrize("command", [*CHEAP, "characterize-html"])
def test_null_device_is_written_through(tmp_path: Path, inputs: dict[str, Path], command: str,
                                        capsys) -> None:
    """Before: exit 0 and the device node replaced by a regular file."""
    null = device(tmp_path, f"null{COMMANDS[command][1]}", 3)
    code, _, err = run(inputs, command, null, capsys)
    assert code == 0, err
    assert is_device(null, 3)


@pytest.mark.parametrize("command", [*CHEAP, "characterize-kalibr"])
def test_full_device_is_a_one_line_error(tmp_path: Path, inputs: dict[str, Path],
                                         command: str, capsys) -> None:
    """Before: exit 0, the device replaced by a file holding the output."""
    full = device(tmp_path, f"full{COMMANDS[command][1]}", 7)
    code, _, err = run(inputs, command, full, capsys)
    one_line_error(code, err, "No space left on device", str(full))
    assert is_device(full, 7)


@pytest.mark.parametrize("command", [*CHEAP, "fit-json", "characterize-kalibr",
                                     "characterize-html"])
def test_directory_is_a_one_line_error(tmp_path: Path, inputs: dict[str, Path], command: str,
                                       capsys) -> None:
    d = tmp_path / f"out{COMMANDS[command][1]}"
    d.mkdir()
    (d / "keep").write_text("x")
    code, _, err = run(inputs, command, d, capsys)
    one_line_error(code, err, "is a directory")
    assert sorted(p.name for p in d.iterdir()) == ["keep"]


def test_output_checked_before_the_work(tmp_path: Path, inputs: dict[str, Path],
                                        capsys) -> None:
    """characterize, fit and identify check --kalibr/--html/-o/--png before the analysis:
    before, a directory or a missing directory failed only after it."""
    for argv in (("characterize", str(inputs["imu"]), "--rate-hz", RATE_HZ, "--kalibr",
                  str(tmp_path / "no" / "k.yaml")),
                 ("characterize", str(inputs["imu"]), "--rate-hz", RATE_HZ, "--html",
                  str(tmp_path)),
                 ("fit", str(inputs["rec"]), "--rate-hz", RATE_HZ, "-o",
                  str(tmp_path / "no" / "f.json")),
                 ("identify", str(inputs["rec"]), "--rate-hz", RATE_HZ, "--png",
                  str(tmp_path / "no" / "i.png"))):
        t0 = time.process_time()
        code = main(with_units(argv))
        one_line_error(code, capsys.readouterr().err)
        # The analysis costs a second or more of CPU; refusing the path costs milliseconds.
        # (CPU time, not wall time: the check holds on a loaded machine.)
        assert time.process_time() - t0 < 0.5, argv


# ----------------------------------------------------------------------------- stdout

def _gyrodrift(*argv: str, **kw) -> subprocess.CompletedProcess[bytes]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    return subprocess.run([sys.executable, "-m", "gyrodrift", *argv], env=env, timeout=120,
                          check=False, **kw)


def test_output_to_stdout_is_the_file_alone(tmp_path: Path) -> None:
    """`-o /dev/stdout`: the configuration, and only it, on stdout (a pipe, then a file);
    the "wrote" line goes to stderr. /proc/self/fd/1 is the same file as /dev/stdout, and a
    regression cannot replace anything under /proc."""
    from gyrodrift.imu.config import default_config, dumps_config

    want = dumps_config(default_config()).encode()
    res = _gyrodrift("config", "write-default", "-o", "/proc/self/fd/1", capture_output=True)
    assert res.returncode == 0, res.stderr
    assert res.stdout == want
    assert b"wrote" in res.stderr
    with (tmp_path / "redirected.toml").open("wb") as fh:
        res = _gyrodrift("config", "write-default", "-o", "/proc/self/fd/1", stdout=fh,
                         stderr=subprocess.PIPE)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "redirected.toml").read_bytes() == want


# --------------------------------------------------------------------- the library rule

def test_atomic_output_rule_directly(tmp_path: Path) -> None:
    # A dangling link creates the file it names; the link stays.
    link = tmp_path / "dangling.txt"
    link.symlink_to(tmp_path / "target.txt")
    atomic_write_text(link, "a\n")
    assert link.is_symlink() and (tmp_path / "target.txt").read_text() == "a\n"
    # A link to a directory, and a loop of links, are refused before anything is written.
    (tmp_path / "d").mkdir()
    (tmp_path / "to_dir").symlink_to(tmp_path / "d")
    with pytest.raises(IsADirectoryError):
        atomic_write_text(tmp_path / "to_dir", "x")
    (tmp_path / "loop1").symlink_to(tmp_path / "loop2")
    (tmp_path / "loop2").symlink_to(tmp_path / "loop1")
    with pytest.raises(OSError) as exc:
        atomic_write_text(tmp_path / "loop1", "x")
    assert exc.value.errno == errno.ELOOP
    # A missing directory names it.
    with pytest.raises(FileNotFoundError, match="does not exist"):
        atomic_write_text(tmp_path / "nodir" / "x.txt", "x")
    assert sorted(p.name for p in (tmp_path / "d").iterdir()) == []


def test_failed_writer_writes_nothing_to_a_fifo(tmp_path: Path) -> None:
    fifo = tmp_path / "out.npy"
    os.mkfifo(fifo)
    assert output_target(fifo).kind == "stream"
    reader = FifoReader(fifo)
    try:
        with pytest.raises(RuntimeError), atomic_output(fifo) as tmp:
            np.save(tmp, np.zeros(10))
            raise RuntimeError("boom")
    finally:
        data = reader.result()
    assert data == b"" and stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_suffix_of_the_temporary_file(tmp_path: Path) -> None:
    """A suffix-less stream target: the writer still gets the suffix it needs."""
    null = device(tmp_path, "nul", 3)
    with atomic_output(null, suffix=".npy") as tmp:
        np.save(tmp, np.zeros(3))  # numpy would append .npy to a name without it
        assert tmp.suffix == ".npy"
    assert is_device(null, 3)


def test_a_writer_that_misses_the_temporary_file_is_named(tmp_path: Path) -> None:
    """numpy.save appends .npy to a suffix-less name: the output rule says so instead of
    failing on a temporary path the caller never saw."""
    null = device(tmp_path, "nul", 3)
    with pytest.raises(AssertionError, match="suffix="), atomic_output(null) as tmp:
        np.save(tmp, np.zeros(3))
    assert is_device(null, 3)


def test_fit_output_to_stdout_is_the_configuration_alone(tmp_path: Path) -> None:
    """`fit -o /dev/stdout` (here /proc/self/fd/1, the same file): stdout carries the processor
    configuration and nothing else, the table goes to stderr. Before, a suffix-less stream was
    refused, and a stream with a suffix got the table printed into it after the file."""
    rec = tmp_path / "rec.npy"
    np.save(rec, np.random.default_rng(3).normal(0.0, 1.0, 3000))
    res = _gyrodrift("fit", str(rec), "--rate-hz", RATE_HZ, "--gyro-units", "deg/h", "-o",
                     "/proc/self/fd/1", capture_output=True)
    assert res.returncode == 0, res.stderr
    cfg = tomllib.loads(res.stdout.decode())  # the whole of stdout is one TOML document
    assert cfg["schema"] == "gyrodrift.processor"
    assert b"chosen:" in res.stderr and b"chosen:" not in res.stdout
    # A link named .json that leads to stdout: the JSON alone on stdout, --json to stderr.
    link = tmp_path / "out.json"
    link.symlink_to("/proc/self/fd/1")
    res = _gyrodrift("fit", str(rec), "--rate-hz", RATE_HZ, "--gyro-units", "deg/h", "-o",
                     str(link), "--json", capture_output=True)
    assert res.returncode == 0, res.stderr
    assert "chosen" in json.loads(res.stdout)
    assert "chosen" in json.loads(res.stderr)
    assert link.is_symlink()


def test_decode_table_writer_follows_the_output_rule(tmp_path: Path) -> None:
    """The decode table for ``gyrodrift-loop --can-signals`` goes through the one output rule:
    a regular file is replaced whole by a rename (a hard link to the old file keeps the old
    table: nothing was truncated and rewritten in place, which a reader or an interrupted write
    would see half-done), a symbolic link stays a link, a FIFO stays a FIFO and gets the table,
    a device stays a device."""
    from gyrodrift.codecs.can_frames import load_dbc
    from gyrodrift.codecs.can_signals import SignalMap, SignalRef, decode_table_text
    from gyrodrift.io.imu_log import write_decode_table

    names = dict(gx="IMU_GyroXY.GyroX", gy="IMU_GyroXY.GyroY", gz="IMU_GyroZ.GyroZ",
                 ax="IMU_AccelXY.AccelX", ay="IMU_AccelXY.AccelY", az="IMU_AccelZ.AccelZ")
    smap = SignalMap(load_dbc(), {r: SignalRef(*s.split(".")) for r, s in names.items()})
    want = decode_table_text(smap)
    table = tmp_path / "imu.cansig"
    table.write_text("old table\n")
    os.link(table, tmp_path / "old.cansig")
    assert write_decode_table(smap, table) == table
    assert table.read_text() == want
    assert (tmp_path / "old.cansig").read_text() == "old table\n"
    link = tmp_path / "link.cansig"
    link.symlink_to(table.name)
    write_decode_table(smap, link)
    assert link.is_symlink() and table.read_text() == want
    fifo = tmp_path / "fifo.cansig"
    os.mkfifo(fifo)
    reader = FifoReader(fifo)
    try:
        write_decode_table(smap, fifo)
    finally:
        data = reader.result()
    assert data.decode() == want and stat.S_ISFIFO(os.lstat(fifo).st_mode)
    null = device(tmp_path, "nul", 3)
    write_decode_table(smap, null)
    assert is_device(null, 3)
