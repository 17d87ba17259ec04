"""Cortex-M4F build gate: every cpp/cortex_m/use_*.cpp must build into a bare-metal ELF for
an STM32F4-class part (1 MiB flash, 128 KiB RAM) with the firmware flags, and must not pull in
the heap, software double-precision routines or exception machinery.

Why a symbol check: EIGEN_NO_MALLOC is an eigen_assert, compiled out with NDEBUG, so only the
linked image tells whether malloc/operator new or __aeabi_d* (the Cortex-M4F FPU is single
precision; every double operation becomes a libgcc call) are reachable. Compiling with
-Wdouble-promotion -Werror additionally rejects implicit float -> double promotions.

Each ELF is then RUN on an emulated STM32F405 (QEMU `netduinoplus2`, Cortex-M4 with FPU):
the start-up code must reach app_main() with the FPU enabled, app_main() must return 0 without
taking any fault, and the painted-stack high-water mark must fit the 8 KiB stack the linker
script reserves. The image reports through ARM semihosting (-DGYRODRIFT_CM_SEMIHOSTING).

The toolchain (Debian gcc-arm-none-eabi, libstdc++-arm-none-eabi-newlib,
binutils-arm-none-eabi, qemu-system-arm; installed by scripts/setup) is required: a missing
tool FAILS.
Sizes go to build/cortex_m/sizes.json and sizes.md and are printed (pytest -s shows them).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent
CM_DIR = REPO_ROOT / "cpp" / "cortex_m"
# cortex_m_start.hpp: the C runtime start startup.cpp shares with the reference firmware.
START_DIR = REPO_ROOT / "cpp" / "firmware" / "board"
INCLUDE_DIR = REPO_ROOT / "include"
EIGEN_DIR = Path("/usr/include/eigen3")
REPORT_DIR = REPO_ROOT / "build" / "cortex_m"

FLASH_BYTES = 1024 * 1024
RAM_BYTES = 128 * 1024
STACK_BYTES = 0x2000  # `_stack_size` in stm32f4.ld (checked below)
QEMU_MACHINE = "netduinoplus2"  # STM32F405: 1 MiB flash @0x08000000, 128 KiB SRAM @0x20000000
QEMU_TIMEOUT_S = 60.0

ARCH_FLAGS = ["-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16"]
CXX_FLAGS = [
    "-std=c++17",
    *ARCH_FLAGS,
    "-Os",
    "-fno-exceptions",
    "-fno-rtti",
    "-fno-threadsafe-statics",  # no __cxa_guard_* locking on a single-threaded MCU
    "-ffunction-sections",
    "-fdata-sections",
    "-fstack-usage",
    "-Wall",
    "-Wextra",
    "-Wdouble-promotion",
    "-Werror",
    # Asserts off as in firmware (so EIGEN_NO_MALLOC is inert: the symbol check is the gate);
    # no SIMD on the M4 (Eigen has no Helium/DSP-extension packet math).
    "-DNDEBUG",
    "-DEIGEN_NO_MALLOC",
    "-DEIGEN_DONT_VECTORIZE",
    "-DGYRODRIFT_CM_SEMIHOSTING",  # startup.cpp reports exit code/stack to the emulator
    "-isystem",
    str(EIGEN_DIR),
    "-I",
    str(INCLUDE_DIR),
    "-I",
    str(CM_DIR),
    "-I",
    str(START_DIR),
]
LD_FLAGS = [
    *ARCH_FLAGS,
    "-nostartfiles",  # startup.cpp provides Reset_Handler and the vector table
    "--specs=nano.specs",
    "--specs=nosys.specs",
    "-T",
    str(CM_DIR / "stm32f4.ld"),
    "-Wl,--gc-sections",
]
SUPPORT_SOURCES = [CM_DIR / "startup.cpp", CM_DIR / "support.cpp"]

# (pattern on defined or undefined symbol names, reason). Matched against `nm` of the ELF.
FORBIDDEN_SYMBOLS: list[tuple[re.Pattern[str], str]] = [
    (re.compile(r"^_?(malloc|free|calloc|realloc|memalign|aligned_alloc|posix_memalign)$"), "heap"),
    (re.compile(r"^_(malloc|free|calloc|realloc|memalign)_r$"), "heap"),
    (re.compile(r"^_Zn[wa]j"), "heap"),  # operator new / new[] (size_t = unsigned int)
    (re.compile(r"^_Zd[la]Pv"), "heap"),  # operator delete / delete[]
    (re.compile(r"^__aeabi_(d\w+|\w+2d|cd\w+)$"), "software double"),
    (re.compile(r"^__(add|sub|mul|div|neg|eq|ne|lt|le|gt|ge|un)df[23]$"), "software double"),
    (re.compile(r"^__(extendsfdf2|truncdfsf2|fix\w*df\w*|float\w*df)$"), "software double"),
    (
        re.compile(r"^(__cxa_throw|__cxa_allocate_exception|__gxx_personality_v0|_Unwind_\w+)$"),
        "exceptions",
    ),
]

# The units allowed to link software double, each with its reason; every other unit is held
# to float. The lag-statistics fit runs in double by design: its likelihood must resolve
# differences of 0.1 on a value of order n (1e-7 relative at 1e6 samples), below float's
# resolution (include/gyrodrift/filters/lag_drift_fit.hpp); its statistics stay float.
SOFTWARE_DOUBLE_UNITS: dict[str, str] = {
    "use_lag_drift_fit": "the drift-model fit from float lag statistics runs in double",
    "use_lag_drift_identifier": "the re-identification's fits from float statistics run in double",
}


@dataclass
class GateResult:
    unit: str
    ok: bool = False
    reasons: list[str] = field(default_factory=list)
    log: str = ""
    text: int = 0
    data: int = 0
    bss: int = 0
    max_frame_bytes: int = 0
    run: str = ""  # "exit" or "fault" as reported by the image under QEMU
    exit_code: int = -1
    stack_bytes: int = 0  # measured high-water mark

    @property
    def flash_bytes(self) -> int:
        return self.text + self.data  # code + constants + initial values of .data

    @property
    def ram_bytes(self) -> int:
        return self.data + self.bss  # excluding the stack reserved by the linker script


def toolchain() -> dict[str, str]:
    tools = {}
    for tool in ("g++", "nm", "size"):
        path = shutil.which(f"arm-none-eabi-{tool}")
        if path is None:
            pytest.fail(
                f"arm-none-eabi-{tool} not found: install gcc-arm-none-eabi, "
                "libstdc++-arm-none-eabi-newlib and binutils-arm-none-eabi (scripts/setup)"
            )
        tools[tool] = path
    qemu = shutil.which("qemu-system-arm")
    if qemu is None:
        pytest.fail("qemu-system-arm not found: install qemu-system-arm (scripts/setup)")
    tools["qemu"] = qemu
    if not (EIGEN_DIR / "Eigen" / "Core").exists():
        pytest.fail(f"Eigen headers not found in {EIGEN_DIR} (libeigen3-dev)")
    return tools


def _run(cmd: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=300, check=False)


def forbidden_symbols(nm_output: str) -> list[str]:
    """'reason: symbol' for every forbidden symbol in `nm` output (defined or undefined)."""
    found = []
    for line in nm_output.splitlines():
        parts = line.split()
        if not parts:
            continue
        name = parts[-1]
        for pattern, reason in FORBIDDEN_SYMBOLS:
            if pattern.match(name):
                found.append(f"{reason}: {name}")
    return sorted(set(found))


def build_unit(src: Path, workdir: Path, extra_flags: list[str] | None = None) -> GateResult:
    """Compile and link src with the support files; check symbols; measure sizes.
    extra_flags: added to the compile flags (e.g. -ffp-contract=off)."""
    tools = toolchain()
    result = GateResult(unit=src.stem)
    workdir.mkdir(parents=True, exist_ok=True)
    objects = []
    for source in [*SUPPORT_SOURCES, src]:
        obj = workdir / (source.stem + ".o")
        proc = _run([tools["g++"], *CXX_FLAGS, *(extra_flags or []), "-c", str(source), "-o",
                     str(obj)], workdir)
        if proc.returncode != 0:
            result.reasons.append(f"compile error in {source.name}")
            result.log += proc.stderr
            return result
        objects.append(str(obj))
    elf = workdir / (src.stem + ".elf")
    proc = _run(
        [
            tools["g++"],
            *LD_FLAGS,
            f"-Wl,-Map={workdir / (src.stem + '.map')}",
            *objects,
            "-o",
            str(elf),
        ],
        workdir,
    )
    if proc.returncode != 0:
        result.reasons.append("link error")
        result.log += proc.stderr
        return result
    nm = _run([tools["nm"], str(elf)], workdir)
    allowed = "software double:" if src.stem in SOFTWARE_DOUBLE_UNITS else None
    result.reasons.extend(r for r in forbidden_symbols(nm.stdout)
                          if allowed is None or not r.startswith(allowed))
    size = _run([tools["size"], "-A", str(elf)], workdir)
    sections = {}
    for line in size.stdout.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[1].isdigit():
            sections[parts[0]] = int(parts[1])
    flash_sections = (
        ".isr_vector",
        ".text",
        ".ARM.extab",
        ".ARM.exidx",
        ".preinit_array",
        ".init_array",
    )
    result.text = sum(sections.get(s, 0) for s in flash_sections)
    result.data = sections.get(".data", 0)
    result.bss = sections.get(".bss", 0)
    su = workdir / (src.stem + ".su")
    if su.exists():
        frames = [int(line.split("\t")[1]) for line in su.read_text().splitlines() if "\t" in line]
        result.max_frame_bytes = max(frames, default=0)
    if result.max_frame_bytes > STACK_BYTES:
        result.reasons.append(f"stack: a {result.max_frame_bytes} B frame exceeds the stack")
    run_on_qemu(tools["qemu"], elf, result)
    result.ok = not result.reasons
    return result


REPORT_LINE = re.compile(
    r"gyrodrift-cm (?P<what>exit|fault) code=0x(?P<code>[0-9a-f]{8}) sink=0x[0-9a-f]{8} "
    r"sink_i32=0x[0-9a-f]{8} stack=0x(?P<stack>[0-9a-f]{8})"
)


def run_on_qemu(qemu: str, elf: Path, result: GateResult) -> None:
    """Run the ELF on the emulated STM32F405; record exit code and stack high-water mark."""
    cmd = [
        qemu,
        "-M",
        QEMU_MACHINE,
        "-nographic",
        "-monitor",
        "none",
        "-serial",
        "none",
        "-semihosting-config",
        "enable=on,target=native",
        "-kernel",
        str(elf),
    ]
    try:
        proc = subprocess.run(  # in the unit's directory: semihosting file I/O is relative
            cmd, capture_output=True, text=True, timeout=QEMU_TIMEOUT_S, check=False,
            cwd=elf.parent,
        )
    except subprocess.TimeoutExpired:
        result.reasons.append(f"run: no report within {QEMU_TIMEOUT_S:.0f} s (hang or lockup)")
        return
    match = REPORT_LINE.search(proc.stdout + proc.stderr)  # semihosting console: stderr
    if match is None:
        result.reasons.append(f"run: no semihosting report (qemu exit {proc.returncode})")
        result.log += proc.stdout[-2000:] + proc.stderr[-2000:]
        return
    result.run = match["what"]
    result.exit_code = int(match["code"], 16)
    result.stack_bytes = int(match["stack"], 16)
    if result.run == "fault":
        result.reasons.append("run: the core took a fault exception")
    elif result.exit_code != 0 or proc.returncode != 0:
        result.reasons.append(f"run: app_main returned {result.exit_code}")
    if result.stack_bytes > STACK_BYTES:
        result.reasons.append(
            f"stack: used {result.stack_bytes} B > {STACK_BYTES} B reserved in stm32f4.ld"
        )


def gate_units() -> list[Path]:
    return sorted(CM_DIR.glob("use_*.cpp"))


BASELINE = "baseline (startup + support, empty app_main)"


@pytest.fixture(scope="module")
def gate_results(tmp_path_factory: pytest.TempPathFactory) -> dict[str, GateResult]:
    root = tmp_path_factory.mktemp("cortex_m")
    results = {src.stem: build_unit(src, root / src.stem) for src in gate_units()}
    baseline = root / "baseline" / "use_baseline.cpp"
    baseline.parent.mkdir(parents=True)
    baseline.write_text('#include "support.hpp"\nextern "C" int app_main(void) { return 0; }\n')
    results[BASELINE] = build_unit(baseline, root / "baseline")
    results[BASELINE].unit = BASELINE
    return results


def test_toolchain_present() -> None:
    tools = toolchain()
    proc = _run([tools["g++"], "--version"], REPO_ROOT)
    assert proc.returncode == 0 and "arm-none-eabi" in proc.stdout


# With no use_*.cpp at all the single None case fails (an empty parameter set would skip).
@pytest.mark.xdist_group("cortex_m_gate")
@pytest.mark.parametrize("src", gate_units() or [None], ids=lambda p: p.stem if p else "none")
def test_unit_passes_gate(src: Path | None, gate_results: dict[str, GateResult]) -> None:
    assert src is not None, f"no use_*.cpp in {CM_DIR}: no filter is covered by the gate"
    result = gate_results[src.stem]
    assert result.ok, f"{src.name}: {result.reasons}\n{result.log[-4000:]}"
    assert 0 < result.flash_bytes <= FLASH_BYTES
    assert 0 < result.ram_bytes <= RAM_BYTES


@pytest.mark.xdist_group("cortex_m_gate")
def test_size_report(gate_results: dict[str, GateResult]) -> None:
    baseline = gate_results[BASELINE]
    assert baseline.ok, baseline.reasons
    rows = []
    for r in gate_results.values():
        rows.append(
            {
                **asdict(r),
                "flash_bytes": r.flash_bytes,
                "ram_bytes": r.ram_bytes,
                "flash_over_baseline": r.flash_bytes - baseline.flash_bytes,
                "ram_over_baseline": r.ram_bytes - baseline.ram_bytes,
            }
        )
        rows[-1].pop("log")
    table = [
        "| unit | gate | flash B | RAM B (data+bss) | flash over baseline "
        f"| stack used B (of {STACK_BYTES}) | largest frame B | run on QEMU {QEMU_MACHINE} |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for row in rows:
        table.append(
            f"| {row['unit']} | {'pass' if row['ok'] else 'FAIL: ' + '; '.join(row['reasons'])} "
            f"| {row['flash_bytes']} | {row['ram_bytes']} | {row['flash_over_baseline']} "
            f"| {row['stack_bytes']} | {row['max_frame_bytes']} "
            f"| {row['run']} {row['exit_code']} |"
        )
    text = "\n".join(table)
    print("\nCortex-M4F gate (arm-none-eabi-g++ -Os, STM32F4-class 1 MiB / 128 KiB):\n" + text)
    REPORT_DIR.mkdir(parents=True, exist_ok=True)
    # Atomic replace: several people may run the gate at once.
    for name, content in (
        ("sizes.json", json.dumps({"flags": CXX_FLAGS, "units": rows}, indent=2)),
        ("sizes.md", text + "\n"),
    ):
        fd, tmp = tempfile.mkstemp(dir=REPORT_DIR)
        with os.fdopen(fd, "w") as fh:
            fh.write(content)
        os.replace(tmp, REPORT_DIR / name)
    assert json.loads((REPORT_DIR / "sizes.json").read_text())["units"]


# --- the gate can fail ----------------------------------------------------------------------

GOOD_UNIT = """
#include <Eigen/Core>
#include "support.hpp"
// A float 2-state filter on fixed-size Eigen types: must pass the gate.
extern "C" int app_main(void) {
  Eigen::Matrix2f a;
  a << 0.6868f, -0.0213f, 1.0f, 0.0f;
  Eigen::Vector2f x = Eigen::Vector2f::Zero();
  for (std::size_t i = 0; i < 100; ++i) {
    x = a * x;
    x(0) += 0.1f * gyrodrift::cortex_m::input(i);
    gyrodrift::cortex_m::sink(x(0));
  }
  return 0;
}
"""

BAD_UNITS = {
    # Explicit double arithmetic (no promotion warning): soft-float __aeabi_d* calls.
    "explicit_double": (
        """
#include "support.hpp"
extern "C" int app_main(void) {
  double acc = 0.0;
  for (std::size_t i = 0; i < 100; ++i) {
    acc = acc * 0.5 + static_cast<double>(gyrodrift::cortex_m::input(i));
  }
  gyrodrift::cortex_m::sink(static_cast<float>(acc));
  return 0;
}
""",
        "software double",
    ),
    # Heap through the standard library.
    "std_vector": (
        """
#include <vector>
#include "support.hpp"
extern "C" int app_main(void) {
  std::vector<float> v;
  for (std::size_t i = 0; i < 10; ++i) v.push_back(gyrodrift::cortex_m::input(i));
  gyrodrift::cortex_m::sink(v.back());
  return static_cast<int>(v.size());
}
""",
        "heap",
    ),
    # Direct malloc.
    "malloc": (
        """
#include <cstdlib>
#include "support.hpp"
float* volatile keep = nullptr;
extern "C" int app_main(void) {
  float* p = static_cast<float*>(std::malloc(16 * sizeof(float)));
  keep = p;  // escapes, so the compiler cannot elide the malloc/free pair
  p[0] = gyrodrift::cortex_m::input(0);
  gyrodrift::cortex_m::sink(p[0]);
  std::free(p);
  return 0;
}
""",
        "heap",
    ),
    # Eigen dynamic-size matrix: heap even with EIGEN_NO_MALLOC (asserts are off).
    "eigen_dynamic": (
        """
#include <Eigen/Core>
#include "support.hpp"
extern "C" int app_main(void) {
  Eigen::VectorXf v(static_cast<Eigen::Index>(gyrodrift::cortex_m::input(0) * 8.0f) + 1);
  v.setConstant(gyrodrift::cortex_m::input(1));
  gyrodrift::cortex_m::sink(v.sum());
  return 0;
}
""",
        "heap",
    ),
    # Implicit float -> double promotion: rejected at compile time by -Wdouble-promotion.
    "implicit_promotion": (
        """
#include "support.hpp"
extern "C" int app_main(void) {
  float x = gyrodrift::cortex_m::input(0);
  double y = x * 1.5;
  gyrodrift::cortex_m::sink(static_cast<float>(y));
  return 0;
}
""",
        "compile error",
    ),
    # Runs into an undefined instruction: the core takes a fault, seen only by running it.
    "hard_fault": (
        """
#include "support.hpp"
extern "C" int app_main(void) {
  if (gyrodrift::cortex_m::input(0) > -1000.0f) __builtin_trap();
  return 0;
}
""",
        "run: the core took a fault",
    ),
    # Reports failure through its return value.
    "nonzero_exit": (
        """
#include "support.hpp"
extern "C" int app_main(void) { return gyrodrift::cortex_m::input(0) > 0.0f ? 3 : 0; }
""",
        "run: app_main returned 3",
    ),
    # 12 KiB of stack: overflows the 8 KiB reservation (measured by the painted high-water mark).
    "stack_overflow": (
        """
#include "support.hpp"
extern "C" int app_main(void) {
  volatile float big[3072];
  for (std::size_t i = 0; i < 3072; ++i) big[i] = gyrodrift::cortex_m::input(i);
  gyrodrift::cortex_m::sink(big[100]);
  return 0;
}
""",
        "stack",
    ),
    # A throw cannot compile with -fno-exceptions.
    "throw": (
        """
#include "support.hpp"
extern "C" int app_main(void) {
  if (gyrodrift::cortex_m::input(0) > 100.0f) throw 1;
  return 0;
}
""",
        "compile error",
    ),
}


def test_stack_budget_matches_linker_script() -> None:
    script = (CM_DIR / "stm32f4.ld").read_text()
    assert re.search(rf"_stack_size\s*=\s*{STACK_BYTES:#x}\s*;", script)


def test_gate_accepts_a_good_float_unit(tmp_path: Path) -> None:
    src = tmp_path / "use_good.cpp"
    src.write_text(GOOD_UNIT)
    result = build_unit(src, tmp_path / "out")
    assert result.ok, f"{result.reasons}\n{result.log}"
    assert result.flash_bytes > 0
    assert result.run == "exit" and result.exit_code == 0
    assert 0 < result.stack_bytes < 1024


@pytest.mark.parametrize("name", sorted(BAD_UNITS))
def test_gate_rejects_bad_unit(name: str, tmp_path: Path) -> None:
    code, expected_reason = BAD_UNITS[name]
    src = tmp_path / f"use_{name}.cpp"
    src.write_text(code)
    result = build_unit(src, tmp_path / "out")
    assert not result.ok
    assert any(r.startswith(expected_reason) for r in result.reasons), (
        result.reasons,
        result.log[-2000:],
    )


def test_software_double_allowance_names_existing_units_only() -> None:
    """The allowance is by unit name: each allowed name is a unit of the gate (a renamed or
    removed unit does not leave a name another unit could take)."""
    assert set(SOFTWARE_DOUBLE_UNITS) <= {p.stem for p in gate_units()}
    assert "explicit_double" not in SOFTWARE_DOUBLE_UNITS


def test_forbidden_symbol_patterns() -> None:
    # nm lines as the gate sees them: defined (T) and undefined (U) symbols.
    sample = "\n".join(
        [
            "08000100 T app_main",
            "         U malloc",
            "08000200 T _malloc_r",
            "08000300 T _Znwj",
            "08000400 T _ZdlPvj",
            "08000500 T __aeabi_dmul",
            "08000600 T __aeabi_f2d",
            "08000700 T __aeabi_fmul",
            "08000800 T __adddf3",
            "08000900 T sqrtf",
            "08000a00 T __aeabi_ui2d",
            "08000b00 T __cxa_throw",
            "08000c00 T memcpy",
        ]
    )
    found = forbidden_symbols(sample)
    names = {f.split(": ")[1] for f in found}
    assert names == {
        "malloc",
        "_malloc_r",
        "_Znwj",
        "_ZdlPvj",
        "__aeabi_dmul",
        "__aeabi_f2d",
        "__adddf3",
        "__aeabi_ui2d",
        "__cxa_throw",
    }


# --- host: every public header compiles without exceptions and RTTI -------------------------


def test_headers_compile_on_host_without_exceptions_and_rtti(tmp_path: Path) -> None:
    cxx = shutil.which("g++")
    assert cxx is not None, "host g++ not found"
    headers = sorted((INCLUDE_DIR / "gyrodrift").rglob("*.hpp"))
    assert headers
    for header in headers:
        rel = header.relative_to(INCLUDE_DIR).as_posix()
        tu = tmp_path / f"{rel.replace('/', '_').removesuffix('.hpp')}.cpp"
        tu.write_text(f"#include <{rel}>\n")  # also proves self-containment
        proc = _run(
            [
                cxx,
                "-std=c++17",
                "-fno-exceptions",
                "-fno-rtti",
                "-fsyntax-only",
                "-Wall",
                "-Wextra",
                "-Wpedantic",
                "-Wconversion",
                "-Wsign-conversion",
                "-Wshadow",
                "-Wdouble-promotion",
                "-Werror",
                "-isystem",
                str(EIGEN_DIR),
                "-I",
                str(INCLUDE_DIR),
                str(tu),
            ],
            tmp_path,
        )
        assert proc.returncode == 0, f"{rel}:\n{proc.stderr[-3000:]}"
