"""The reference firmware image of the IMU loop on an emulated STM32F405: build it from a
processor configuration (CMake with the Arm cross toolchain, ``cpp/firmware``), check it
against the MCU budget, and run it as a replay target in QEMU's ``netduinoplus2`` board, its
USART1 on a pseudo-terminal.

The image speaks the serial frame format of the host loop and answers a health request frame
with its counters (health report frames, one counter each, under the host loop's names).

Cost: QEMU runs with ``-icount shift=0``, so virtual time advances exactly 1 ns per guest
instruction; the image times each step with SysTick, which counts the board's 168 MHz clock
on that virtual time. Instructions per step = SysTick counts x 1e9 / 168e6 (a count is
5.95 instructions; the median comes from 16-count bins, +-48 instructions). The image takes
the time spent in its receive interrupt out of a step (reported per received byte).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import select
import shutil
import struct
import subprocess
import sys
import tempfile
import time
import tty
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gyrodrift.codecs.serial_frame import (
    FRAME_SIZE,
    SYNC0,
    SYNC1,
    TYPE_HEALTH_REPORT,
    TYPE_HEALTH_REQUEST,
    crc16_ccitt_false,
    encode_frame,
)
from gyrodrift.errors import GyrodriftError
from gyrodrift.imu.config import ProcessorConfig, dumps_config
from gyrodrift.imu.firmware_header import emit_cpp
from gyrodrift.io.atomic import atomic_write_text

__all__ = [
    "ASSUMED_CPI",
    "CORE_CLOCK_HZ",
    "CPU_LOAD_GOAL",
    "FLASH_BUDGET_BYTES",
    "LAG_FIT_STACK_BYTES",
    "LAG_FLASH_BUDGET_BYTES",
    "MONITOR_FLASH_BUDGET_BYTES",
    "MONITOR_RAM_BUDGET_BYTES",
    "QEMU_MACHINE",
    "RAM_BUDGET_BYTES",
    "FirmwareError",
    "FirmwareImage",
    "HealthReport",
    "QemuTarget",
    "budget_violations",
    "build_firmware",
    "cached_firmware",
    "instruction_budget",
    "parse_health_report",
    "step_cost",
]

FLASH_BUDGET_BYTES = 16 * 1024  # code + constants + initial data
RAM_BUDGET_BYTES = 8 * 1024  # data + bss + the stack reserved by the linker script
# The gyro monitor ([monitor] enabled) may add at most this much RAM to the image of the same
# configuration without it.
MONITOR_RAM_BUDGET_BYTES = 2 * 1024
# An image whose monitor re-identifies the drift model ([monitor] reidentify) may take this much
# flash on top of FLASH_BUDGET_BYTES (the re-identification, with the statistics, alarms and float
# math library routines the monitor calls; the STM32F405 has 1 MiB). Without re-identification the
# monitor's image fits FLASH_BUDGET_BYTES itself.
MONITOR_FLASH_BUDGET_BYTES = 16 * 1024
# An image whose monitor re-identifies with the lag identifier may take this much more flash
# again: the fit in software double (the double arithmetic and math library routines, the
# likelihood, its BFGS and the guards' Hessian).
LAG_FLASH_BUDGET_BYTES = 16 * 1024
# An image whose monitor re-identifies with the lag identifier ([monitor] identifier = "lag")
# runs the identifier's fits in thread mode: its stack reserve is this much larger than the
# linker script's (the fit's frames, below which the tick work and the link interrupt nest).
# A bound, not one run's high-water mark: thread mode's frames at a fit (160 B) + the fit's own
# (1140 B measured) + the deepest tick work with the link interrupt in it (1128 B) = 2428 B,
# within the 1536 B of the linker script + this (docs/validation/monitor-firmware.md).
LAG_FIT_STACK_BYTES = 1024
CORE_CLOCK_HZ = 168_000_000  # STM32F405 at full speed (and QEMU's netduinoplus2 clock)
# Assumed cycles per instruction of the M4F running this code from flash (5 wait states with
# the ART accelerator, FPU loads of 2 cycles): an assumption, not a measurement.
ASSUMED_CPI = 1.5
CPU_LOAD_GOAL = 0.05  # the default chain's share of the CPU at the loop rate
QEMU_MACHINE = "netduinoplus2"
QEMU_ICOUNT_SHIFT = 0  # 2**shift ns of virtual time per guest instruction
STARTUP_TIMEOUT_S = 20.0

# Symbols a firmware image must not contain (as the Cortex-M gate checks).
_FORBIDDEN = [
    (re.compile(r"^_?(malloc|free|calloc|realloc|memalign)$|^_(malloc|free|calloc|realloc)_r$"),
     "heap"),
    (re.compile(r"^_Zn[wa]j|^_Zd[la]Pv"), "heap"),
    (re.compile(r"^__aeabi_(d\w+|\w+2d|cd\w+)$|^__(add|sub|mul|div|neg|eq|ne|lt|le|gt|ge|un)df[23]$"
                r"|^__(extendsfdf2|truncdfsf2)$"), "software double"),
    (re.compile(r"^(__cxa_throw|__cxa_allocate_exception|__gxx_personality_v0|_Unwind_\w+)$"),
     "exceptions"),
]


class FirmwareError(GyrodriftError, RuntimeError):
    """The firmware image could not be built, does not fit its budget, or did not run.

    Examples
    --------
    >>> str(FirmwareError("flash 20000 B > 16384 B"))
    'flash 20000 B > 16384 B'
    """


def _repo_root() -> Path:
    """Where cpp/firmware and include/ are: the copy an installed package carries
    (gyrodrift/_firmware), else the source tree this package runs from."""
    here = Path(__file__).resolve()
    packaged = here.parents[1] / "_firmware"
    if (packaged / "cpp" / "firmware" / "CMakeLists.txt").is_file():
        return packaged
    return here.parents[3]


def firmware_source_dir() -> Path:
    """``cpp/firmware``: the installed package's copy, else the source tree's."""
    d = _repo_root() / "cpp" / "firmware"
    if not (d / "CMakeLists.txt").is_file():
        raise FirmwareError(f"firmware sources not found in {d}: reinstall gyrodrift "
                            "(pip install .) or run from a source checkout")
    return d


@dataclass(frozen=True)
class FirmwareImage:
    """A built image: the ELF, its section sizes and what it was built from.

    Examples
    --------
    >>> img = FirmwareImage(Path("x.elf"), text=10000, data=4, bss=5000, stack_reserved=1536)
    >>> img.flash_bytes, img.ram_bytes
    (10004, 6540)
    """

    elf: Path
    text: int
    data: int
    bss: int
    stack_reserved: int
    defines: tuple[str, ...] = ()
    config_text: str = ""
    monitor: bool = False  # built with the gyro monitor ([monitor] enabled)
    reidentify: bool = False  # ... and its re-identification ([monitor] reidentify)
    lag_identifier: bool = False  # ... by the lag identifier (software double: its fit)

    @property
    def flash_bytes(self) -> int:
        return self.text + self.data

    @property
    def ram_bytes(self) -> int:
        return self.data + self.bss + self.stack_reserved

    @property
    def flash_budget_bytes(self) -> int:
        """FLASH_BUDGET_BYTES, plus MONITOR_FLASH_BUDGET_BYTES for an image whose monitor
        re-identifies the drift model, plus LAG_FLASH_BUDGET_BYTES when it does so with the lag
        identifier."""
        reid = self.monitor and self.reidentify
        return (FLASH_BUDGET_BYTES + (MONITOR_FLASH_BUDGET_BYTES if reid else 0)
                + (LAG_FLASH_BUDGET_BYTES if reid and self.lag_identifier else 0))

    def as_dict(self) -> dict[str, Any]:
        return {"elf": str(self.elf), "flash_bytes": self.flash_bytes,
                "ram_bytes": self.ram_bytes, "text": self.text, "data": self.data,
                "bss": self.bss, "stack_reserved": self.stack_reserved,
                "flash_budget_bytes": self.flash_budget_bytes,
                "ram_budget_bytes": RAM_BUDGET_BYTES,
                "defines": list(self.defines)}


def budget_violations(image: FirmwareImage) -> list[str]:
    """Why `image` does not fit the MCU budget (empty: it fits).

    Examples
    --------
    >>> budget_violations(FirmwareImage(Path("x.elf"), 20000, 4, 7000, 1536))
    ['flash 20004 B > 16384 B', 'RAM 8540 B (data + bss + stack) > 8192 B']
    >>> budget_violations(FirmwareImage(Path("x.elf"), 20000, 4, 5000, 1536, monitor=True))
    ['flash 20004 B > 16384 B']
    >>> budget_violations(FirmwareImage(Path("x.elf"), 20000, 4, 5000, 1536, monitor=True,
    ...                                 reidentify=True))
    []
    >>> budget_violations(FirmwareImage(Path("x.elf"), 42000, 4, 3800, 3328, monitor=True,
    ...                                 reidentify=True, lag_identifier=True))
    []
    """
    out = []
    if image.flash_bytes > image.flash_budget_bytes:
        out.append(f"flash {image.flash_bytes} B > {image.flash_budget_bytes} B")
    if image.ram_bytes > RAM_BUDGET_BYTES:
        out.append(f"RAM {image.ram_bytes} B (data + bss + stack) > {RAM_BUDGET_BYTES} B")
    return out


def instruction_budget(loop_rate_hz: float) -> float:
    """Instructions per loop step that keep the chain within CPU_LOAD_GOAL of a 168 MHz M4F
    at `loop_rate_hz`, at ASSUMED_CPI.

    Examples
    --------
    >>> instruction_budget(400.0)
    14000.0
    """
    return CPU_LOAD_GOAL * CORE_CLOCK_HZ / loop_rate_hz / ASSUMED_CPI


def _tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise FirmwareError(f"{name} not found: install it (scripts/setup installs "
                            "gcc-arm-none-eabi, libstdc++-arm-none-eabi-newlib, "
                            "binutils-arm-none-eabi, cmake and qemu-system-arm)")
    return path


def _stack_reserved(ld: Path) -> int:
    m = re.search(r"_stack_size\s*=\s*(0x[0-9A-Fa-f]+|\d+)\s*\)?\s*;", ld.read_text())
    if m is None:
        raise FirmwareError(f"{ld}: no _stack_size")
    return int(m.group(1), 0)


def _section_sizes(elf: Path) -> tuple[int, int, int]:
    out = subprocess.run([_tool("arm-none-eabi-size"), "-A", str(elf)], capture_output=True,
                         text=True, check=True).stdout
    sizes: dict[str, int] = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0].startswith(".") and parts[1].isdigit():
            sizes[parts[0]] = int(parts[1])
    text = sum(sizes.get(s, 0) for s in (".isr_vector", ".text", ".ARM.exidx", ".ARM.extab",
                                          ".preinit_array", ".init_array"))
    return text, sizes.get(".data", 0), sizes.get(".bss", 0)


def _lag_identifier(config: ProcessorConfig) -> bool:
    """Whether `config`'s image holds the monitor's lag identifier (its fit in double)."""
    m = config.monitor
    return bool(m.enabled and m.reidentify and m.identifier == "lag")


def _forbidden_symbols(elf: Path, allow_double: bool = False) -> list[str]:
    out = subprocess.run([_tool("arm-none-eabi-nm"), str(elf)], capture_output=True,
                         text=True, check=True).stdout
    found = []
    for line in out.splitlines():
        name = line.split()[-1] if line.split() else ""
        for pat, why in _FORBIDDEN:
            if pat.search(name) and not (allow_double and why == "software double"):
                found.append(f"{why}: {name}")
    return sorted(set(found))


def build_firmware(config: ProcessorConfig, out_dir: str | os.PathLike[str], *,
                   defines: tuple[str, ...] = (), check_budget: bool = True) -> FirmwareImage:
    """Build the image for `config` in `out_dir` (CMake, the cross toolchain file, the
    configuration emitted as a constexpr header) and check it: no heap, software double or
    exception symbols, and (check_budget) flash and RAM within the budget. `defines` are extra
    preprocessor definitions (the test of the test injects defects with them).

    Raises FirmwareError with the reason when the configuration cannot become an image or
    the image does not fit.

    Examples
    --------
    A soft wavelet threshold has no firmware form; the build refuses it before compiling:

    >>> import tempfile
    >>> from dataclasses import replace
    >>> from gyrodrift.imu.config import default_config
    >>> cfg = default_config()
    >>> gx = cfg.channel("gx")
    >>> soft = cfg.with_channel("gx", replace(gx, stages=(
    ...     replace(gx.stages[0], threshold="soft"), gx.stages[1])))
    >>> try:
    ...     build_firmware(soft, tempfile.mkdtemp())
    ... except FirmwareError as exc:
    ...     print(str(exc).split(":")[0])
    configuration refused for the firmware
    """
    src = firmware_source_dir()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    try:
        emit_cpp(config, namespace="fw_config")  # refuses what has no firmware form
    except (GyrodriftError, ValueError) as exc:
        raise FirmwareError(f"configuration refused for the firmware: {exc}") from None
    text = dumps_config(config)
    cfg_path = out / "config.toml"
    atomic_write_text(cfg_path, text)
    pkg_parent = str(Path(__file__).resolve().parents[2])
    pythonpath = os.pathsep.join([pkg_parent, *[p for p in sys.path if p and p != pkg_parent]])
    build = out / "build"
    lag = _lag_identifier(config)
    stack = _stack_reserved(src / "board" / "stm32f4" / "stm32f405.ld") + (
        LAG_FIT_STACK_BYTES if lag else 0)
    configure = [_tool("cmake"), "-S", str(src), "-B", str(build),
                 f"-DCMAKE_TOOLCHAIN_FILE={src / 'cmake' / 'arm-none-eabi.cmake'}",
                 f"-DGYRODRIFT_CONFIG={cfg_path}", f"-DGYRODRIFT_PYTHON={sys.executable}",
                 f"-DGYRODRIFT_PYTHONPATH={pythonpath}",
                 f"-DGYRODRIFT_FW_DEFINES={';'.join(defines)}",
                 f"-DGYRODRIFT_FW_STACK_BYTES={stack if lag else ''}"]
    _tool("arm-none-eabi-g++")
    for cmd in (configure, [_tool("cmake"), "--build", str(build)]):
        res = subprocess.run(cmd, capture_output=True, text=True)
        if res.returncode != 0:
            log = (res.stdout + res.stderr).strip().splitlines()
            raise FirmwareError("firmware build failed: " + " | ".join(log[-12:]))
    elf = build / "gyrodrift-firmware.elf"
    text_b, data_b, bss_b = _section_sizes(elf)
    image = FirmwareImage(elf, text_b, data_b, bss_b, stack, tuple(defines), text,
                          bool(config.monitor.enabled),
                          bool(config.monitor.enabled and config.monitor.reidentify), lag)
    bad = _forbidden_symbols(elf, allow_double=image.lag_identifier)
    if bad:
        raise FirmwareError(f"{elf}: forbidden symbols ({', '.join(bad)})")
    if check_budget:
        why = budget_violations(image)
        if why:
            raise FirmwareError("the configuration does not fit the MCU budget: "
                                + "; ".join(why))
    return image


def _source_digest() -> str:
    h = hashlib.sha256()
    root = _repo_root()
    for d in (root / "cpp" / "firmware", root / "include" / "gyrodrift"):
        for p in sorted(d.rglob("*")):
            if p.is_file():
                h.update(str(p.relative_to(root)).encode())
                h.update(p.read_bytes())
    return h.hexdigest()


def cached_firmware(config: ProcessorConfig, defines: tuple[str, ...] = (), *,
                    check_budget: bool = True) -> FirmwareImage:
    """The image for `config`, built once per (configuration, defines, sources) in the
    temporary directory and reused.

    Examples
    --------
    Building needs the Cortex-M toolchain and takes tens of seconds, so this is not run here
    (tests/test_firmware_qemu.py does):

    >>> from gyrodrift.imu.config import default_config
    >>> image = cached_firmware(default_config())  # doctest: +SKIP
    >>> image.flash_bytes < 16 * 1024  # doctest: +SKIP
    True
    """
    stack = f"stack +{LAG_FIT_STACK_BYTES if _lag_identifier(config) else 0}"
    key = hashlib.sha256("\n".join([dumps_config(config), *defines, stack, _source_digest()])
                         .encode()).hexdigest()[:16]
    out = Path(tempfile.gettempdir()) / f"gyrodrift-firmware-{key}"
    meta = out / "image.json"
    if not meta.is_file():
        # Built aside and renamed into place: a concurrent session building the same image
        # never sees a half-built directory (the loser of the race uses the winner's).
        tmp = Path(tempfile.mkdtemp(prefix=f"gyrodrift-firmware-{key}-"))
        try:
            image = build_firmware(config, tmp, defines=defines, check_budget=False)
            (tmp / "image.json").write_text(json.dumps(image.as_dict()))
            if out.exists() and not meta.is_file():  # left by an interrupted build
                shutil.rmtree(out, ignore_errors=True)
            os.rename(tmp, out)
        except OSError:
            if not meta.is_file():
                raise
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    m = json.loads(meta.read_text())
    image = FirmwareImage(out / "build" / "gyrodrift-firmware.elf", m["text"], m["data"],
                          m["bss"], m["stack_reserved"], tuple(m["defines"]),
                          dumps_config(config), bool(config.monitor.enabled),
                          bool(config.monitor.enabled and config.monitor.reidentify),
                          _lag_identifier(config))
    if check_budget and budget_violations(image):
        raise FirmwareError("the configuration does not fit the MCU budget: "
                            + "; ".join(budget_violations(image)))
    return image


@dataclass
class HealthReport:
    """A target's health counters by group: top level, rejected, health, firmware.

    Examples
    --------
    >>> rep = HealthReport(top={"frames_in": 7}, complete=True)
    >>> rep.top["frames_in"], rep.rejected, rep.complete
    (7, {}, True)
    """

    top: dict[str, int] = field(default_factory=dict)
    rejected: dict[str, int] = field(default_factory=dict)
    health: dict[str, int] = field(default_factory=dict)
    firmware: dict[str, int] = field(default_factory=dict)
    complete: bool = False


_GROUPS = {0: "top", 1: "rejected", 2: "health", 3: "firmware"}


def health_request_frame() -> bytes:
    """The frame that asks a target for its health report."""
    return encode_frame(0, 0, [0.0] * 6, frame_type=TYPE_HEALTH_REQUEST)


def parse_health_report(data: bytes) -> tuple[HealthReport, int]:
    """The last complete health report in `data` (frames of type 0x82 up to the end frame),
    and the number of other valid frames seen.

    Examples
    --------
    >>> def counter(i, group, value, name):
    ...     body = struct.pack("<BBBBHHQ", SYNC0, SYNC1, TYPE_HEALTH_REPORT, 36, i, group,
    ...                        value) + name.encode().ljust(24, b"\\0")
    ...     return body + struct.pack("<H", crc16_ccitt_false(body[2:]))
    >>> rep, other = parse_health_report(counter(0, 0, 7, "frames_in") + counter(1, 255, 1, "end"))
    >>> rep.top, rep.complete, other
    ({'frames_in': 7}, True, 0)
    """
    best = HealthReport()
    cur = HealthReport()
    other = 0
    k = 0
    while k + FRAME_SIZE <= len(data):
        b = data[k:k + FRAME_SIZE]
        if b[0] != SYNC0 or b[1] != SYNC1 or b[3] != 36 or \
                struct.unpack_from("<H", b, 40)[0] != crc16_ccitt_false(b[2:40]):
            k += 1
            continue
        k += FRAME_SIZE
        if b[2] != TYPE_HEALTH_REPORT:
            other += 1
            continue
        index, group, value = struct.unpack_from("<HHQ", b, 4)
        name = b[16:40].rstrip(b"\0").decode("ascii", errors="replace")
        if index == 0:
            cur = HealthReport()
        if group == 0xFF:
            cur.complete = value == index
            if cur.complete:
                best = cur
            cur = HealthReport()
        elif group in _GROUPS:
            getattr(cur, _GROUPS[group])[name] = int(value)
    return best, other


def step_cost(firmware: dict[str, int], loop_rate_hz: float, bytes_in: int = 0
              ) -> dict[str, Any]:
    """Instructions per step and the CPU load they mean on a 168 MHz M4F, from the image's
    SysTick counts under ``-icount shift=0`` (module docstring).

    Examples
    --------
    >>> c = step_cost({"steps_timed": 10, "step_cycles_max": 840, "step_cycles_median": 808,
    ...                "step_cycles_min": 790, "core_clock_hz": 168000000}, 400.0)
    >>> c["instructions_max"], round(c["cpu_load_max"], 4)
    (5000.0, 0.0179)
    """
    per_count = 1e9 / firmware.get("core_clock_hz", CORE_CLOCK_HZ) / 2 ** QEMU_ICOUNT_SHIFT
    cyc_budget = CORE_CLOCK_HZ / loop_rate_hz

    def ins(k: str) -> float:
        return round(firmware.get(k, 0) * per_count, 1)

    imax, imed = ins("step_cycles_max"), ins("step_cycles_median")
    # The image times a loop of known length at start-up: counts x per_count must give its
    # instruction count back (ratio 1 when the emulated clock is the instruction count).
    cal_counts = firmware.get("calibration_cycles", 0)
    cal_ratio = (cal_counts * per_count / firmware["calibration_instructions"]
                 if cal_counts and firmware.get("calibration_instructions") else float("nan"))
    return {
        "counter": "QEMU -icount shift=0 (1 ns virtual per instruction), timed by SysTick at "
                   "168 MHz in the image; the receive interrupt's own time is taken out of a "
                   "step and given per received byte",
        "steps": firmware.get("steps_timed", 0),
        "instructions_max": imax,
        "instructions_median": imed,
        "instructions_min": ins("step_cycles_min"),
        "calibration_ratio": cal_ratio,
        "interrupt_instructions_per_byte": (
            round(firmware.get("interrupt_cycles", 0) * per_count / bytes_in, 1)
            if bytes_in else float("nan")),
        "resolution_instructions": round(per_count, 2),
        "assumed_cpi": ASSUMED_CPI,
        "core_clock_hz": CORE_CLOCK_HZ,
        "loop_rate_hz": loop_rate_hz,
        "cpu_load_max": imax * ASSUMED_CPI / cyc_budget,
        "cpu_load_median": imed * ASSUMED_CPI / cyc_budget,
        "cpu_load_goal": CPU_LOAD_GOAL,
        "instruction_budget": instruction_budget(loop_rate_hz),
        # the monitor's fits in thread mode (the lag identifier), their own instructions
        "fits_run": firmware.get("monitor_fits_run", 0),
        "fit_instructions_max": ins("fit_cycles_max"),
        "fit_instructions_min": ins("fit_cycles_min"),
    }


class QemuTarget:
    """The image running in ``qemu-system-arm -M netduinoplus2``, USART1 on a pseudo-terminal.

    `start()` boots it and waits until it answers a health request; `device` is then the
    pty's path, which the harness opens as it would open /dev/ttyUSB0. `stop()` asks for the
    final health report, ends QEMU and returns the counters in the host loop's statistics
    layout (``frames_in``, ``rejected``, ``health``, ...) plus ``firmware`` and
    ``step_cost``.

    Examples
    --------
    Booting needs QEMU and a built image (tests/test_firmware_qemu.py runs this):

    >>> from gyrodrift.imu.config import default_config
    >>> target = QemuTarget(cached_firmware(default_config()), 400.0)  # doctest: +SKIP
    >>> target.start()  # doctest: +SKIP
    >>> target.device.startswith("/dev/pts/")  # doctest: +SKIP
    True
    >>> stats = target.stop()  # doctest: +SKIP
    """

    def __init__(self, image: FirmwareImage, loop_rate_hz: float, *, icount: bool = True
                 ) -> None:
        self.image = image
        self.loop_rate_hz = loop_rate_hz
        # -icount: the emulated clock counts instructions (the step cost is an instruction
        # count); without it the emulated clock is the host's (the loop keeps real time on a
        # loaded host, and the image's step timings are host time, not reported as a cost).
        self.icount = icount
        self.proc: subprocess.Popen[bytes] | None = None
        self.device = ""
        self.stderr_lines: list[str] = []
        self._fd = -1
        self._stopped = False
        self._stats: dict[str, Any] | None = None

    def start(self) -> None:
        qemu = _tool("qemu-system-arm")
        args = [qemu, "-M", QEMU_MACHINE, "-nographic", "-monitor", "none",
                *(["-icount", f"shift={QEMU_ICOUNT_SHIFT}"] if self.icount else []),
                "-chardev", "pty,id=link", "-serial", "chardev:link",
                "-kernel", str(self.image.elf)]
        # QEMU names the pty on stdout ("char device redirected to /dev/pts/N (label link)")
        self.proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT)
        assert self.proc.stdout is not None
        deadline = time.monotonic() + STARTUP_TIMEOUT_S
        while not self.device and time.monotonic() < deadline:
            ready, _, _ = select.select([self.proc.stdout], [], [], 0.2)
            if ready:
                line = self.proc.stdout.readline().decode(errors="replace").rstrip()
                if not line and self.proc.poll() is not None:
                    break
                self.stderr_lines.append(line)
                m = re.search(r"redirected to (/dev/pts/\d+) \(label link\)", line)
                if m:
                    self.device = m.group(1)
        if not self.device:
            self.stop()
            raise FirmwareError("QEMU did not start: " + (" | ".join(self.stderr_lines)
                                                          or "no output"))
        # Held open for the whole run: the pty stays connected (QEMU drops output while no
        # one has it open), and the final health report is read through it.
        self._fd = os.open(self.device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        tty.setraw(self._fd)
        rep = self._request_report(deadline)
        if not rep.complete:
            self.stop()
            raise FirmwareError(f"the firmware on {QEMU_MACHINE} did not answer a health "
                                "request")

    def _request_report(self, deadline: float) -> HealthReport:
        """Send a health request (again every second until answered) and return the last
        complete report once the line has been quiet for 0.2 s: the answer to the latest
        request, after any earlier report still in the pty (the start-up announcement)."""
        buf = b""
        quiet_s = 0.2
        while time.monotonic() < deadline:
            os.write(self._fd, health_request_frame())
            t_retry = min(deadline, time.monotonic() + 1.0)
            last_data = time.monotonic()
            while time.monotonic() < t_retry:
                ready, _, _ = select.select([self._fd], [], [], 0.05)
                if ready:
                    try:
                        buf += os.read(self._fd, 1 << 16)
                        last_data = time.monotonic()
                    except BlockingIOError:
                        pass
                    continue
                rep, _ = parse_health_report(buf)
                if rep.complete and time.monotonic() - last_data >= quiet_s:
                    return rep
        return HealthReport()

    def stop(self, timeout_s: float = 10.0) -> dict[str, Any] | None:
        if self._stopped:
            return self._stats
        self._stopped = True
        rep = HealthReport()
        try:
            if self._fd >= 0 and self.proc is not None and self.proc.poll() is None:
                rep = self._request_report(time.monotonic() + timeout_s)
        except OSError:
            rep = HealthReport()  # the pty went away: no final report (checks then fail)
        finally:  # QEMU never outlives the replay, whatever happened
            if self._fd >= 0:
                os.close(self._fd)
                self._fd = -1
            if self.proc is not None:
                self.proc.terminate()
                try:
                    self.proc.wait(timeout=5.0)
                except subprocess.TimeoutExpired:
                    self.proc.kill()
                    self.proc.wait()
        if not rep.complete:
            self._stats = None
            return None
        t = rep.top
        self._stats = {
            "program": "gyrodrift-firmware",
            "target": f"qemu {QEMU_MACHINE}",
            "interface": "serial",
            "device": self.device,
            "image": str(self.image.elf),
            **t,
            "frames_dropped": 0,
            "rejected": rep.rejected,
            "health": rep.health,
            "firmware": rep.firmware,
            "step_cost": step_cost(rep.firmware, self.loop_rate_hz, t.get("bytes_in", 0))
            if self.icount else None,
        }
        return self._stats
