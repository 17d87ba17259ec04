"""The IMU processor's bound configuration objects (_core.ImuProcessorSettings,
_core.ImuChannelSettings, _core.ImuWaveletSettings; CONTRIBUTING.md "Results and errors"):
keyword-only, closed to unknown fields, type- and range-checked when built and when used, field
names and defaults those of the configuration schema (gyrodrift.imu.schema), and the Python
dataclasses' defaults from the same schema."""

from __future__ import annotations

import math

import pytest
from gyrodrift import _core
from gyrodrift.imu import schema
from gyrodrift.imu.processor import ImuChannelConfig, ImuConfig, ImuProcessor, WaveletSettings

# The binding object holding each schema section's fields ("timing" has only the tolerance:
# the rates are the loop's, the processor takes period_us).
SECTION_OBJECT = {
    "channel": _core.ImuChannelSettings,
    "bias_removal": _core.ImuChannelSettings,
    "ar2_kalman": _core.ImuChannelSettings,
    "wavelet": _core.ImuWaveletSettings,
}
SHARED = [f for f in schema.FIELDS if f.section in SECTION_OBJECT]


def wavelet_stage(**kw: object) -> _core.ImuWaveletSettings:
    return _core.ImuWaveletSettings(**{**schema.PAPER_WAVELET, **kw})


def test_field_names_are_the_schema_names() -> None:
    assert {f.section for f in SHARED} == set(SECTION_OBJECT)
    channel = _core.ImuChannelSettings()
    stage = wavelet_stage()
    for f in SHARED:
        obj = stage if f.section == "wavelet" else channel
        assert hasattr(obj, f.name), f"{f.section}.{f.name}"
    assert hasattr(_core.ImuProcessorSettings(), "time_tolerance_us")
    # the detail handling is the schema's `threshold`, not the older `mode`
    assert not hasattr(stage, "mode")
    assert channel.wavelet is None


@pytest.mark.parametrize("f", SHARED, ids=lambda f: f"{f.section}.{f.name}")
def test_defaults_are_the_schema_defaults(f: schema.Field) -> None:
    if f.section == "wavelet":
        if f.required:  # wavelet, window, level must be given
            kw = {k: v for k, v in schema.PAPER_WAVELET.items() if k != f.name}
            with pytest.raises(TypeError):
                _core.ImuWaveletSettings(**kw)
        else:
            required = {k: schema.PAPER_WAVELET[k] for k in ("wavelet", "window", "level")}
            assert getattr(_core.ImuWaveletSettings(**required), f.name) == f.default
        return
    value = getattr(_core.ImuChannelSettings(), f.name)
    if f.required or f.default is None:
        # the model and variances are unset (NaN: the processor refuses an ar2_kalman stage
        # without them); the bias is 0 (subtracted after any chain without bias_removal)
        assert (value == 0.0) if f.name == "bias" else math.isnan(value)
    else:
        assert value == f.default and type(value) is type(f.default)


def test_processor_defaults_are_imu_config_defaults() -> None:
    s = _core.ImuProcessorSettings()
    rate = schema.DEFAULT_SAMPLE_RATE_HZ
    assert s.period_us == schema.default_period_us(rate) == _core.IMU_DEFAULT_PERIOD_US
    assert s.time_tolerance_us == schema.default_time_tolerance_us(rate)
    assert [c.filter for c in s.channels] == ["ar2_kalman"] * 3 + ["pass_through"] * 3
    assert all(c.filter2 == "pass_through" for c in s.channels)
    # gyro models unset: the processor is built but refuses everything (the C++ contract)
    assert _core.ImuProcessor(s).status == "bad channel config"


def test_python_dataclass_defaults_are_the_schema_defaults() -> None:
    ch = ImuChannelConfig()
    for section, name in (("ar2_kalman", "p0"), ("ar2_kalman", "steady_state"),
                          ("channel", "saturation"), ("channel", "stuck_samples")):
        assert getattr(ch, name) == schema.field_spec(section, name).default, name
    ws = WaveletSettings()
    assert (ws.wavelet, ws.window, ws.level, ws.threshold) == tuple(schema.PAPER_WAVELET.values())
    # and the binding's: a default dataclass channel gives a default binding channel
    b = _core.ImuChannelSettings()
    for name in ("filter", "filter2", "steady_state", "bias", "p0", "saturation",
                 "stuck_samples"):
        assert getattr(ch, name) == getattr(b, name), name


def test_keyword_only_and_closed() -> None:
    with pytest.raises(TypeError):  # keyword-only: no positional list
        _core.ImuWaveletSettings("db4", 256, 5, "forced")
    with pytest.raises(TypeError):
        _core.ImuChannelSettings("ar2_kalman")
    with pytest.raises(TypeError):
        _core.ImuProcessorSettings([_core.ImuChannelSettings()] * 6)
    for cls, kw in ((_core.ImuChannelSettings, {"filters": ["pass_through"]}),
                    (_core.ImuChannelSettings, {"mode": "soft"}),
                    (_core.ImuProcessorSettings, {"filters2": [0] * 6}),
                    (_core.ImuWaveletSettings, {**schema.PAPER_WAVELET, "mode": "soft"})):
        with pytest.raises(TypeError):  # an unknown field
            cls(**kw)
    for obj, name in ((_core.ImuChannelSettings(), "sigma"),
                      (_core.ImuProcessorSettings(), "period"), (wavelet_stage(), "mode")):
        with pytest.raises(AttributeError):  # a misspelt field is not silently added
            setattr(obj, name, 1)
    with pytest.raises(TypeError):  # the old positional processor is gone
        _core.ImuProcessor([0] * 6, [0.0] * 6)
    with pytest.raises(TypeError):
        _core.ImuProcessorF32()


@pytest.mark.parametrize("kw", [
    {"bias": "0.1"}, {"filter": 2}, {"steady_state": 1}, {"steady_state": None},
    {"stuck_samples": 1.5}, {"saturation": None}, {"wavelet": ("db4", 256, 5, "forced")},
    {"wavelet": schema.PAPER_WAVELET},
])
def test_channel_wrong_types(kw: dict[str, object]) -> None:
    with pytest.raises(TypeError):
        _core.ImuChannelSettings(**kw)


def test_wrong_types_elsewhere_and_on_assignment() -> None:
    with pytest.raises(TypeError):
        _core.ImuWaveletSettings(wavelet="db4", window=256.0, level=5)
    with pytest.raises(TypeError):
        _core.ImuProcessorSettings(channels=[{"filter": "pass_through"}] * 6)
    with pytest.raises(TypeError):
        _core.ImuProcessorSettings(period_us="2500")
    ch = _core.ImuChannelSettings()
    for name, value in (("steady_state", 1), ("steady_state", "yes"), ("q", "1e-10"),
                        ("stuck_samples", 2.0), ("wavelet", "db4")):
        with pytest.raises(TypeError):
            setattr(ch, name, value)
    ch.steady_state = True  # a bool is a bool
    assert ch.steady_state is True


def test_values_checked_when_built() -> None:
    with pytest.raises(ValueError, match=r"^filter: expected one of pass_through, bias_removal, "
                                         r"wavelet, ar2_kalman, got 'median'$"):
        _core.ImuChannelSettings(filter="median")
    with pytest.raises(ValueError, match=r"^filter2: expected one of"):
        _core.ImuChannelSettings(filter2="kalman")
    with pytest.raises(ValueError, match=r"^stuck_samples: expected 0\.\.4294967295, got -1$"):
        _core.ImuChannelSettings(stuck_samples=-1)
    with pytest.raises(ValueError, match=r"^wavelet\.threshold: expected one of forced, soft, "
                                         r"hard, got 'garrote'$"):
        _core.ImuChannelSettings(wavelet=_bad_threshold_stage())
    with pytest.raises(ValueError, match=r"^wavelet: expected one of db4, db8, got 'haar'$"):
        wavelet_stage(wavelet="haar")
    with pytest.raises(ValueError, match=r"^threshold: expected one of forced, soft, hard"):
        wavelet_stage(threshold="garrote")
    with pytest.raises(ValueError, match=r"^channels: expected 6 ImuChannelSettings, got 5$"):
        _core.ImuProcessorSettings(channels=[_core.ImuChannelSettings()] * 5)
    with pytest.raises(ValueError, match=r"^time_tolerance_us: expected 0\.\.4294967295 us"):
        _core.ImuProcessorSettings(time_tolerance_us=2**32)
    with pytest.raises(ValueError, match=r"^period_us: expected 0\.\.4294967295 us, got -1$"):
        _core.ImuProcessorSettings(period_us=-1)


def _bad_threshold_stage() -> _core.ImuWaveletSettings:
    stage = wavelet_stage()
    stage.threshold = "garrote"  # writable: checked again where it is used
    return stage


def test_values_checked_again_when_used() -> None:
    s = _core.ImuProcessorSettings(channels=[_core.ImuChannelSettings()] * 6)
    chans = s.channels
    chans[4].filter2 = "median"
    s.channels = chans
    with pytest.raises(ValueError, match=r"^channels\[4\]\.filter2: expected one of"):
        _core.ImuProcessor(s)
    s = _core.ImuProcessorSettings(channels=[_core.ImuChannelSettings()] * 6)
    s.time_tolerance_us = -5
    with pytest.raises(ValueError, match=r"^time_tolerance_us: expected"):
        _core.ImuProcessorF32(settings=s)
    s.time_tolerance_us = 0
    assert _core.ImuProcessorF32(settings=s).status == "ok"


def test_repr_round_trips() -> None:
    stage = wavelet_stage(level=4)
    assert repr(stage) == ("ImuWaveletSettings(wavelet='db4', window=256, level=4, "
                           "threshold='forced')")
    ch = _core.ImuChannelSettings(filter="wavelet", filter2="ar2_kalman", a1=1.0, a2=-0.25,
                                  sigma2=1e-10, mean=0.0, q=1e-10, r=1e-8, steady_state=True,
                                  wavelet=stage)
    ns = {"ImuChannelSettings": _core.ImuChannelSettings,
          "ImuWaveletSettings": _core.ImuWaveletSettings, "nan": math.nan, "inf": math.inf}
    again = eval(repr(ch), ns)  # our own repr
    assert repr(again) == repr(ch)
    s = _core.ImuProcessorSettings(channels=[ch] * 6, period_us=1000, time_tolerance_us=0)
    assert repr(s).startswith("ImuProcessorSettings(channels=[ImuChannelSettings(filter=")
    assert repr(s).endswith("period_us=1000, time_tolerance_us=0)")


def test_python_processor_turns_binding_refusals_into_package_errors() -> None:
    from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError

    chans = [ImuChannelConfig() for _ in range(6)]
    chans[2].stuck_samples = 2**32  # passes the dataclass check (>= 0), not the binding's
    with pytest.raises(GyrodriftValueError, match=r"^invalid IMU processor configuration: "
                                                  r"channels\[2\]: stuck_samples: expected "):
        ImuProcessor(ImuConfig(channels=chans))
    chans[2].stuck_samples = 0
    chans[3].bias = "0.1"  # type: ignore[assignment]
    with pytest.raises(GyrodriftTypeError, match=r"channels\[3\]: "):
        ImuProcessor(ImuConfig(channels=chans))
    chans[3].bias = 0.0
    with pytest.raises(GyrodriftValueError, match=r"channels\[0\]: wavelet: expected one of db4, "
                                                  r"db8, got 'haar'$"):
        ImuProcessor(ImuConfig(channels=[ImuChannelConfig(filter="wavelet"), *chans[1:]]),
                     wavelet=WaveletSettings(wavelet="haar"))
