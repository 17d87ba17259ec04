"""One source of truth for the processor contract (issue 12): flag bits, health counter names,
rejection names and defaults are defined once in include/gyrodrift/imu/imu_processor.hpp and
exported by gyrodrift._core. This test fails if any other copy differs: the C++ constants
themselves (a flag added without a table entry), gyrodrift.imu.processor, the loop's JSON, the
README
table. (The replay harness's rejection names are checked at run time against the loop's JSON
by its own `loop_processor_rejections` check.)"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import gyrodrift.imu.processor as imu
from gyrodrift._native import core
from gyrodrift.imu import contract
from test_loop_program import PASS, Loop, _frames, loop_bin  # noqa: F401 (fixture)

ROOT = Path(__file__).resolve().parents[1]


def _core_contract() -> tuple[dict[str, int], tuple[str, ...], tuple[str, ...]]:
    c = core("imu")
    return dict(c.IMU_FLAGS), tuple(c.IMU_HEALTH_KEYS), tuple(c.IMU_REJECTION_KEYS)


def test_header_constants_equal_the_exported_table() -> None:
    flags, health, _ = _core_contract()
    text = (ROOT / "include" / "gyrodrift" / "imu" / "imu_processor.hpp").read_text()
    consts = {m[1]: 1 << int(m[2]) for m in
              re.finditer(r"kFlag(\w+) = 1U << (\d+);", text)}
    # every kFlag constant is in the exported table, with its bit, and nothing else is
    assert sorted(consts.values()) == sorted(flags.values())
    camel = {re.sub(r"(?<!^)(?=[A-Z])", "_", k).lower(): v for k, v in consts.items()}
    assert camel == flags
    start = text.index("struct ImuHealth {")
    struct = text[start:text.index("};", start)]
    members = tuple(re.findall(r"std::uint64_t (\w+) = 0;", struct))
    assert members == health  # for_each_health_field lists every counter, in order


def test_python_takes_the_contract_from_core() -> None:
    flags, health, _ = _core_contract()
    for name, bit in flags.items():
        assert getattr(contract, f"FLAG_{name.upper()}") == bit
    assert contract.FLAG_NAMES == {b: n for n, b in flags.items()}
    assert contract.HEALTH_KEYS == health
    c = core("imu")
    assert contract.RESYNC_AFTER == c.IMU_RESYNC_AFTER == 8
    assert imu.ImuConfig().period_us == c.IMU_DEFAULT_PERIOD_US
    assert imu.ImuConfig().time_tolerance_us == c.IMU_DEFAULT_TIME_TOLERANCE_US
    assert tuple(imu.ImuProcessor(imu.ImuConfig(
        channels=[imu.ImuChannelConfig() for _ in range(6)])).health) == health


def test_loop_json_uses_the_contract_names(loop_bin: Path) -> None:  # noqa: F811
    _, health, rejections = _core_contract()
    loop = Loop(loop_bin, "--serial", *PASS)
    data, _ = _frames(20)
    loop.write(data + data[:42])  # seq 0 again after seq 19: out of order (rejected)
    loop.read_until(20 * 42)
    stats = loop.finish()
    assert tuple(stats["health"]) == health
    proc_keys = [k for k in stats["rejected"] if k in rejections]
    assert tuple(proc_keys) == rejections
    assert stats["rejected"]["out_of_order"] == 1  # seq 0 after seq 19: behind


def test_readme_flag_table_matches() -> None:
    flags, _, _ = _core_contract()
    text = (ROOT / "README.md").read_text()
    rows = dict((m[2], int(m[1])) for m in re.finditer(r"^\| (\d+) \| (\w+) \|", text, re.M)
                if m[2] in flags or m[2].startswith(("non_", "seq_", "time_", "filter_")))
    assert {k: 1 << v for k, v in rows.items()} == flags


def test_gyrodrift_loop_help_mentions_config(loop_bin: Path) -> None:  # noqa: F811
    r = subprocess.run([str(loop_bin), "--help"], capture_output=True, timeout=10)
    assert r.returncode == 0 and b"--config FILE" in r.stdout


def test_loop_demo_model_has_one_source(loop_bin: Path) -> None:  # noqa: F811
    """The loop's demonstration AR(2) model (no identified model given) is ImuDemoAr2 in
    imu/imu_processor.hpp; the loop's defaults, its --help text and the replay harness's
    ProcessorSettings all carry the exported values (before: three hand-typed copies)."""
    from gyrodrift.replay.processor import ProcessorSettings

    demo = dict(core("imu").IMU_DEMO_AR2)
    s = ProcessorSettings()
    assert {k: getattr(s, k) for k in demo} == demo
    processing = (ROOT / "cpp" / "programs" / "gyrodrift-loop" / "processing.hpp").read_text()
    assert "-0.25" not in processing and "ImuDemoAr2::a1" in processing
    text = subprocess.run([str(loop_bin), "--help"], capture_output=True, timeout=10,
                          text=True).stdout
    ar2 = re.search(r"--gyro-ar2 A1,A2,SIGMA2,MEAN .*\(default ([^:]+):", text)
    qr = re.search(r"--gyro-q Q --gyro-r R .*\(default ([^,]+), ([^)]+)\)", text)
    assert ar2 and qr, text
    assert [float(v) for v in ar2[1].split(",")] == [demo[k] for k in ("a1", "a2", "sigma2",
                                                                        "mean")]
    assert (float(qr[1]), float(qr[2])) == (demo["q"], demo["r"])
