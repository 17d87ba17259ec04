"""Health alarms of one gyro channel on the C++ code the target runs
(include/gyrodrift/imu/health_alarms.hpp): the streaming Allan variance leaves the reference
curve (angle random walk, bias instability or rate random walk up by more than a factor, with
statistical significance), or the channel is stuck or saturated for too many samples in a
row. Alarms are latched, counted, and keep the statistic that tripped them.

The reference is the expected Allan variance at tau = 2^k / rate, k = 0 .. n_octaves - 1
(:mod:`gyrodrift.stability.model_allan`: from the drift model or IEEE 952 terms). Each octave
belongs to one alarm by the reference's local slope: the leading octaves where it falls like
white noise to ``arw_high``, later rising octaves to ``rate_random_walk_high``, the others
to ``bias_instability_high``. Each time ``block_terms`` new squared differences have arrived
at an octave (and at each new one while it has fewer), their Allan variance over the
reference is compared with max(factor^2, chi2_{1-p}(edf) / edf), p the
``false_alarm_probability`` per test (docs/guides/health-alarms.md).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from gyrodrift._native import core
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.stability.allan import ONE_SIGMA_CI
from gyrodrift.stability.online_noise import NoiseEstimates, noise_from_tuple
from gyrodrift.stability.streaming import MAX_OCTAVES

__all__ = ["HEALTH_ALARMS", "HealthAlarmSettings", "HealthAlarms", "HealthTrip", "alarm_names"]

#: The alarm names in bit order (bit i = 1 << i).
HEALTH_ALARMS: tuple[str, ...] = ("arw_high", "bias_instability_high", "rate_random_walk_high",
                                  "stuck", "saturated")


def alarm_names(bits: int) -> list[str]:
    """The names of the alarms set in ``bits``.

    Examples
    --------
    >>> alarm_names(0b01001)
    ['arw_high', 'stuck']
    >>> alarm_names(0)
    []
    """
    return [name for i, name in enumerate(HEALTH_ALARMS) if int(bits) & (1 << i)]


@dataclass(frozen=True)
class HealthAlarmSettings:
    """Settings of the health alarms (defaults those of the C++ struct).

    Attributes:
        arw_factor: alarm when N is up by more than this factor (the short octaves' Allan
            variance above factor^2 times the reference), >= 1.
        bias_instability_factor: the same for B (octaves around the reference's minimum).
        rate_random_walk_factor: the same for K (the long, rising octaves).
        false_alarm_probability: per test, for the chi-square bound, in (0, 0.5].
        stuck_samples: stuck this many samples in a row raises ``stuck`` (0: off).
        saturated_samples: saturated this many samples in a row raises ``saturated`` (0: off).
        block_terms: squared differences per block test at each octave (>= 4).

    Examples
    --------
    >>> s = HealthAlarmSettings(arw_factor=1.5)
    >>> s.arw_factor, s.block_terms
    (1.5, 64)
    """

    arw_factor: float = 2.0
    bias_instability_factor: float = 2.0
    rate_random_walk_factor: float = 2.0
    false_alarm_probability: float = 1e-6
    stuck_samples: int = 0
    saturated_samples: int = 0
    block_terms: int = 64

    def __post_init__(self) -> None:
        for name in ("arw_factor", "bias_instability_factor", "rate_random_walk_factor"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 1.0):
                raise GyrodriftValueError(f"{name} must be a finite number >= 1, got {v!r}")
        if not 0.0 < self.false_alarm_probability <= 0.5:
            raise GyrodriftValueError("false_alarm_probability must lie in (0, 0.5], got "
                                      f"{self.false_alarm_probability!r}")
        for name, low in (("stuck_samples", 0), ("saturated_samples", 0), ("block_terms", 4)):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or not low <= int(v) < 2 ** 32:
                raise GyrodriftValueError(f"{name} must be an integer in {low}..2^32-1, got {v!r}")

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def _native(self) -> Any:
        s = core("allan").HealthAlarmSettings()
        for f in fields(self):
            setattr(s, f.name, getattr(self, f.name))
        return s


@dataclass(frozen=True)
class HealthTrip:
    """What raised an alarm (the first time since the last reset or unlatch).

    Attributes:
        name: the alarm.
        statistic: measured / expected Allan deviation (octave tests) or the run length
            (stuck, saturated).
        threshold: the value it exceeded.
        tau_s: averaging time of the octave (0 for stuck, saturated).
        sample: samples processed when it tripped (1-based).

    Examples
    --------
    >>> HealthTrip("stuck", 5.0, 5.0, 0.0, 12).as_dict()["sample"]
    12
    """

    name: str
    statistic: float
    threshold: float
    tau_s: float
    sample: int

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {"name": self.name, "statistic": self.statistic, "threshold": self.threshold,
                "tau_s": self.tau_s, "sample": self.sample}


class HealthAlarms:
    """A streaming Allan variance and the health alarms of one channel, sample by sample.

    Parameters
    ----------
    rate_hz : float
        Sample rate of the record.
    reference_avar : array_like
        Expected Allan variance at tau = 2^k / rate_hz, k = 0 .. len - 1 (record units^2;
        1 .. ``MAX_OCTAVES`` octaves, positive).
    settings : HealthAlarmSettings, optional
        The factors, the false-alarm probability, the stuck/saturated limits.
    edf_per_term : array_like, optional
        Degrees of freedom per squared difference of a block at each octave under the
        reference model (:func:`gyrodrift.stability.model_allan.ar2_white_edf_per_term` with
        ``n = settings.block_terms``); 0 or None: from the reference's local slope as a
        power law (exact for one power-law noise, optimistic where a smooth drift mixes in).
    dtype : numpy dtype, optional
        ``np.float64`` (default) or ``np.float32`` (the float state of the target).

    Raises
    ------
    GyrodriftValueError
        A bad rate, reference or dtype.

    Examples
    --------
    >>> import numpy as np
    >>> ref = 1.0 / 2.0 ** np.arange(6)  # white noise of variance 1
    >>> ha = HealthAlarms(100.0, ref, HealthAlarmSettings(stuck_samples=3))
    >>> y = np.random.default_rng(0).standard_normal(4000)
    >>> int(ha.run(y)[-1])  # healthy
    0
    >>> bits = ha.run(3.0 * y)  # N up 3x
    >>> alarm_names(int(bits[-1])), ha.raised["arw_high"]
    (['arw_high'], 1)
    >>> ha.trips["arw_high"].sample > 4000
    True
    """

    def __init__(self, rate_hz: float, reference_avar: ArrayLike,
                 settings: HealthAlarmSettings | None = None, *,
                 edf_per_term: ArrayLike | None = None,
                 dtype: DTypeLike = np.float64) -> None:
        rate = float(rate_hz)
        if not (np.isfinite(rate) and rate > 0.0):
            raise GyrodriftValueError(f"rate_hz must be a positive finite number, got {rate_hz!r}")
        ref = np.ascontiguousarray(reference_avar, dtype=np.float64)
        if ref.ndim != 1 or not 1 <= ref.size <= MAX_OCTAVES:
            raise GyrodriftValueError(
                f"reference_avar: expected 1..{MAX_OCTAVES} octaves, got shape {ref.shape}")
        if not (np.all(np.isfinite(ref)) and np.all(ref > 0.0)):
            raise GyrodriftValueError("reference_avar must be positive and finite")
        self._settings = settings if settings is not None else HealthAlarmSettings()
        if not isinstance(self._settings, HealthAlarmSettings):
            raise GyrodriftTypeError("settings must be a HealthAlarmSettings, got "
                                     f"{type(settings).__name__}")
        self._dtype = np.dtype(dtype)
        native = core("allan")
        if self._dtype == np.float64:
            cls = native.HealthAlarms
        elif self._dtype == np.float32:
            cls = native.HealthAlarmsF32
        else:
            raise GyrodriftValueError(f"dtype must be float64 or float32, got {self._dtype}")
        edf = None
        if edf_per_term is not None:
            edf = np.ascontiguousarray(edf_per_term, dtype=np.float64)
            if edf.shape != ref.shape or not np.all((edf >= 0.0) & (edf <= 1.0)):
                raise GyrodriftValueError(
                    "edf_per_term: expected one value in [0, 1] per octave of reference_avar")
        self._impl = cls(rate, ref, self._settings._native(), edf)
        self._rate_hz = rate
        self._ref = ref

    def run(self, y: ArrayLike, stuck: ArrayLike | None = None,
            saturated: ArrayLike | None = None, *, every: int = 1) -> np.ndarray:
        """Process samples in time order (continuing the record so far).

        Parameters
        ----------
        y : array_like
            Rate samples (record units; non-finite ones are skipped by the Allan variance).
        stuck, saturated : array_like of bool, optional
            The channel's per-sample flags (same length as y).
        every : int, optional
            Report the latched bits after every ``every``-th sample (and after the last).

        Returns
        -------
        numpy.ndarray
            uint16 latched alarm bits (bit i: ``HEALTH_ALARMS[i]``) per report.
        """
        arr = np.ascontiguousarray(y, dtype=self._dtype)
        if arr.ndim != 1:
            raise GyrodriftValueError(f"y: expected a 1-D array, got shape {arr.shape}")
        if isinstance(every, bool) or int(every) != every or int(every) < 1:
            raise GyrodriftValueError(f"every must be an integer >= 1, got {every!r}")
        flags: list[np.ndarray | None] = []
        for name, f in (("stuck", stuck), ("saturated", saturated)):
            if f is None:
                flags.append(None)
                continue
            fa = np.ascontiguousarray(f, dtype=bool)
            if fa.shape != arr.shape:
                raise GyrodriftValueError(f"{name}: expected shape {arr.shape}, got {fa.shape}")
            flags.append(fa)
        return np.asarray(self._impl.run(arr, flags[0], flags[1], int(every)))

    def estimate_noise(self, ci: float = ONE_SIGMA_CI) -> NoiseEstimates:
        """N, B, K from this channel's streaming Allan curve so far
        (:func:`gyrodrift.stability.online_noise.estimate_noise`).

        Examples
        --------
        >>> import numpy as np
        >>> ha = HealthAlarms(100.0, 1.0 / 2.0 ** np.arange(6))
        >>> _ = ha.run(np.random.default_rng(0).standard_normal(4000))
        >>> ha.estimate_noise(0.95).n.valid
        True
        """
        c = float(ci)
        if not 0.0 < c < 1.0:
            raise GyrodriftValueError(f"ci must lie in (0, 1), got {ci!r}")
        return noise_from_tuple(self._impl.estimate_noise(c), c)

    def reset(self) -> None:
        """Forget every sample, alarm, count and trip (the configuration stays)."""
        self._impl.reset()

    def unlatch(self) -> None:
        """Lower the latched alarms (counts and trips stay; a new raise records a new trip)."""
        self._impl.unlatch()

    @property
    def settings(self) -> HealthAlarmSettings:
        """The settings."""
        return self._settings

    @property
    def reference_avar(self) -> np.ndarray:
        """The reference curve."""
        return self._ref.copy()

    @property
    def latched(self) -> list[str]:
        """The alarms latched now."""
        return alarm_names(int(self._impl.latched))

    @property
    def raised(self) -> dict[str, int]:
        """Times each alarm was raised since the last reset."""
        return dict(zip(HEALTH_ALARMS, (int(v) for v in self._impl.raised), strict=True))

    @property
    def exceedances(self) -> dict[str, int]:
        """Failed tests of each alarm since the last reset (also while latched)."""
        return dict(zip(HEALTH_ALARMS, (int(v) for v in self._impl.exceedances), strict=True))

    @property
    def trips(self) -> dict[str, HealthTrip]:
        """What raised each alarm that was raised."""
        out = {}
        for name, count, t in zip(HEALTH_ALARMS, self._impl.raised, self._impl.trips,
                                  strict=True):
            if count:
                out[name] = HealthTrip(name, float(t[0]), float(t[1]), float(t[2]), int(t[3]))
        return out

    @property
    def octave_alarms(self) -> list[str]:
        """The alarm each octave's tests raise."""
        return [alarm_names(int(b))[0] for b in self._impl.octave_alarms]

    @property
    def avar(self) -> np.ndarray:
        """The streaming Allan variance so far (NaN before an octave has a term)."""
        return np.asarray(self._impl.avar)

    @property
    def samples(self) -> int:
        """Samples accepted by the Allan variance so far."""
        return int(self._impl.samples)

    @property
    def state_bytes(self) -> int:
        """sizeof the C++ alarm state at this precision for ``MAX_OCTAVES`` octaves."""
        return int(self._impl.state_bytes)
