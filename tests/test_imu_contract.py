"""One source of truth for the processor contract (issue 12): flag bits, health counter names,
rejection names and defaults are defined once in include/gyrodrift/imu/imu_processor.hpp and
exported by gyrodrift._core. This test fails if any other copy differs: the C++ constants
themselves (a flag added without a table entry), gyrodrift.imu.processor, the loop's JSON, the
flag table of the wire formats guide (docs/guides/wire-formats.md). (The replay harness's
rejection names are checked at run time against the loop's JSON by its own
`loop_processor_rejections` check.)"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import gyrodrift.imu.processor as imu
from gyrodrift._native import core
from gyrodrift.imu import contract
from test_loop_program import Loop, _frames, loop_bin, pass_args  # noqa: F401 (fixtures)

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


def test_loop_json_uses_the_contract_names(loop_bin: Path,  # noqa: F811
                                           pass_args: list[str]) -> None:  # noqa: F811
    _, health, rejections = _core_contract()
    loop = Loop(loop_bin, "--serial", *pass_args)
    data, _ = _frames(20)
    loop.write(data + data[:42])  # seq 0 again after seq 19: out of order (rejected)
    loop.read_until(20 * 42)
    stats = loop.finish()
    assert tuple(stats["health"]) == health
    proc_keys = [k for k in stats["rejected"] if k in rejections]
    assert tuple(proc_keys) == rejections
    assert stats["rejected"]["out_of_order"] == 1  # seq 0 after seq 19: behind


def test_wire_formats_guide_flag_table_matches() -> None:
    flags, _, _ = _core_contract()
    text = (ROOT / "docs" / "guides" / "wire-formats.md").read_text()
    rows = dict((m[2], int(m[1])) for m in re.finditer(r"^\| (\d+) \| (\w+) \|", text, re.M)
                if m[2] in flags or m[2].startswith(("non_", "seq_", "time_", "filter_")))
    assert {k: 1 << v for k, v in rows.items()} == flags


def test_gyrodrift_loop_help_mentions_config(loop_bin: Path) -> None:  # noqa: F811
    r = subprocess.run([str(loop_bin), "--help"], capture_output=True, timeout=10)
    assert r.returncode == 0 and b"--config FILE" in r.stdout


LOOP_DIR = ROOT / "cpp" / "programs" / "gyrodrift-loop"
# The processor options the loop no longer has: the processor and the rates come only from a
# configuration (--config FILE, or the built-in default configuration).
RETIRED = ("--gyro-filter", "--accel-filter", "--gyro-ar2", "--gyro-q", "--gyro-r",
           "--gyro-bias", "--accel-bias", "--gyro-saturation", "--accel-saturation",
           "--stuck-samples", "--time-tolerance-us", "--rate-hz", "--sample-rate-hz")


def test_processor_defaults_have_one_source() -> None:
    """The processor's defaults are the schema's (gyrodrift.imu.schema -> the generated
    config_schema.hpp): the demonstration AR(2) model (ImuDemoAr2 is the schema's DemoAr2,
    exported as IMU_DEMO_AR2, and the model of the shipped default configuration), the default
    timing, and the channel defaults (no literal left in imu_processor.hpp)."""
    from gyrodrift.imu.config import default_config
    from gyrodrift.imu.schema import (
        DEFAULT_SAMPLE_RATE_HZ,
        DEMO_AR2,
        default_period_us,
        default_time_tolerance_us,
        field_spec,
    )

    c = core("imu")
    demo = dict(c.IMU_DEMO_AR2)
    assert demo == {**DEMO_AR2, "sigma2": DEMO_AR2["q"]}
    kalman = default_config().channel("gx").stages[1]
    assert {k: getattr(kalman, k) for k in ("a1", "a2", "mean", "q", "r")} == DEMO_AR2
    assert kalman.sigma2_value == demo["sigma2"]
    assert c.IMU_DEFAULT_PERIOD_US == default_period_us(DEFAULT_SAMPLE_RATE_HZ)
    assert c.IMU_DEFAULT_TIME_TOLERANCE_US == default_time_tolerance_us(DEFAULT_SAMPLE_RATE_HZ)
    ch = imu.ImuChannelConfig()
    assert ch.p0 == field_spec("ar2_kalman", "p0").default
    assert ch.saturation == field_spec("channel", "saturation").default
    assert ch.stuck_samples == field_spec("channel", "stuck_samples").default
    text = (ROOT / "include" / "gyrodrift" / "imu" / "imu_processor.hpp").read_text()
    assert "using ImuDemoAr2 = config_schema::DemoAr2;" in text
    assert "kImuDefaultPeriodUs = config_schema::kDefaultPeriodUs;" in text
    for literal in ("2500", "1250", "-0.25", "1e-10", "Scalar p0 = Scalar(1)",
                    "saturation = std::numeric_limits"):
        assert literal not in text, literal


def test_loop_processor_comes_only_from_a_configuration(loop_bin: Path) -> None:  # noqa: F811
    """One meaning per flag: the loop's usage has --config FILE and --check-config FILE, no
    processor or rate option (each is refused, pointing to the configuration), and names the
    built-in default configuration's sample rate as the schema has it. The loop's sources
    never say a bare `rate_hz`: sample_rate_hz and loop_rate_hz are different rates."""
    from gyrodrift.imu.schema import DEFAULT_SAMPLE_RATE_HZ

    text = subprocess.run([str(loop_bin), "--help"], capture_output=True, timeout=10,
                          text=True).stdout
    assert "--config FILE" in text and "--check-config FILE" in text
    for flag in RETIRED:
        assert flag not in text, flag
        r = subprocess.run([str(loop_bin), "--serial", "fd:0", flag, "1"], capture_output=True,
                           timeout=10, text=True)
        assert r.returncode == 2 and "no such option" in r.stderr, (flag, r.stderr)
    rate = re.search(r"built-in default configuration.*?\(sample rate ([\d.]+) Hz\)", text,
                     re.S)
    assert rate and float(rate[1]) == DEFAULT_SAMPLE_RATE_HZ, text
    for src in sorted(LOOP_DIR.glob("*.[hc]pp")):
        code = src.read_text()
        assert "ProcessingOptions" not in code, src.name
        bare = re.findall(r"(?<![A-Za-z0-9_])rate_hz", code)
        assert not bare, (src.name, len(bare))
