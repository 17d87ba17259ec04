"""Bound configuration structs of the Allan and wavelet bindings (issue 9, CONTRIBUTING.md
"Results and errors"): one keyword-only object instead of a positional list, checked when built
and when used, closed to unknown fields."""

from __future__ import annotations

import numpy as np
import pytest
from gyrodrift import _core


def test_oadev_options_construct_and_use() -> None:
    o = _core.OadevOptions()
    assert (o.kind, o.method, o.block, o.threads) == ("rate", "fused", 65536, 1)
    o = _core.OadevOptions(kind="phase", method="per_tau", block=32, threads=2)
    assert repr(o) == "OadevOptions(kind='phase', method='per_tau', block=32, threads=2)"
    # a white phase record x = 0, 1, 0, 1, ...: second differences +-2, sigma2(m=1) = 4/2 = 2
    x = np.tile([0.0, 1.0], 50)
    s2, terms = _core.oadev_sigma2(x, np.array([1], dtype=np.int64), o)
    assert s2[0] == 2.0 and terms[0] == 98
    # the default options: rate input, fused kernel. y = 0, 1, 0, 1, ...: successive means
    # differ by 1 at m = 1, sigma2 = 1/2
    s2, terms = _core.oadev_sigma2(x, np.array([1], dtype=np.int64))
    assert s2[0] == 0.5 and terms[0] == 99


def test_oadev_options_reject_wrong_fields() -> None:
    with pytest.raises(TypeError):  # keyword-only: no positional list
        _core.OadevOptions("rate", "fused", 65536, 1)
    with pytest.raises(TypeError):  # an unknown field
        _core.OadevOptions(kinds="rate")
    o = _core.OadevOptions()
    with pytest.raises(AttributeError):  # closed: a misspelt field is not silently added
        o.thread = 4  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match="kind must be 'rate' or 'phase'"):
        _core.OadevOptions(kind="frequency")
    with pytest.raises(ValueError, match="method must be 'fused' or 'per_tau'"):
        _core.OadevOptions(method="fast")
    with pytest.raises(ValueError, match="block must be >= 16"):
        _core.OadevOptions(block=8)
    with pytest.raises(ValueError, match="threads must be >= 1"):
        _core.OadevOptions(threads=0)
    # writable fields are checked again when used
    o.threads = 0
    with pytest.raises(ValueError, match="threads must be >= 1"):
        _core.oadev_sigma2(np.zeros(16), np.array([1], dtype=np.int64), o)
    with pytest.raises(TypeError):  # the old positional form is gone
        _core.oadev_sigma2(np.zeros(16), np.array([1], dtype=np.int64), "rate", "fused")


def test_realtime_wavelet_config_construct_and_use() -> None:
    c = _core.RealtimeWaveletConfig(wavelet="db4", window=8, level=1)
    assert (c.wavelet, c.window, c.level, c.mode, c.channels) == ("db4", 8, 1, "forced", 1)
    assert repr(c) == ("RealtimeWaveletConfig(wavelet='db4', window=8, level=1, "
                       "mode='forced', channels=1)")
    bank = _core.RealtimeWaveletBankF64(c)
    assert bank.channels == 1 and bank.taps().shape == (8,)
    # the forced prefilter passes a constant unchanged once its window is full (DC gain 1)
    y = bank.filter(np.full(32, 2.5))
    np.testing.assert_allclose(y[8:], 2.5, rtol=1e-12)
    c3 = _core.RealtimeWaveletConfig(wavelet="db8", window=64, level=2, mode="soft", channels=3)
    assert _core.RealtimeWaveletBankF32(c3).channels == 3


def test_realtime_wavelet_config_rejects_wrong_fields() -> None:
    with pytest.raises(TypeError):  # keyword-only
        _core.RealtimeWaveletConfig("db4", 8, 1, "forced", 1)
    with pytest.raises(TypeError):  # wavelet, window and level are required
        _core.RealtimeWaveletConfig(wavelet="db4", window=8)
    with pytest.raises(TypeError):  # an unknown field
        _core.RealtimeWaveletConfig(wavelet="db4", window=8, level=1, threshold="soft")
    c = _core.RealtimeWaveletConfig(wavelet="db4", window=8, level=1)
    with pytest.raises(AttributeError):
        c.levels = 2  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match="unsupported wavelet"):
        _core.RealtimeWaveletConfig(wavelet="haar", window=8, level=1)
    with pytest.raises(ValueError, match="unsupported mode"):
        _core.RealtimeWaveletConfig(wavelet="db4", window=8, level=1, mode="garrote")
    with pytest.raises(ValueError, match="power of two"):
        _core.RealtimeWaveletConfig(wavelet="db4", window=100, level=1)
    with pytest.raises(ValueError, match="out of range"):
        _core.RealtimeWaveletConfig(wavelet="db8", window=8, level=3)
    with pytest.raises(ValueError, match="channels must be 1 or 3"):
        _core.RealtimeWaveletConfig(wavelet="db4", window=8, level=1, channels=2)
    c.channels = 2  # writable, checked again by the bank
    with pytest.raises(ValueError, match="channels must be 1 or 3"):
        _core.RealtimeWaveletBankF64(c)
    with pytest.raises(TypeError):  # the old positional form is gone
        _core.RealtimeWaveletBankF64("db4", 8, 1, "forced", 1)
