"""The configuration is validated in the scalar the target uses (float32): every value the
validator accepts builds the float32 processor (the binding ImuProcessorF32) and a firmware
header (`gyrodrift config emit-cpp`) whose numbers read back exactly as the float32 of the
configuration's value; a value that does not fit a float32 (1e-50, 1e39), or whose rounding
breaks a bound or a relation (a1 = 0.999999999 with a2 = 0 rounds to a unit root), is
refused naming its key. Values drawn by hypothesis over each float32 field's bounds.
"""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
import pytest
from gyrodrift.imu.config import (
    Ar2KalmanStage,
    BiasRemoval,
    ConfigError,
    ProcessorConfig,
    default_config,
    dumps_config,
    parse_config,
)
from gyrodrift.imu.firmware_header import emit_cpp
from gyrodrift.imu.processor import ImuProcessor
from gyrodrift.imu.schema import FIELDS, FLOAT32_MAX, FLOAT32_MIN_NORMAL, field_spec
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

AR2_FIELDS = ["a1", "a2", "mean", "sigma2", "q", "r", "p0"]
SLOW = [HealthCheck.too_slow, HealthCheck.filter_too_much]
LITERAL = r"-?(?:\d\.\d*e[+-]\d+f|std::numeric_limits<float>::infinity\(\)|kNaN)"


def _header_numbers(header: str, channel: int) -> list[float]:
    """bias, a1, a2, sigma2, mean, q, r, p0, saturation of one channel's initializer."""
    inits = re.findall(r"\{gyrodrift::ChannelFilter::.*?\}, *// \w\w", header, flags=re.S)
    nums = re.findall(LITERAL, inits[channel])
    out = []
    for lit in nums:
        if lit == "kNaN":
            out.append(math.nan)
        elif "infinity" in lit:
            out.append(-math.inf if lit.startswith("-") else math.inf)
        else:
            out.append(float(np.float32(lit.rstrip("f"))))  # a C++ float literal
    assert len(out) == 9, inits[channel]
    return out


def _with_gx(cfg: ProcessorConfig, **changes: float) -> ProcessorConfig:
    gx = cfg.channel("gx")
    stages = tuple(replace(s, **{k: v for k, v in changes.items() if k in AR2_FIELDS})
                   if isinstance(s, Ar2KalmanStage) else s for s in gx.stages)
    extra = {k: v for k, v in changes.items() if k == "saturation"}
    return cfg.with_channel("gx", replace(gx, stages=stages, **extra))


def _values(name: str) -> st.SearchStrategy[float]:
    f = field_spec("channel" if name == "saturation" else "ar2_kalman", name)
    lo = -FLOAT32_MAX if f.lo is None else f.lo
    hi = FLOAT32_MAX * 2 if f.hi is None else f.hi
    edges = [lo, hi, FLOAT32_MIN_NORMAL, FLOAT32_MIN_NORMAL * 0.99, 1e-50, 1e39, 3.5e38,
             math.nextafter(hi, math.inf), hi * (1 + 1e-7), 0.0]
    return st.one_of(st.floats(lo, hi, allow_nan=False), st.sampled_from(edges),
                     st.floats(-1e-30, 1e-30), st.floats(allow_nan=False, allow_infinity=False))


def _check_built(cfg: ProcessorConfig, channel: int = 0) -> None:
    proc = ImuProcessor(cfg, dtype=np.float32)  # raises if the float processor refuses
    assert proc is not None
    header = emit_cpp(cfg)
    got = _header_numbers(header, channel)
    cc = cfg.channels[channel]
    ar = next((s for s in cc.stages if isinstance(s, Ar2KalmanStage)), None)
    bias = next((s.bias for s in cc.stages if isinstance(s, BiasRemoval)), 0.0)
    want = [bias]
    want += ([ar.a1, ar.a2, ar.sigma2_value, ar.mean, ar.q, ar.r, ar.p0] if ar is not None
             else [math.nan] * 6 + [field_spec("ar2_kalman", "p0").default])
    want.append(cc.saturation)
    for g, w in zip(got, want, strict=True):
        if math.isnan(w):
            assert math.isnan(g)
        else:
            assert g == float(np.float32(w)), (got, want)  # exact: the float32 round trip


@pytest.mark.parametrize("name", [*AR2_FIELDS, "saturation"])
@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=SLOW)
@given(data=st.data())
def test_every_accepted_value_builds_the_float_processor_and_header(name: str,
                                                                    data: st.DataObject) -> None:
    x = data.draw(_values(name))
    try:
        cfg = _with_gx(default_config(), **{name: x})
    except ConfigError as exc:
        key = "saturation_rad_s" if name == "saturation" else \
            ("mean_rad_s" if name == "mean" else name)
        assert exc.key.endswith(key) or exc.key.endswith(".a1"), str(exc)
        assume(False)
        return
    _check_built(cfg)
    # and the file reads back to the same configuration
    assert parse_config(dumps_config(cfg)) == cfg


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=SLOW)
@given(a1=st.floats(-2.0, 2.0), a2=st.floats(-1.0, 1.0))
def test_every_accepted_ar2_model_builds(a1: float, a2: float) -> None:
    try:
        cfg = _with_gx(default_config(), a1=a1, a2=a2)
    except ConfigError as exc:
        assert exc.key in ("channels.gx.stages[1].a1", "channels.gx.stages[1].a2"), str(exc)
        assume(False)
        return
    _check_built(cfg)


def test_bias_of_an_accelerometer_round_trips() -> None:
    cfg = default_config()
    for b in (1e-37, -3.0e38, 0.1):
        ax = cfg.channel("ax")
        c2 = cfg.with_channel("ax", replace(ax, stages=(BiasRemoval(bias=b),)))
        _check_built(c2, channel=3)


@pytest.mark.parametrize("name,value,key", [
    ("r", 1e-50, "channels.gx.stages[1].r"),
    ("q", 1e39, "channels.gx.stages[1].q"),
    ("mean", 3e38, "channels.gx.stages[1].mean_rad_s"),
    ("saturation", 1e-50, "channels.gx.saturation_rad_s"),
    ("a1", 0.999999999, "channels.gx.stages[1].a1"),
])
def test_values_valid_in_double_but_not_in_float32_are_refused(name: str, value: float,
                                                               key: str) -> None:
    changes = {name: value}
    if name == "a1":
        changes["a2"] = 0.0  # a1 + a2 rounds to 1: a unit root in float32
    with pytest.raises(ConfigError) as info:
        _with_gx(default_config(), **changes)
    assert info.value.key == key, str(info.value)


def test_float32_fields_are_the_processors_floats() -> None:
    names = {f.name for f in FIELDS if f.float32 and f.section != "monitor"}
    assert names == {"saturation", "bias", "a1", "a2", "mean", "sigma2", "q", "r", "p0"}
    # the gyro monitor holds its factors, probabilities and guards as float32 too
    monitor = {f.name for f in FIELDS if f.float32 and f.section == "monitor"}
    assert monitor == {"coverage", "arw_factor", "bias_instability_factor",
                       "rate_random_walk_factor", "false_alarm_probability", "max_step",
                       "identified_max_rel_stderr"}


def test_the_float_processor_names_the_channel() -> None:
    # A processor built in code (no configuration file, so no validator): r = 1e-50 is 0 in
    # float32, the float processor refuses it and says which channel.
    from gyrodrift.imu.processor import ImuChannelConfig, ImuConfig

    chans = [ImuChannelConfig() for _ in range(6)]
    chans[2] = ImuChannelConfig(filter="ar2_kalman", a1=0.5, a2=0.1, mean=0.0, sigma2=1e-10,
                                q=1e-10, r=1e-50)
    ImuProcessor(ImuConfig(channels=chans))  # fine in double
    with pytest.raises(ValueError, match=r"^channels\.gz: invalid IMU processor configuration "
                                         r"in float32: "):
        ImuProcessor(ImuConfig(channels=chans), dtype=np.float32)
