"""
From an identified model to firmware
====================================

Identify a gyro's drift model, write it into a processor configuration file, generate the
firmware header from that file, and build it for a Cortex-M4F exactly as firmware would: no
heap, no software double precision, no exceptions. The build runs on the emulated STM32F405
(QEMU), which checks that the code runs and terminates. The cross toolchain and QEMU are the
Debian packages ``scripts/setup`` installs; run this script from the source tree (it uses
``cpp/cortex_m``).
"""

# %%
# Identify the drift model
# ------------------------
# The gyro's drift is identified on a record in rad/s (the processor's unit) by maximum
# likelihood on the model "AR(2) drift + white noise"
# (:func:`~gyrodrift.filters.drift_model.fit_drift_model`); its Kalman tuning comes with it.
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import gyrodrift
from gyrodrift.filters.drift_model import fit_drift_model
from gyrodrift.imu.config import drift_filter_config, dumps_config, load_config, write_config
from gyrodrift.imu.firmware_header import emit_cpp
from gyrodrift.units import DPH

rate_hz = 400.0
rec = gyrodrift.simulate(60.0, rate_hz=rate_hz, n_deg_rt_h=0.01,
                         ar2=(0.6868, -0.0213, 0.5), bias_deg_h=3.0, seed=4)
x_rad_s = rec.rate_deg_h * DPH
ml = fit_drift_model(x_rad_s, rate_hz, "ar2+white")
print(f"a1 = {ml.a1:.4f}, a2 = {ml.a2:.4f}, q = {ml.q:.3e}, r = {ml.r:.3e} (rad/s)^2, "
      f"mean = {ml.mean:.3e} rad/s")

# %%
# The configuration file
# ----------------------
# :func:`~gyrodrift.imu.config.drift_filter_config` puts the model into the six-channel
# processor's configuration (the other channels pass through); the file is TOML, checked field
# by field when read (see :doc:`/guides/configuration-file`).
work = Path(tempfile.mkdtemp())
cfg = drift_filter_config("gz", a1=ml.a1, a2=ml.a2, mean=ml.mean, q=ml.q, r=ml.r,
                          sample_rate_hz=rate_hz)
path = write_config(cfg, work / "proc.toml")
text = dumps_config(load_config(path))
print(text[text.index("[channels.gz]"):text.index("[channels.ax]")])

# %%
# The firmware header
# -------------------
# :func:`~gyrodrift.imu.firmware_header.emit_cpp` (``gyrodrift config emit-cpp``) writes the
# configuration as ``constexpr`` data and a ``Processor`` type for it: the firmware needs no
# parser.
header = emit_cpp(load_config(path), namespace="my_imu")
(work / "my_imu_config.hpp").write_text(header)
print("\n".join(line for line in header.splitlines() if "gz" in line or "Processor" in line))

# %%
# The Cortex-M4F build
# --------------------
# One firmware unit steps the processor on 600 samples; the start-up code, the linker script
# (1 MiB flash, 128 KiB RAM, no heap) and the I/O stubs are those of the project's build gate.
here = Path.cwd().resolve()
repo = next(d for d in [here, *here.parents, *Path(gyrodrift.__file__).resolve().parents]
            if (d / "cpp" / "cortex_m" / "stm32f4.ld").is_file())
cm = repo / "cpp" / "cortex_m"
(work / "app.cpp").write_text("""
#include "my_imu_config.hpp"
#include "support.hpp"
namespace { my_imu::Processor processor(my_imu::kImuConfig, my_imu::make_wavelet); }
extern "C" int app_main(void) {
  gyrodrift::ImuSample<float> s;
  gyrodrift::ImuOutput<float> y;
  for (std::uint32_t k = 0; k < 600; ++k) {
    s.seq = static_cast<std::uint16_t>(k);
    s.t_us = std::uint64_t{my_imu::kImuConfig.period_us} * k;
    for (std::size_t c = 0; c < 6; ++c) s.values[c] = gyrodrift::cortex_m::input(k + 7u * c);
    if ((processor.step(s, y) & gyrodrift::kFlagRejected) != 0u) return 1;
    gyrodrift::cortex_m::sink(y.values[2]);
  }
  return 0;
}
""")
arch = ["-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16"]
cxx = ["arm-none-eabi-g++", "-std=c++17", *arch, "-Os", "-fno-exceptions", "-fno-rtti",
       "-fno-threadsafe-statics", "-ffunction-sections", "-fdata-sections", "-Wall", "-Wextra",
       "-Wdouble-promotion", "-Werror", "-DNDEBUG", "-DEIGEN_NO_MALLOC",
       "-DEIGEN_DONT_VECTORIZE", "-DGYRODRIFT_CM_SEMIHOSTING", "-isystem", "/usr/include/eigen3",
       "-I", str(repo / "include"), "-I", str(cm), "-I", str(repo / "cpp" / "firmware" / "board"),
       "-I", str(work)]
objects = []
for src in (cm / "startup.cpp", cm / "support.cpp", work / "app.cpp"):
    obj = work / (src.stem + ".o")
    subprocess.run([*cxx, "-c", str(src), "-o", str(obj)], check=True)
    objects.append(str(obj))
elf = work / "app.elf"
subprocess.run(["arm-none-eabi-g++", *arch, "-nostartfiles", "--specs=nano.specs",
                "--specs=nosys.specs", "-T", str(cm / "stm32f4.ld"), "-Wl,--gc-sections",
                *objects, "-o", str(elf)], check=True)
print(subprocess.run(["arm-none-eabi-size", str(elf)], capture_output=True, text=True,
                     check=True).stdout)

# %%
# What is not in the image: no heap, no software double, no exception machinery.
symbols = subprocess.run(["arm-none-eabi-nm", str(elf)], capture_output=True, text=True,
                         check=True).stdout
forbidden = re.compile(r"\b(malloc|_malloc_r|_Znwj|__aeabi_d\w+|__adddf3|__muldf3|__cxa_throw)\b")
print("forbidden symbols:", sorted(set(forbidden.findall(symbols))) or "none")

# %%
# Run it on the emulated STM32F405
# --------------------------------
# The start-up code reports ``app_main``'s exit code and the measured stack through ARM
# semihosting.
qemu = subprocess.run(
    ["qemu-system-arm", "-M", "netduinoplus2", "-nographic", "-monitor", "none", "-serial",
     "none", "-semihosting-config", "enable=on,target=native", "-kernel", str(elf)],
    capture_output=True, text=True, timeout=120, check=False, cwd=work)
report = re.search(r"gyrodrift-cm (exit|fault) code=0x([0-9a-f]{8}).*stack=0x([0-9a-f]{8})",
                   qemu.stdout + qemu.stderr)
assert report is not None, qemu.stderr[-500:]
print(f"{report[1]}: app_main returned {int(report[2], 16)}, stack used {int(report[3], 16)} B")
shutil.rmtree(work)
