"""Online re-identification of the drift model, sample by sample, on the C++ core the target
runs (include/gyrodrift/filters/online_drift_identifier.hpp).

Model (that of :func:`gyrodrift.filters.drift_model.fit_drift_model`), on a rate record y:

    x_k = a1 x_{k-1} + a2 x_{k-2} + w_k,   w_k ~ N(0, q)
    y_k = mean + x_k + v_k,                 v_k ~ N(0, r)

Estimator: recursive prediction error (Ljung & Soderstrom 1983, the recursive Gauss-Newton
algorithm) on the exact Kalman innovations, parameters (tanh-transformed partial
autocorrelations, log q, log r) updated once per block of ``block_samples`` samples, the
innovations' sensitivities from three perturbed filter copies, the mean a running mean.
Without forgetting (``memory_blocks = 0``) it converges to the offline maximum-likelihood fit
from a start in its basin (the configured model); with forgetting it tracks a change, best
with ``adapt_ar=False`` (a1, a2 held, q and r tracked). The steady-state AR(2)-Kalman gain is
retuned every ``retune_blocks`` blocks, only after ``min_samples`` samples, only when the
drift/white split is identified (relative standard errors of q and r at most
``max_rel_stderr``) and the estimate is finite, stationary, off its bounds and describes the
data (normalised innovation power within ``max_innovation_ratio``); otherwise the configured
model and its gain are in use. Measurements: docs/validation/online-identification.md.

:class:`SharedDriftIdentifier` is the identifier the processor's gyro monitor runs for several
watched gyros: one estimator shared in turns of one block among up to three channels
(include/gyrodrift/filters/shared_drift_identifier.hpp).

``dtype=np.float32`` runs the float state the microcontroller uses.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from gyrodrift._native import core
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError

__all__ = [
    "ONLINE_DRIFT_STATUS",
    "DriftParams",
    "OnlineDriftIdentifier",
    "OnlineDriftSettings",
    "OnlineDriftTrace",
    "SharedDriftIdentifier",
]

#: Status names by code (the C++ OnlineDriftStatus).
ONLINE_DRIFT_STATUS = ("unconfigured", "learning", "tracking", "not_identified", "fallback")


@dataclass(frozen=True)
class DriftParams:
    """Parameters of the drift model: a1, a2, q, r in (record units)^2, mean in record units.

    Examples
    --------
    >>> DriftParams(0.6868, -0.0213, 0.5, 1.0, 0.0).as_dict()["q"]
    0.5
    """

    a1: float
    a2: float
    q: float
    r: float
    mean: float

    @classmethod
    def from_fit(cls, fit: Any) -> DriftParams:
        """The parameters of an offline fit
        (a :class:`~gyrodrift.filters.drift_model.DriftModelFit`).

        Examples
        --------
        >>> import numpy as np
        >>> from gyrodrift.filters.drift_model import fit_drift_model
        >>> y = np.random.default_rng(0).normal(size=3000)
        >>> DriftParams.from_fit(fit_drift_model(y, rate_hz=100.0, model="white")).a1
        0.0
        """
        return cls(float(fit.a1), float(fit.a2), float(fit.q), float(fit.r), float(fit.mean))

    def as_dict(self) -> dict[str, float]:
        """JSON-ready values.

        Examples
        --------
        >>> sorted(DriftParams(0.1, 0.0, 1.0, 2.0, 3.0).as_dict())
        ['a1', 'a2', 'mean', 'q', 'r']
        """
        return asdict(self)


@dataclass(frozen=True)
class OnlineDriftSettings:
    """Settings of the online identifier (the C++ OnlineDriftSettings; defaults from there).

    Attributes
    ----------
    block_samples : int
        Samples per parameter update (>= 8).
    retune_blocks : int
        Parameter updates between gain retunes (>= 1).
    min_samples : int
        No retune before this many accepted samples.
    memory_blocks : float
        Forgetting horizon in blocks (0: none, the estimate converges to the ML fit; else >= 1).
    max_step : float
        Largest change of one parameter (log q, log r, the tanh pre-images of the partial
        autocorrelations) per update; the step is scaled as a whole.
    max_rel_stderr : float
        The split is identified when the relative standard errors of q and r are <= this.
    max_innovation_ratio : float
        Divergence guard: the mean e^2/F over a retune interval must be in [1/ratio, ratio].
    ar_order : int
        2, or 1 (a2 held at 0; the configured a2 must be 0).
    warmup_blocks, lambda_start : float
        Start-up schedule of the gain (lambda_1 = lambda_start, lambda_k -> 1 with time
        constant warmup_blocks; warmup_blocks = 0: gain 1/k from the start).
    adapt_ar : bool
        False: a1, a2 held at the configured model, only q and r identified.
    info_blocks : float
        Memory of the information matrix in blocks (0: as long as the estimate's; else >= 1).
    min_ar_wald : float
        With adapt_ar: the split counts as identified only if the Wald statistic of the AR
        part against white drift is at least this (chi-square, 2 degrees of freedom).

    Examples
    --------
    >>> OnlineDriftSettings(block_samples=200).retune_blocks
    60
    >>> OnlineDriftSettings(block_samples=4)
    Traceback (most recent call last):
    ...
    gyrodrift.errors.GyrodriftValueError: OnlineDriftSettings: block_samples must be >= 8
    """

    block_samples: int = 400
    retune_blocks: int = 60
    min_samples: int = 240000
    memory_blocks: float = 0.0
    max_step: float = 0.1
    max_rel_stderr: float = 0.5
    max_innovation_ratio: float = 3.0
    ar_order: int = 2
    warmup_blocks: float = 50.0
    lambda_start: float = 0.7
    adapt_ar: bool = True
    info_blocks: float = 50.0
    min_ar_wald: float = 25.0

    def __post_init__(self) -> None:
        for name in ("block_samples", "retune_blocks", "min_samples", "ar_order"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                raise GyrodriftTypeError(
                    f"OnlineDriftSettings: {name} must be an integer, got {v!r}")
        for name in ("memory_blocks", "max_step", "max_rel_stderr", "max_innovation_ratio",
                     "warmup_blocks", "lambda_start", "info_blocks", "min_ar_wald"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise GyrodriftTypeError(f"OnlineDriftSettings: {name} must be a number, got {v!r}")
        if not isinstance(self.adapt_ar, (bool, np.bool_)):
            raise GyrodriftTypeError(
                f"OnlineDriftSettings: adapt_ar must be a bool, got {self.adapt_ar!r}")
        problem = _settings_problem(self)
        if problem:
            raise GyrodriftValueError(f"OnlineDriftSettings: {problem}")

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready values.

        Examples
        --------
        >>> OnlineDriftSettings().as_dict()["block_samples"]
        400
        """
        return asdict(self)

    def _native(self, lib: Any) -> Any:
        return lib.OnlineDriftSettings(
            block_samples=int(self.block_samples), retune_blocks=int(self.retune_blocks),
            min_samples=int(self.min_samples), memory_blocks=float(self.memory_blocks),
            max_step=float(self.max_step), max_rel_stderr=float(self.max_rel_stderr),
            max_innovation_ratio=float(self.max_innovation_ratio), ar_order=int(self.ar_order),
            warmup_blocks=float(self.warmup_blocks), lambda_start=float(self.lambda_start),
            adapt_ar=bool(self.adapt_ar), info_blocks=float(self.info_blocks),
            min_ar_wald=float(self.min_ar_wald))


def _settings_problem(s: OnlineDriftSettings) -> str:
    def finite(v: float) -> bool:
        return math.isfinite(float(v))

    if not 8 <= s.block_samples < 2**32:
        return "block_samples must be >= 8"
    if not 1 <= s.retune_blocks < 2**32:
        return "retune_blocks must be >= 1"
    if not 0 <= s.min_samples < 2**64:
        return "min_samples must be >= 0"
    if not finite(s.memory_blocks) or not (s.memory_blocks == 0 or s.memory_blocks >= 1):
        return "memory_blocks must be 0 (no forgetting) or a finite number >= 1"
    if not finite(s.max_step) or not s.max_step > 0:
        return "max_step must be a positive finite number"
    if not finite(s.max_rel_stderr) or not s.max_rel_stderr > 0:
        return "max_rel_stderr must be a positive finite number"
    if not finite(s.max_innovation_ratio) or not s.max_innovation_ratio > 1:
        return "max_innovation_ratio must be a finite number > 1"
    if s.ar_order not in (1, 2):
        return "ar_order must be 1 or 2"
    if not finite(s.warmup_blocks) or not (s.warmup_blocks == 0 or s.warmup_blocks >= 1):
        return "warmup_blocks must be 0 (gain 1/k from the start) or a finite number >= 1"
    if not 0 < s.lambda_start <= 1:
        return "lambda_start must be in (0, 1]"
    if not finite(s.info_blocks) or not (s.info_blocks == 0 or s.info_blocks >= 1):
        return "info_blocks must be 0 or a finite number >= 1"
    if not finite(s.min_ar_wald) or not s.min_ar_wald >= 0:
        return "min_ar_wald must be a finite number >= 0"
    return ""


@dataclass(frozen=True)
class OnlineDriftTrace:
    """The identifier's state after each block (parameter update) completed by one push.

    Attributes
    ----------
    samples : ndarray (n,) int64
        Accepted samples so far at the end of each block.
    estimate, in_use : ndarray (n, 5)
        (a1, a2, q, r, mean) of the running estimate and of the gain's model.
    gain : ndarray (n, 2)
        Steady-state Kalman gain (k0, k1) of in_use.
    status : ndarray (n,) uint8
        Status codes (names in ``ONLINE_DRIFT_STATUS``).
    stderr : ndarray (n, 5)
        Standard errors of the estimate (NaN while unavailable).
    retuned : ndarray (n,) bool
        The gain changed during the block (a retune, or the configured gain put back).

    Examples
    --------
    >>> t = OnlineDriftTrace.empty()
    >>> t.estimate.shape, t.status_names
    ((0, 5), [])
    """

    samples: np.ndarray
    estimate: np.ndarray
    in_use: np.ndarray
    gain: np.ndarray
    status: np.ndarray
    stderr: np.ndarray
    retuned: np.ndarray

    @classmethod
    def empty(cls) -> OnlineDriftTrace:
        """A trace with no block.

        Examples
        --------
        >>> len(OnlineDriftTrace.empty().samples)
        0
        """
        return cls(np.zeros(0, np.int64), np.zeros((0, 5)), np.zeros((0, 5)), np.zeros((0, 2)),
                   np.zeros(0, np.uint8), np.zeros((0, 5)), np.zeros(0, bool))

    @property
    def status_names(self) -> list[str]:
        """Status names per block."""
        return [ONLINE_DRIFT_STATUS[int(c)] for c in self.status]

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready values (lists; NaN as None).

        Examples
        --------
        >>> OnlineDriftTrace.empty().as_dict()["status"]
        []
        """
        def clean(a: np.ndarray) -> list[Any]:
            return [None if isinstance(v, float) and not math.isfinite(v) else v
                    for v in a.tolist()] if a.ndim == 1 else [clean(row) for row in a]
        return {"samples": self.samples.tolist(), "estimate": clean(self.estimate),
                "in_use": clean(self.in_use), "gain": clean(self.gain),
                "status": self.status_names, "stderr": clean(self.stderr),
                "retuned": self.retuned.tolist()}



def _settings_dtype_class(settings: OnlineDriftSettings | None, dtype: DTypeLike,
                          name: str) -> tuple[OnlineDriftSettings, np.dtype[Any], Any]:
    """The settings (the defaults for None), the state's dtype and the bound class `name`
    (its F32 twin for float32), each checked."""
    chosen = settings if settings is not None else OnlineDriftSettings()
    if not isinstance(chosen, OnlineDriftSettings):
        raise GyrodriftTypeError(
            f"settings must be an OnlineDriftSettings, got {type(settings).__name__}")
    dt = np.dtype(dtype)
    if dt not in (np.float64, np.float32):
        raise GyrodriftValueError(f"dtype must be float64 or float32, got {dt}")
    return chosen, dt, getattr(core("drift"), name if dt == np.float64 else name + "F32")

class OnlineDriftIdentifier:
    """Online identifier of the drift model with guarded retunes of the steady-state gain.

    Parameters
    ----------
    configured : DriftParams
        The configured model: the start of the estimate and the fallback (r > 0; stationary).
    settings : OnlineDriftSettings, optional
        Defaults as in the C++ core.
    dtype : numpy dtype, optional
        ``np.float64`` (default) or ``np.float32`` (the float state of the target).

    Raises
    ------
    GyrodriftValueError
        The configured model is refused (not stationary, r <= 0, non-finite, a2 != 0 with
        ar_order 1) or another dtype.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> rng = np.random.default_rng(1)
    >>> x = lfilter([1.0], [1.0, -0.2297, -0.1638], rng.normal(size=60000))
    >>> y = 2.0 + x + rng.normal(size=60000)
    >>> ident = OnlineDriftIdentifier(DriftParams(0.2, 0.1, 1.5, 0.7, 0.0),
    ...                               OnlineDriftSettings(block_samples=200, retune_blocks=20,
    ...                                                   min_samples=20000))
    >>> trace = ident.push(y)          # one row per block of 200 samples
    >>> len(trace.samples), ident.status, ident.retunes > 0
    (300, 'tracking', True)
    >>> round(ident.estimate.mean, 1), bool(abs(ident.estimate.q - 1.0) < 0.5)
    (2.0, True)
    """

    def __init__(self, configured: DriftParams, settings: OnlineDriftSettings | None = None, *,
                 dtype: DTypeLike = np.float64) -> None:
        if not isinstance(configured, DriftParams):
            raise GyrodriftTypeError(
                f"configured must be a DriftParams, got {type(configured).__name__}")
        self._settings, self._dtype, cls = _settings_dtype_class(settings, dtype,
                                                                 "OnlineDriftIdentifier")
        try:
            self._impl: Any = cls(a1=float(configured.a1), a2=float(configured.a2),
                                  q=float(configured.q), r=float(configured.r),
                                  mean=float(configured.mean),
                                  settings=self._settings._native(core("drift")))
        except ValueError as exc:
            raise GyrodriftValueError(str(exc)) from None

    def push(self, y: ArrayLike) -> OnlineDriftTrace:
        """Run rate samples through the identifier in time order (GIL released).

        Non-finite samples are skipped and counted in :attr:`rejected`. Returns the state after
        each block completed during this call.

        Raises
        ------
        GyrodriftValueError
            y is not one-dimensional.
        """
        arr = np.ascontiguousarray(y, dtype=self._dtype)
        if arr.ndim != 1:
            raise GyrodriftValueError(f"y: expected a 1-D array, got shape {arr.shape}")
        _, samples, est, use, gain, status, se, retuned = self._impl.push(arr)
        return OnlineDriftTrace(np.asarray(samples), np.asarray(est), np.asarray(use),
                                np.asarray(gain), np.asarray(status), np.asarray(se),
                                np.asarray(retuned))

    def reset(self) -> None:
        """Back to the configured model, counters cleared."""
        self._impl.reset()

    @property
    def settings(self) -> OnlineDriftSettings:
        """The settings."""
        return self._settings

    @property
    def dtype(self) -> np.dtype[Any]:
        """The precision of the state (float64 or float32)."""
        return self._dtype

    @property
    def status(self) -> str:
        """One of ``ONLINE_DRIFT_STATUS``."""
        return ONLINE_DRIFT_STATUS[int(self._impl.status)]

    @property
    def configured(self) -> DriftParams:
        """The configured model (as stored in the state's precision)."""
        return DriftParams(*self._impl.configured)

    @property
    def estimate(self) -> DriftParams:
        """The running estimate."""
        return DriftParams(*self._impl.estimate)

    @property
    def in_use(self) -> DriftParams:
        """The model of the current gain."""
        return DriftParams(*self._impl.in_use)

    @property
    def stderr(self) -> DriftParams | None:
        """Approximate standard errors of the estimate, or None while unavailable."""
        se = self._impl.stderrs
        return None if se is None else DriftParams(*se)

    @property
    def gain(self) -> tuple[float, float]:
        """Steady-state Kalman gain (k0, k1) of :attr:`in_use`."""
        k0, k1 = self._impl.gain
        return float(k0), float(k1)

    @property
    def samples(self) -> int:
        """Samples accepted so far."""
        return int(self._impl.samples)

    @property
    def rejected(self) -> int:
        """Non-finite samples skipped so far."""
        return int(self._impl.rejected)

    @property
    def blocks(self) -> int:
        """Parameter updates so far."""
        return int(self._impl.blocks)

    @property
    def retunes(self) -> int:
        """Accepted gain retunes."""
        return int(self._impl.retunes)

    @property
    def refused_retunes(self) -> int:
        """Retunes refused by a guard (the configured model then in use)."""
        return int(self._impl.refused_retunes)

    @property
    def state_bytes(self) -> int:
        """Size of the C++ identifier's state in this precision (bytes)."""
        return int(self._impl.state_bytes)


class SharedDriftIdentifier:
    """One online identifier shared among 1 to 3 gyro channels in turns of one block, as the
    processor's gyro monitor re-identifies its watched gyros (the C++ SharedDriftIdentifier).

    The channels take turns of one block each, in channel order: during its turn a channel's
    samples run through the estimator's filters and block sums, at the end of the block come
    its parameter update and, every ``retune_blocks`` of its blocks, its gain retune; the other
    channels' samples only move their running means and sample counts. Each channel keeps its
    own configured model, estimate, gain, status and counters.

    Parameters
    ----------
    configured : sequence of DriftParams
        One configured model per channel (1 to :attr:`capacity`), the start and fallback of
        that channel's estimate.
    settings : OnlineDriftSettings, optional
        One setting for all channels; defaults as in the C++ core.
    dtype : numpy dtype, optional
        ``np.float64`` (default) or ``np.float32`` (the float state of the target).

    Raises
    ------
    GyrodriftValueError
        No channel, more than :attr:`capacity`, a refused model (named by its channel) or
        another dtype.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> rng = np.random.default_rng(1)
    >>> y = np.stack([lfilter([1.0], [1.0, -0.2297, -0.1638], rng.normal(size=6000))
    ...               + rng.normal(size=6000) for _ in range(3)], axis=1)
    >>> cfg = DriftParams(0.2, 0.1, 1.5, 0.7, 0.0)
    >>> ident = SharedDriftIdentifier([cfg] * 3, OnlineDriftSettings(block_samples=200))
    >>> traces = ident.push(y)   # rows of (gx, gy, gz) samples, one trace per channel
    >>> [len(t.samples) for t in traces]   # each channel ran one block in three
    [10, 10, 10]
    >>> [int(v) for v in traces[1].samples[:2]]   # its blocks end 3 * 200 - 2 samples apart
    [399, 997]
    """

    #: Channels one shared identifier serves (the processor's gyro monitor slots).
    capacity = 3

    def __init__(self, configured: Sequence[DriftParams],
                 settings: OnlineDriftSettings | None = None, *,
                 dtype: DTypeLike = np.float64) -> None:
        models = list(configured)
        if not models or not all(isinstance(m, DriftParams) for m in models):
            raise GyrodriftTypeError("configured must be a non-empty sequence of DriftParams")
        if len(models) > self.capacity:
            raise GyrodriftValueError(
                f"SharedDriftIdentifier: at most {self.capacity} channels, got {len(models)}")
        self._settings, self._dtype, cls = _settings_dtype_class(settings, dtype,
                                                                 "SharedDriftIdentifier")
        table = np.array([[m.a1, m.a2, m.q, m.r, m.mean] for m in models], dtype=np.float64)
        try:
            self._impl: Any = cls(models=table, settings=self._settings._native(core("drift")))
        except ValueError as exc:
            raise GyrodriftValueError(str(exc)) from None
        self._n = len(models)

    def push(self, y: ArrayLike) -> list[OnlineDriftTrace]:
        """Run rows of samples, one column per channel, in time order (GIL released).

        Each row's samples go in channel order, as the processor steps its watched gyros.
        Non-finite samples are skipped and counted in :meth:`rejected`. Returns one trace per
        channel with the state after each of its blocks completed during this call (``samples``:
        the channel's accepted samples at the end of the block; ``stderr`` is NaN: the shared
        identifier does not report standard errors).

        Raises
        ------
        GyrodriftValueError
            y is not of shape (samples, channels).
        """
        arr = np.ascontiguousarray(y, dtype=self._dtype)
        if arr.ndim == 1 and self._n == 1:
            arr = arr.reshape(-1, 1)
        if arr.ndim != 2 or arr.shape[1] != self._n:
            raise GyrodriftValueError(
                f"y: expected shape (samples, {self._n}), got shape {arr.shape}")
        channel, samples, est, use, gain, status, retuned = self._impl.push(arr)
        channel = np.asarray(channel)
        out = []
        for c in range(self._n):
            sel = channel == c
            nb = int(np.count_nonzero(sel))
            out.append(OnlineDriftTrace(np.asarray(samples)[sel], np.asarray(est)[sel],
                                        np.asarray(use)[sel], np.asarray(gain)[sel],
                                        np.asarray(status)[sel], np.full((nb, 5), np.nan),
                                        np.asarray(retuned)[sel]))
        return out

    def reset(self) -> None:
        """Every channel back to its configured model, counters cleared, the turn at channel 0."""
        self._impl.reset()

    @property
    def channels(self) -> int:
        """Channels configured."""
        return self._n

    @property
    def turn(self) -> int:
        """The channel whose block runs now."""
        return int(self._impl.turn)

    @property
    def settings(self) -> OnlineDriftSettings:
        """The settings (one for all channels)."""
        return self._settings

    @property
    def dtype(self) -> np.dtype[Any]:
        """The precision of the state (float64 or float32)."""
        return self._dtype

    def _check(self, c: int) -> int:
        if isinstance(c, bool) or not isinstance(c, (int, np.integer)) or not 0 <= c < self._n:
            raise GyrodriftValueError(f"channel {c!r} out of range (0 to {self._n - 1})")
        return int(c)

    def status(self, c: int) -> str:
        """Channel c's status, one of ``ONLINE_DRIFT_STATUS``."""
        return ONLINE_DRIFT_STATUS[int(self._impl.status(self._check(c)))]

    def configured(self, c: int) -> DriftParams:
        """Channel c's configured model (as stored in the state's precision)."""
        return DriftParams(*self._impl.configured(self._check(c)))

    def estimate(self, c: int) -> DriftParams:
        """Channel c's running estimate."""
        return DriftParams(*self._impl.estimate(self._check(c)))

    def in_use(self, c: int) -> DriftParams:
        """The model of channel c's current gain."""
        return DriftParams(*self._impl.in_use(self._check(c)))

    def gain(self, c: int) -> tuple[float, float]:
        """Steady-state Kalman gain (k0, k1) of channel c's :meth:`in_use`."""
        k0, k1 = self._impl.gain(self._check(c))
        return float(k0), float(k1)

    def samples(self, c: int) -> int:
        """Samples of channel c accepted so far (all of them, not only its turns')."""
        return int(self._impl.samples(self._check(c)))

    def rejected(self, c: int) -> int:
        """Non-finite samples of channel c skipped so far."""
        return int(self._impl.rejected(self._check(c)))

    def blocks(self, c: int) -> int:
        """Channel c's parameter updates (its turns) so far."""
        return int(self._impl.blocks(self._check(c)))

    def retunes(self, c: int) -> int:
        """Channel c's accepted gain retunes."""
        return int(self._impl.retunes(self._check(c)))

    def refused_retunes(self, c: int) -> int:
        """Channel c's retunes refused by a guard (its configured model then in use)."""
        return int(self._impl.refused_retunes(self._check(c)))

    @property
    def state_bytes(self) -> int:
        """Size of the C++ shared identifier's state (three channels) in this precision (bytes)."""
        return int(self._impl.state_bytes)
