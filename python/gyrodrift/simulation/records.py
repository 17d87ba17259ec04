"""Seeded gyro and static-IMU noise simulator (IEEE Std 952-1997 error terms).

Every term is generated from its defining equation so that Allan-variance analysis of a
simulated record returns the input coefficients (IEEE Std 952, Annex C, table C.2):

    sigma^2(tau) = 3 Q^2 / tau^2 + N^2 / tau + (2 ln2 / pi) B^2 + K^2 tau / 3 + R^2 tau^2 / 2

with consistent units (Q in deg, N in deg/sqrt(h), B in deg/h, K in deg/h/sqrt(h), R in deg/h/h,
tau in h; the record itself is a rate in deg/h).

How each term is made (dt = 1 / rate_hz):

- quantization Q [deg]: a white *angle* error e_k ~ N(0, Q^2), differenced into rate
  (e_k - e_{k-1}) / dt. Allan of the angle second difference: 6 Q^2 / (2 tau^2) = 3 Q^2/tau^2.
- angle random walk N [deg/sqrt(h)]: white rate, std 60 N / sqrt(dt_s) deg/h (two-sided PSD
  N^2, so sigma^2 = N^2 / tau for block averages).
- bias instability B [deg/h]: flicker noise with two-sided PSD S(f) = B^2 / (2 pi f), made by
  shaping white Gaussian noise in the frequency domain (FFT of a record twice as long as
  requested, so the output does not wrap around; the DC bin is zero). The shaped band is
  f in [1 / (L dt), 1 / (2 dt)] with L >= 2 n and T = n dt. The expected Allan variance of
  the generated process (exact sum over the shaped spectrum) is within 3 % of the floor
  (2 ln2 / pi) B^2 (Allan deviation within 1.5 % of 0.664 B) for 4 dt <= tau <= T / 4, and
  within 1 % for 8 dt <= tau <= T / 10; below 4 dt the sampled spectrum lifts it (+19 % at
  tau = dt). tests/test_simulate.py checks these numbers and the generated records.
- rate random walk K [deg/h/sqrt(h)]: cumulative sum of white increments of std
  K sqrt(dt_h) = K sqrt(dt_s) / 60 deg/h; exact discrete Allan variance
  s^2 (2 m^2 + 1) / (6 m) for tau = m dt, which tends to K^2 tau / 3.
- rate ramp R [deg/h/h]: deterministic R t_h (starts at 0 at t = 0).
- constant bias [deg/h].
- AR(2) drift (papers' eq. 1) y_k = a1 y_{k-1} + a2 y_{k-2} + r_k, r_k ~ N(0, sigma^2) in deg/h;
  the two initial values are drawn from the exact stationary distribution, so the record is
  stationary from its first sample (no burn-in transient). Non-stationary (a1, a2) are rejected.
- first-order Gauss-Markov terms gm = ((sigma_deg_h, tau_s), ...): x_k = phi x_{k-1} + u_k,
  phi = exp(-dt/tau), var u = sigma^2 (1 - phi^2), stationary from the first sample
  (autocovariance ``sigma^2 exp(-|t|/tau)``; IEEE Std 952 C.1 exponentially correlated noise).
- optional pulse counting (pulse_deg = S > 0), as a ring-laser gyro's digital output: the sum
  of the terms is integrated to angle theta and the output per sample is
  floor(theta_k / S) - floor(theta_{k-1} / S) pulses (random initial phase). The angle error is
  bounded by S and, when the angle noise per sample spans several pulses, white and uniform
  with variance S^2 / 12, i.e. quantization Q = S / sqrt(12).

Each term draws from its own child stream of ``numpy.random.SeedSequence(seed)``, so adding or
removing one term does not change the realisation of the others, and the same seed always
gives the same record.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from gyrodrift.defaults import DEFAULT_SAMPLE_RATE_HZ
from gyrodrift.errors import GyrodriftTypeError, GyrodriftValueError
from gyrodrift.nav import earth

__all__ = [
    "GyroRecord",
    "ImuRecord",
    "NoiseTerms",
    "ar2_stationary_covariance",
    "simulate",
    "simulate_imu",
]

# Order in which terms draw their child seed streams (fixed forever: changing it would change
# every seeded record other areas rely on).
_TERM_ORDER = ("q", "n", "b", "k", "ar2", "pulse", "gm")


@dataclass(frozen=True)
class NoiseTerms:
    """IEEE Std 952 gyro error terms (all >= 0) plus a constant bias and an AR(2) drift.

    Attributes
    ----------
    q_deg
        quantization noise coefficient Q, deg.
    n_deg_rt_h
        angle random walk N, deg/sqrt(h).
    b_deg_h
        bias instability B, deg/h (Allan floor 0.664 B).
    k_deg_h_rt_h
        rate random walk K, deg/h/sqrt(h).
    r_deg_h2
        rate ramp R, deg/h/h (may be negative: the sign is the ramp direction).
    bias_deg_h
        constant bias, deg/h (any sign).
    ar2
        (a1, a2, sigma_deg_h) of the AR(2) drift component, or None.
    gm
        first-order Gauss-Markov terms, a tuple of (sigma_deg_h, tau_s): stationary
        standard deviation (deg/h) and correlation time (s) of each (IEEE Std 952 C.1
        "exponentially correlated noise"), at most 3.
    pulse_deg
        if > 0, the output is pulse-counted like a ring-laser gyro: the sum of all
        terms is integrated to angle and the output is whole pulses of this size per
        sample (rate = counts x pulse_deg / dt). Quantization noise then has
        Q = pulse_deg / sqrt(12) when the angle sweeps many pulses (IEEE Std 952, C.1).

    Examples
    --------
    >>> NoiseTerms(n_deg_rt_h=0.01, b_deg_h=0.1).b_deg_h
    0.1
    """

    q_deg: float = 0.0
    n_deg_rt_h: float = 0.0
    b_deg_h: float = 0.0
    k_deg_h_rt_h: float = 0.0
    r_deg_h2: float = 0.0
    bias_deg_h: float = 0.0
    ar2: tuple[float, float, float] | None = None
    pulse_deg: float = 0.0
    gm: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        try:
            gm = tuple((float(s), float(t)) for s, t in self.gm)
        except (TypeError, ValueError):
            raise GyrodriftValueError(
                f"gm must be a tuple of (sigma_deg_h, tau_s) pairs, got {self.gm!r}") from None
        if len(gm) > 3:
            raise GyrodriftValueError(f"at most 3 Gauss-Markov terms, got {len(gm)}")
        for sigma, tau in gm:
            if not (math.isfinite(sigma) and sigma >= 0.0 and math.isfinite(tau) and tau > 0.0):
                raise GyrodriftValueError(
                    f"gm terms need sigma_deg_h >= 0 and tau_s > 0, got {gm!r}")
        object.__setattr__(self, "gm", gm)
        for name in ("q_deg", "n_deg_rt_h", "b_deg_h", "k_deg_h_rt_h", "pulse_deg"):
            value = getattr(self, name)
            if not _is_finite_number(value) or value < 0.0:
                raise GyrodriftValueError(f"{name} must be a finite number >= 0, got {value!r}")
        for name in ("r_deg_h2", "bias_deg_h"):
            value = getattr(self, name)
            if not _is_finite_number(value):
                raise GyrodriftValueError(f"{name} must be a finite number, got {value!r}")
        if self.ar2 is not None:
            try:
                a1, a2, sigma = (float(v) for v in self.ar2)
            except (TypeError, ValueError):
                raise GyrodriftValueError(
                    f"ar2 must be a tuple (a1, a2, sigma_deg_h), got {self.ar2!r}"
                ) from None
            if not all(math.isfinite(v) for v in (a1, a2, sigma)):
                raise GyrodriftValueError(f"ar2 values must be finite, got {self.ar2!r}")
            if sigma < 0.0:
                raise GyrodriftValueError(f"ar2 sigma_deg_h must be >= 0, got {sigma!r}")
            # Stationarity triangle of z^2 - a1 z - a2 (both roots strictly inside |z| = 1).
            if not (abs(a2) < 1.0 and a2 + a1 < 1.0 and a2 - a1 < 1.0):
                raise GyrodriftValueError(
                    f"ar2 (a1={a1}, a2={a2}) is not stationary: the roots of "
                    "z^2 - a1 z - a2 must lie strictly inside the unit circle"
                )
            object.__setattr__(self, "ar2", (a1, a2, sigma))


class _TimeBase:
    """dt_s and t_s of a record with `n` samples at `rate_hz` (shared by the record types)."""

    rate_hz: float

    @property
    def n(self) -> int:
        raise NotImplementedError

    @property
    def dt_s(self) -> float:
        return 1.0 / self.rate_hz

    @property
    def t_s(self) -> np.ndarray:
        """Sample times k dt, s."""
        return np.arange(self.n, dtype=np.float64) * self.dt_s


@dataclass(frozen=True, eq=False)  # array fields: identity comparison
class GyroRecord(_TimeBase):
    """A simulated gyro rate record.

    Attributes
    ----------
    rate_deg_h
        rate in deg/h, shape (n,) for one axis or (n, axes), float64, C-contiguous.
    rate_hz
        sample rate, Hz.
    terms
        the noise terms the record was generated from.
    seed
        the seed that reproduces it.
    components
        per-term contributions in deg/h (same shape as rate_deg_h) when
        ``keep_components=True`` was passed, keyed "quantization", "arw",
        "bias_instability", "rrw", "ramp", "bias", "ar2", "gauss_markov" (all GM terms)
        and "pulse_quantization" (the
        pulse-counting error); otherwise empty.

    Examples
    --------
    >>> rec = simulate(n=100, rate_hz=10.0, n_deg_rt_h=0.01, seed=0)
    >>> rec.n, rec.dt_s, rec.rate_deg_h.shape
    (100, 0.1, (100,))
    """

    rate_deg_h: np.ndarray
    rate_hz: float
    terms: NoiseTerms
    seed: int
    components: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    @property
    def n(self) -> int:
        return int(self.rate_deg_h.shape[0])

    @property
    def axes(self) -> int:
        return 1 if self.rate_deg_h.ndim == 1 else int(self.rate_deg_h.shape[1])

    @property
    def rate_deg_s(self) -> np.ndarray:
        """Rate in deg/s."""
        return self.rate_deg_h / 3600.0

    @property
    def rate_rad_s(self) -> np.ndarray:
        """Rate in rad/s."""
        return np.deg2rad(self.rate_deg_h / 3600.0)

    @property
    def dtheta_deg(self) -> np.ndarray:
        """Angle increments per sample (rate x dt), deg."""
        return self.rate_deg_h * (self.dt_s / 3600.0)

    @property
    def dtheta_rad(self) -> np.ndarray:
        """Angle increments per sample (rate x dt), rad."""
        return np.deg2rad(self.dtheta_deg)


@dataclass(frozen=True, eq=False)  # array fields: identity comparison
class ImuRecord(_TimeBase):
    """A simulated static strapdown IMU record.

    Frames: navigation frame ENU (x east, y north, z up); body frame x right, y forward, z up
    (as the shared laser-gyro record), level, heading_deg = angle from north to the body y axis,
    clockwise seen from above. Accelerometers read specific force, +g on z when level.

    Attributes
    ----------
    gyro_rad_s
        (n, 3) angular rate, rad/s (Earth rate in body axes + gyro errors).
    accel_m_s2
        (n, 3) specific force, m/s^2 (gravity reaction + accelerometer errors).
    rate_hz
        sample rate, Hz.
    latitude_deg, height_m, heading_deg
        the static pose.
    gravity_m_s2
        normal gravity magnitude used (gyrodrift.nav.earth.gravity_m_s2: WGS-84
        normal gravity series + free-air).
    gyro_true_rad_s
        (3,) error-free body rate.
    accel_true_m_s2
        (3,) error-free specific force.
    gyro_err_deg_h
        (n, 3) gyro errors that were added, deg/h.
    gyro_terms
        the (x, y, z) gyro error terms.
    accel_bias_m_s2
        (3,) constant accelerometer bias that was added.
    vrw_m_s_rt_h
        (3,) velocity random walk coefficients, m/s/sqrt(h).
    seed
        reproduces the record.

    Examples
    --------
    >>> imu = simulate_imu(n=10, rate_hz=100.0)
    >>> imu.gyro_rad_s.shape, imu.accel_m_s2.shape
    ((10, 3), (10, 3))
    """

    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray
    rate_hz: float
    latitude_deg: float
    height_m: float
    heading_deg: float
    gravity_m_s2: float
    gyro_true_rad_s: np.ndarray
    accel_true_m_s2: np.ndarray
    gyro_err_deg_h: np.ndarray
    gyro_terms: tuple[NoiseTerms, NoiseTerms, NoiseTerms]
    accel_bias_m_s2: np.ndarray
    vrw_m_s_rt_h: np.ndarray
    seed: int

    @property
    def n(self) -> int:
        return int(self.gyro_rad_s.shape[0])

    @property
    def dtheta_rad(self) -> np.ndarray:
        """(n, 3) gyro angle increments per sample, rad."""
        return self.gyro_rad_s * self.dt_s

    @property
    def dv_m_s(self) -> np.ndarray:
        """(n, 3) accelerometer velocity increments per sample, m/s."""
        return self.accel_m_s2 * self.dt_s


def _is_finite_number(value: object) -> bool:
    return (
        isinstance(value, (int, float, np.integer, np.floating))
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )


def _resolve_n(duration_s: float | None, n: int | None, rate_hz: float, min_n: int = 2) -> int:
    if not _is_finite_number(rate_hz) or rate_hz <= 0.0:
        raise GyrodriftValueError(f"rate_hz must be a finite number > 0, got {rate_hz!r}")
    if (duration_s is None) == (n is None):
        raise GyrodriftValueError("give exactly one of duration_s or n")
    if n is None:
        if not _is_finite_number(duration_s) or duration_s <= 0.0:  # type: ignore[operator]
            raise GyrodriftValueError(f"duration_s must be a finite number > 0, got {duration_s!r}")
        n = round(float(duration_s) * float(rate_hz))  # type: ignore[arg-type]
    elif not isinstance(n, (int, np.integer)) or isinstance(n, bool):
        raise GyrodriftValueError(f"n must be an integer, got {n!r}")
    n = int(n)
    if n < min_n:
        raise GyrodriftValueError(f"too few samples: n={n}, need at least {min_n}")
    return n


def _resolve_seed(seed: int) -> int:
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise GyrodriftValueError(f"seed must be a non-negative integer, got {seed!r}")
    return int(seed)


def ar2_stationary_covariance(a1: float, a2: float, sigma2: float) -> tuple[float, float]:
    """Stationary (gamma0, gamma1) of y_k = a1 y_{k-1} + a2 y_{k-2} + r_k, var(r) = sigma2.

    From the Yule-Walker equations gamma1 = a1 gamma0 + a2 gamma1 and
    gamma0 = a1 gamma1 + a2 gamma2 + sigma2 with gamma2 = a1 gamma1 + a2 gamma0.

    Examples
    --------
    >>> ar2_stationary_covariance(0.0, 0.0, 2.0)  # white noise
    (2.0, 0.0)
    """
    gamma0 = sigma2 * (1.0 - a2) / ((1.0 + a2) * ((1.0 - a2) ** 2 - a1**2))
    gamma1 = a1 * gamma0 / (1.0 - a2)
    return gamma0, gamma1


def _flicker(
    rng: np.random.Generator, b_deg_h: float, n: int, dt_s: float, axes: int
) -> np.ndarray:
    """Flicker noise with two-sided PSD B^2 / (2 pi f) (f in Hz, rate in deg/h), shape (axes, n).

    White noise of unit variance has two-sided PSD dt; multiplying its spectrum by
    sqrt(S(f) / dt) gives PSD S(f). Length L = 2 n (rounded up to a fast FFT size) so that the
    first n samples are not circularly wrapped; the DC bin is zeroed (flicker has no finite mean).
    """
    import scipy.fft  # here, not at module level: `import gyrodrift` stays light (0.15 s)

    length = scipy.fft.next_fast_len(2 * n, real=True)
    f_hz = np.fft.rfftfreq(length, d=dt_s)
    gain = np.zeros_like(f_hz)
    gain[1:] = np.sqrt(b_deg_h**2 / (2.0 * np.pi * f_hz[1:]) / dt_s)
    out = np.empty((axes, n))
    for axis in range(axes):  # one axis at a time: bounded memory for 1e7-sample records
        white = rng.standard_normal(length)
        out[axis] = scipy.fft.irfft(scipy.fft.rfft(white) * gain, n=length)[:n]
    return out


def _generate(
    terms: NoiseTerms, n: int, rate_hz: float, axes: int, seed: int, keep_components: bool
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Sum of the terms as an (axes, n) array in deg/h, plus optional components."""
    import scipy.signal  # here: `import gyrodrift` stays light (scipy.signal loads scipy.stats)

    dt_s = 1.0 / rate_hz
    dt_h = dt_s / 3600.0
    streams = dict(
        zip(_TERM_ORDER, np.random.SeedSequence(seed).spawn(len(_TERM_ORDER)), strict=True)
    )
    rate = np.zeros((axes, n))
    parts: dict[str, np.ndarray] = {}

    def add(name: str, values: np.ndarray) -> None:
        nonlocal rate
        rate += values
        if keep_components:
            parts[name] = np.broadcast_to(values, (axes, n)).copy()

    if terms.q_deg > 0.0:
        rng = np.random.default_rng(streams["q"])
        angle_deg = terms.q_deg * rng.standard_normal((axes, n + 1))
        add("quantization", np.diff(angle_deg, axis=1) / dt_h)
    if terms.n_deg_rt_h > 0.0:
        rng = np.random.default_rng(streams["n"])
        add("arw", (terms.n_deg_rt_h / math.sqrt(dt_h)) * rng.standard_normal((axes, n)))
    if terms.b_deg_h > 0.0:
        rng = np.random.default_rng(streams["b"])
        add("bias_instability", _flicker(rng, terms.b_deg_h, n, dt_s, axes))
    if terms.k_deg_h_rt_h > 0.0:
        rng = np.random.default_rng(streams["k"])
        steps = (terms.k_deg_h_rt_h * math.sqrt(dt_h)) * rng.standard_normal((axes, n))
        add("rrw", np.cumsum(steps, axis=1))
    if terms.r_deg_h2 != 0.0:
        t_h = np.arange(n, dtype=np.float64) * dt_h
        add("ramp", np.broadcast_to(terms.r_deg_h2 * t_h, (axes, n)))
    if terms.bias_deg_h != 0.0:
        add("bias", np.full((axes, n), float(terms.bias_deg_h)))
    if terms.ar2 is not None and terms.ar2[2] > 0.0:
        a1, a2, sigma = terms.ar2
        rng = np.random.default_rng(streams["ar2"])
        gamma0, gamma1 = ar2_stationary_covariance(a1, a2, sigma**2)
        # (y_{-1}, y_{-2}) from the stationary joint distribution.
        init = rng.multivariate_normal([0.0, 0.0], [[gamma0, gamma1], [gamma1, gamma0]], size=axes)
        drive = sigma * rng.standard_normal((axes, n))
        # lfilter direct-form-II-transposed state for b=[1], a=[1, -a1, -a2]:
        # z0 = a1 y_{-1} + a2 y_{-2}, z1 = a2 y_{-1}.
        zi = np.stack([a1 * init[:, 0] + a2 * init[:, 1], a2 * init[:, 0]], axis=1)
        y, _ = scipy.signal.lfilter([1.0], [1.0, -a1, -a2], drive, axis=1, zi=zi)
        add("ar2", y)
    if terms.gm:
        # First-order Gauss-Markov, exact discretisation of dx = -x/T dt + w:
        # x_k = phi x_{k-1} + u_k, phi = exp(-dt/T), var u = sigma^2 (1 - phi^2), x_{-1}
        # drawn from the stationary N(0, sigma^2): stationary from the first sample.
        rng = np.random.default_rng(streams["gm"])
        total = np.zeros((axes, n))
        for sigma, tau_s in terms.gm:
            phi = math.exp(-dt_s / tau_s)
            init = sigma * rng.standard_normal((axes, 1))
            drive = sigma * math.sqrt(-math.expm1(-2.0 * dt_s / tau_s)) * rng.standard_normal(
                (axes, n))
            y, _ = scipy.signal.lfilter([1.0], [1.0, -phi], drive, axis=1, zi=phi * init)
            total += y
        add("gauss_markov", total)
    if terms.pulse_deg > 0.0:
        # Pulse counting (RLG/FOG digital output): counts_k = floor(theta_k / S) -
        # floor(theta_{k-1} / S) of the integrated angle, with a random initial phase in [0, S).
        rng = np.random.default_rng(streams["pulse"])
        pulse = float(terms.pulse_deg)
        theta0 = pulse * rng.random((axes, 1))
        theta = theta0 + np.cumsum(rate * dt_h, axis=1)
        edges = np.floor(np.concatenate([theta0, theta], axis=1) / pulse)
        quantized = np.diff(edges, axis=1) * (pulse / dt_h)
        if keep_components:
            parts["pulse_quantization"] = quantized - rate
        rate = quantized
    return rate, parts


def _layout(values: np.ndarray, axes: int) -> np.ndarray:
    """(axes, n) -> (n,) for one axis, else C-contiguous (n, axes)."""
    if axes == 1:
        return np.ascontiguousarray(values[0])
    return np.ascontiguousarray(values.T)


def simulate(
    duration_s: float | None = None,
    *,
    n: int | None = None,
    rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    q_deg: float = 0.0,
    n_deg_rt_h: float = 0.0,
    b_deg_h: float = 0.0,
    k_deg_h_rt_h: float = 0.0,
    r_deg_h2: float = 0.0,
    bias_deg_h: float = 0.0,
    ar2: tuple[float, float, float] | None = None,
    pulse_deg: float = 0.0,
    gm: tuple[tuple[float, float], ...] = (),
    axes: int = 1,
    seed: int = 0,
    keep_components: bool = False,
) -> GyroRecord:
    """Simulate a gyro rate record in deg/h from IEEE Std 952 terms (see the module docstring).

    Give the length as ``duration_s`` (rounded to whole samples) or ``n``. ``axes`` independent
    axes share the same terms; the result is (n,) for one axis, else (n, axes).

    Raises
    ------
    ValueError
        negative or non-finite terms, non-stationary ar2, rate_hz <= 0, both or
        neither of duration_s / n, fewer than 2 samples, axes < 1, bad seed.

    Examples
    --------
    >>> rec = simulate(duration_s=10.0, rate_hz=100.0, bias_deg_h=5.0, seed=1)
    >>> rec.n, float(rec.rate_deg_h.mean())
    (1000, 5.0)
    """
    terms = NoiseTerms(
        q_deg=q_deg,
        n_deg_rt_h=n_deg_rt_h,
        b_deg_h=b_deg_h,
        k_deg_h_rt_h=k_deg_h_rt_h,
        r_deg_h2=r_deg_h2,
        bias_deg_h=bias_deg_h,
        ar2=ar2,
        pulse_deg=pulse_deg,
        gm=gm,
    )
    return simulate_terms(
        terms,
        duration_s=duration_s,
        n=n,
        rate_hz=rate_hz,
        axes=axes,
        seed=seed,
        keep_components=keep_components,
    )


def simulate_terms(
    terms: NoiseTerms,
    duration_s: float | None = None,
    *,
    n: int | None = None,
    rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    axes: int = 1,
    seed: int = 0,
    keep_components: bool = False,
) -> GyroRecord:
    """`simulate` with the terms given as a `NoiseTerms` object."""
    if not isinstance(terms, NoiseTerms):
        raise GyrodriftTypeError(f"terms must be a NoiseTerms, got {type(terms).__name__}")
    n_samples = _resolve_n(duration_s, n, rate_hz)
    if not isinstance(axes, (int, np.integer)) or isinstance(axes, bool) or axes < 1:
        raise GyrodriftValueError(f"axes must be an integer >= 1, got {axes!r}")
    seed = _resolve_seed(seed)
    rate, parts = _generate(terms, n_samples, float(rate_hz), int(axes), seed, keep_components)
    return GyroRecord(
        rate_deg_h=_layout(rate, int(axes)),
        rate_hz=float(rate_hz),
        terms=terms,
        seed=seed,
        components={k: _layout(v, int(axes)) for k, v in parts.items()},
    )


def _per_axis(value: float | Sequence[float], name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(3, float(arr))
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise GyrodriftValueError(
            f"{name} must be a finite number or 3 finite numbers, got {value!r}")
    return arr


def simulate_imu(
    duration_s: float | None = None,
    *,
    n: int | None = None,
    rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    latitude_deg: float = 39.0,
    height_m: float = 0.0,
    heading_deg: float = 0.0,
    gyro: NoiseTerms | Sequence[NoiseTerms] = NoiseTerms(),
    accel_bias_m_s2: float | Sequence[float] = 0.0,
    vrw_m_s_rt_h: float | Sequence[float] = 0.0,
    seed: int = 0,
) -> ImuRecord:
    """Simulate a static, level strapdown IMU: 3 gyros (rad/s) and 3 accelerometers (m/s^2).

    Truth (ENU navigation frame, body x right / y forward / z up, heading psi from north to body
    y, clockwise): Earth rate [0, W cos(lat), W sin(lat)] and specific force [0, 0, g] rotated
    into the body frame: gyro_true = [-sin(psi) W cos(lat), cos(psi) W cos(lat), W sin(lat)],
    accel_true = [0, 0, g(lat, h)].

    Errors: ``gyro`` is one `NoiseTerms` for all axes or three (x, y, z), generated in deg/h by
    the same code as `simulate` and converted to rad/s; accelerometers get a constant bias and
    velocity random walk (white specific force of std vrw / 60 / sqrt(dt_s) m/s^2 for vrw in
    m/s/sqrt(h)).

    Examples
    --------
    >>> imu = simulate_imu(n=100, latitude_deg=45.0, seed=2)
    >>> bool(np.allclose(imu.accel_m_s2[:, 2], imu.gravity_m_s2))  # level, no accel noise
    True
    """
    n_samples = _resolve_n(duration_s, n, rate_hz)
    seed = _resolve_seed(seed)
    for name, value in (
        ("latitude_deg", latitude_deg),
        ("height_m", height_m),
        ("heading_deg", heading_deg),
    ):
        if not _is_finite_number(value):
            raise GyrodriftValueError(f"{name} must be a finite number, got {value!r}")
    if abs(latitude_deg) > 90.0:
        raise GyrodriftValueError(f"latitude_deg must be within [-90, 90], got {latitude_deg!r}")
    if isinstance(gyro, NoiseTerms):
        gyro_terms = [gyro, gyro, gyro]
    else:
        gyro_terms = list(gyro)
        if len(gyro_terms) != 3 or not all(isinstance(t, NoiseTerms) for t in gyro_terms):
            raise GyrodriftValueError("gyro must be a NoiseTerms or a sequence of 3 NoiseTerms")
    bias = _per_axis(accel_bias_m_s2, "accel_bias_m_s2")
    vrw = _per_axis(vrw_m_s_rt_h, "vrw_m_s_rt_h")
    if np.any(vrw < 0.0):
        raise GyrodriftValueError(f"vrw_m_s_rt_h must be >= 0, got {vrw_m_s_rt_h!r}")

    rate_hz = float(rate_hz)
    dt_s = 1.0 / rate_hz
    # Independent streams: one per gyro axis, one for the accelerometers.
    gyro_seeds, accel_seed = np.random.SeedSequence(seed).spawn(2)
    axis_seeds = gyro_seeds.generate_state(3, dtype=np.uint32)
    gyro_err = np.empty((3, n_samples))
    if gyro_terms[0] == gyro_terms[1] == gyro_terms[2]:
        gyro_err[:], _ = _generate(gyro_terms[0], n_samples, rate_hz, 3, int(axis_seeds[0]), False)
    else:
        for axis, terms in enumerate(gyro_terms):
            gyro_err[axis], _ = _generate(
                terms, n_samples, rate_hz, 1, int(axis_seeds[axis]), False
            )

    lat = math.radians(latitude_deg)
    psi = math.radians(heading_deg)
    w_e = earth.EARTH_RATE_RAD_S
    gyro_true = np.array(
        [
            -math.sin(psi) * w_e * math.cos(lat),
            math.cos(psi) * w_e * math.cos(lat),
            w_e * math.sin(lat),
        ]
    )
    g = earth.gravity_m_s2(lat, height_m)
    accel_true = np.array([0.0, 0.0, g])

    rng = np.random.default_rng(accel_seed)
    accel_noise = rng.standard_normal((n_samples, 3)) * (vrw / 60.0 / math.sqrt(dt_s))
    gyro_err_nx3 = np.ascontiguousarray(gyro_err.T)
    gyro_rad_s = gyro_true + np.deg2rad(gyro_err_nx3 / 3600.0)
    accel = accel_true + bias + accel_noise
    return ImuRecord(
        gyro_rad_s=np.ascontiguousarray(gyro_rad_s),
        accel_m_s2=np.ascontiguousarray(accel),
        rate_hz=rate_hz,
        latitude_deg=float(latitude_deg),
        height_m=float(height_m),
        heading_deg=float(heading_deg),
        gravity_m_s2=g,
        gyro_true_rad_s=gyro_true,
        accel_true_m_s2=accel_true,
        gyro_err_deg_h=gyro_err_nx3,
        gyro_terms=(gyro_terms[0], gyro_terms[1], gyro_terms[2]),
        accel_bias_m_s2=bias,
        vrw_m_s_rt_h=vrw,
        seed=seed,
    )

