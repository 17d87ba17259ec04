"""Gyro noise identification from an Allan deviation curve (tau in s, sigma in deg/h).

Three methods:

1. `identify` -- IEEE Std 952-1997 Annex C (eq. C.21 and table C.2): weighted least squares
   of the Allan variance on sigma^2(tau) = sum_{k=-2..2} C_k tau^k with C_k >= 0, then::

       C_-2 = 3 Q^2        Q  = sqrt(C_-2 / 3)          (deg/h)*s = arcsec
       C_-1 = N^2          N  = sqrt(C_-1) / 60         deg/sqrt(h)
       C_0  = (2 ln2/pi) B^2   B = sqrt(C_0 pi / (2 ln2))   deg/h
       C_1  = K^2 / 3      K  = 60 sqrt(3 C_1)          deg/h/sqrt(h)
       C_2  = R^2 / 2      R  = 3600 sqrt(2 C_2)        deg/h/h

   Unit factors: sqrt(s) = sqrt(h)/60, so (deg/h) sqrt(s) = deg/sqrt(h) / 60 and
   (deg/h)/sqrt(s) = 60 deg/h/sqrt(h); (deg/h)/s = 3600 deg/h^2.
   Each squared residual is weighted by edf / (2 sigma^4), the inverse variance of a
   chi-squared sigma^2 estimate with edf degrees of freedom.
2. `paper_fit` -- the 2006 paper's eq. (8): ``sigma(tau) = A0 + A_-1/sqrt(tau) + A_-2/tau``,
   least squares on sigma (not sigma^2) with A >= 0, and its conversions ``Q = A_-2/sqrt(3)``,
   ``N = A_-1/60``, ``B = A0/0.6648``. With sigma in deg/h and tau in s, ``A_-2/sqrt(3)`` is in
   ``(deg/h)*s`` = arcsec although the paper's Table 1 heads that column (deg); both are given.
3. `slope_method` -- IEEE Std 952 C.1 read-offs as a cross-check: the -1/2 slope line at
   tau = 1 h gives N, the +1/2 line at tau = 3 h gives K, the -1 line at tau = sqrt(3) s
   gives Q, the flat minimum / sqrt(2 ln2/pi) gives B.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np
import scipy.optimize

from gyrodrift._scale import scale_for_peak
from gyrodrift.errors import GyrodriftValueError

__all__ = [
    "B_FLOOR_FACTOR",
    "NoiseFit",
    "PaperFit",
    "SlopeReadout",
    "allan_model_deg_h",
    "identify",
    "identify_noise",
    "paper_fit",
    "slope_method",
]

#: sigma_B = sqrt(2 ln2 / pi) B = 0.6643 B (IEEE Std 952 table C.2).
B_FLOOR_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)
#: The 2006 paper's rounded factor in B = A0 / 0.6648.
PAPER_B_FACTOR = 0.6648
POWERS = np.array([-2, -1, 0, 1, 2])


@dataclass(frozen=True)
class NoiseFit:
    """IEEE Std 952 terms. q_arcsec is numerically (deg/h)*s; q_deg = q_arcsec / 3600.

    Examples
    --------
    >>> tau = np.logspace(-1, 3, 30)
    >>> fit = identify(tau, allan_model_deg_h(tau, n_deg_rt_h=0.01))
    >>> round(fit.n_deg_rt_h, 6)
    0.01
    """

    q_arcsec: float
    n_deg_rt_h: float
    b_deg_h: float
    k_deg_h_rt_h: float
    r_deg_h2: float
    coeffs: tuple[float, float, float, float, float]  # C_-2 .. C_2, (deg/h)^2 s^k
    tau_min_s: float
    tau_max_s: float

    @property
    def q_deg(self) -> float:
        return self.q_arcsec / 3600.0

    def as_dict(self) -> dict[str, object]:
        d = asdict(self)
        d["q_deg"] = self.q_deg
        d["coeffs"] = list(self.coeffs)
        return d


@dataclass(frozen=True)
class PaperFit:
    """The 2006 paper's eq. (8) fit. q_paper is the number the paper prints under 'Q (deg)';
    it is ``A_-2/sqrt(3)`` in ``(deg/h)*s``, i.e. arcsec (q_arcsec, same number); q_deg is the true
    angle in degrees (q_arcsec / 3600).

    Examples
    --------
    >>> tau = np.logspace(-1, 3, 30)
    >>> round(paper_fit(tau, allan_model_deg_h(tau, n_deg_rt_h=0.01)).n_deg_rt_h, 6)
    0.01
    """

    a0: float
    a_m1: float
    a_m2: float
    q_paper: float
    q_arcsec: float
    q_deg: float
    n_deg_rt_h: float
    b_deg_h: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True)
class SlopeReadout:
    """Slope-method read-offs; None where the curve has no stretch with that slope.

    Examples
    --------
    >>> tau = np.logspace(0, 3, 16)
    >>> slope_method(tau, 0.01 * 60 / np.sqrt(tau)).b_deg_h is None  # no flat part
    True
    """

    q_arcsec: float | None
    n_deg_rt_h: float | None
    b_deg_h: float | None
    k_deg_h_rt_h: float | None

    def as_dict(self) -> dict[str, float | None]:
        return asdict(self)


def _check_curve(tau_s: np.ndarray, adev_deg_h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    tau = np.asarray(tau_s, dtype=np.float64)
    sig = np.asarray(adev_deg_h, dtype=np.float64)
    if tau.ndim != 1 or tau.shape != sig.shape:
        raise GyrodriftValueError(f"tau_s and adev must be 1-D of equal length, got {tau.shape}, "
                         f"{sig.shape}")
    if not (np.all(np.isfinite(tau)) and np.all(np.isfinite(sig))):
        raise GyrodriftValueError("tau_s and adev must be finite")
    if np.any(tau <= 0) or np.any(sig <= 0):
        raise GyrodriftValueError("tau_s and adev must be positive")
    return tau, sig


def allan_model_deg_h(tau_s: np.ndarray, q_arcsec: float = 0.0, n_deg_rt_h: float = 0.0,
                    b_deg_h: float = 0.0, k_deg_h_rt_h: float = 0.0, r_deg_h2: float = 0.0
                    ) -> np.ndarray:
    """sigma(tau) in deg/h of IEEE Std 952 table C.2 for tau in s.

    Examples
    --------
    >>> allan_model_deg_h(np.array([3600.0]), n_deg_rt_h=1.0).tolist()  # N / sqrt(tau) at 1 h
    [1.0]
    """
    tau = np.asarray(tau_s, dtype=np.float64)
    n_ = n_deg_rt_h * 60.0
    k_ = k_deg_h_rt_h / 60.0
    r_ = r_deg_h2 / 3600.0
    var = (3.0 * q_arcsec**2 / tau**2 + n_**2 / tau + (B_FLOOR_FACTOR * b_deg_h) ** 2
           + k_**2 * tau / 3.0 + r_**2 * tau**2 / 2.0)
    return np.sqrt(var)


def identify(tau_s: np.ndarray, adev_deg_h: np.ndarray, edf: np.ndarray | None = None,
             powers: tuple[int, ...] = (-2, -1, 0, 1, 2)) -> NoiseFit:
    """IEEE Std 952 Annex C weighted non-negative least squares (module docstring).

    edf: equivalent degrees of freedom per tau (AllanResult.edf); None weights every point
    as if it had the same relative uncertainty. `powers` restricts the model (e.g. no ramp).

    Examples
    --------
    >>> from gyrodrift import oadev, simulate
    >>> rec = simulate(n=200_000, rate_hz=10.0, n_deg_rt_h=0.01, seed=1)
    >>> r = oadev(rec.rate_deg_h, 10.0, progress=False)
    >>> fit = identify(r.tau_s, r.adev, r.edf)
    >>> bool(abs(fit.n_deg_rt_h - 0.01) < 0.001)
    True
    """
    tau, sig = _check_curve(tau_s, adev_deg_h)
    c_dev = scale_for_peak(float(np.max(np.abs(sig))))
    if c_dev != 1.0:
        # A curve of extreme magnitude (sig^2 or its weights overflow or underflow): fitted
        # scaled by a power of two (exact), every term scaled back (coefficients by c^2).
        f = identify(tau, sig / c_dev, edf, powers)
        return replace(f, q_arcsec=f.q_arcsec * c_dev, n_deg_rt_h=f.n_deg_rt_h * c_dev,
                       b_deg_h=f.b_deg_h * c_dev, k_deg_h_rt_h=f.k_deg_h_rt_h * c_dev,
                       r_deg_h2=f.r_deg_h2 * c_dev,
                       coeffs=tuple(v * c_dev * c_dev for v in f.coeffs))  # type: ignore[arg-type]
    use = np.isin(POWERS, np.asarray(powers))
    if tau.size < int(use.sum()):
        raise GyrodriftValueError(f"{tau.size} taus cannot identify {int(use.sum())} terms")
    w = np.ones_like(tau) if edf is None else np.sqrt(np.asarray(edf, dtype=np.float64) / 2.0)
    if w.shape != tau.shape or not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise GyrodriftValueError("edf must be positive, finite, one per tau")
    var = sig * sig
    basis = tau[:, None] ** POWERS[use][None, :]
    # Row i scaled by sqrt(edf_i / 2) / sigma_i^2 (1 / standard error of sigma_i^2). The
    # standard error belongs to the true sigma^2: weighting by the measured value gives low
    # outliers (the scattered longest taus) a huge weight, so the weights are iterated with
    # the fitted model (iteratively reweighted least squares, a few passes converge).
    weight_var = var
    coef_used = np.zeros(int(use.sum()))
    for _ in range(6):
        row = w / weight_var
        design = basis * row[:, None]
        # Column scaling: tau^k spans many decades, NNLS wants comparable columns.
        col = np.linalg.norm(design, axis=0)
        coef_scaled, _ = scipy.optimize.nnls(design / col, var * row)
        coef_used = coef_scaled / col
        model = basis @ coef_used
        if not np.all(model > 0):
            break
        weight_var = model
    c = np.zeros(5)
    c[use] = coef_used
    return NoiseFit(
        q_arcsec=math.sqrt(c[0] / 3.0),
        n_deg_rt_h=math.sqrt(c[1]) / 60.0,
        b_deg_h=math.sqrt(c[2]) / B_FLOOR_FACTOR,
        k_deg_h_rt_h=60.0 * math.sqrt(3.0 * c[3]),
        r_deg_h2=3600.0 * math.sqrt(2.0 * c[4]),
        coeffs=(float(c[0]), float(c[1]), float(c[2]), float(c[3]), float(c[4])),
        tau_min_s=float(tau.min()),
        tau_max_s=float(tau.max()),
    )


def paper_fit(tau_s: np.ndarray, adev_deg_h: np.ndarray, edf: np.ndarray | None = None
              ) -> PaperFit:
    """The 2006 paper's eq. (8) fit with A >= 0 (module docstring). Each residual of sigma is
    weighted by 1/(sigma/sqrt(2 edf)), the standard error of a deviation; without edf, by
    1/sigma (relative residuals).

    Examples
    --------
    >>> from gyrodrift import oadev, simulate
    >>> rec = simulate(n=200_000, rate_hz=10.0, n_deg_rt_h=0.01, seed=1)
    >>> r = oadev(rec.rate_deg_h, 10.0, progress=False)
    >>> bool(abs(paper_fit(r.tau_s, r.adev, r.edf).n_deg_rt_h - 0.01) < 0.001)
    True
    """
    tau, sig = _check_curve(tau_s, adev_deg_h)
    if tau.size < 3:
        raise GyrodriftValueError(f"{tau.size} taus cannot fit the 3-term model")
    w = np.ones_like(tau) if edf is None else np.sqrt(2.0 * np.asarray(edf, dtype=np.float64))
    row = w / sig
    design = np.column_stack([np.ones_like(tau), tau**-0.5, 1.0 / tau]) * row[:, None]
    col = np.linalg.norm(design, axis=0)
    a_scaled, _ = scipy.optimize.nnls(design / col, sig * row)
    a0, a_m1, a_m2 = (float(v) for v in a_scaled / col)
    q = a_m2 / math.sqrt(3.0)
    return PaperFit(a0=a0, a_m1=a_m1, a_m2=a_m2, q_paper=q, q_arcsec=q, q_deg=q / 3600.0,
                    n_deg_rt_h=a_m1 / 60.0, b_deg_h=a0 / PAPER_B_FACTOR)


def slope_method(tau_s: np.ndarray, adev_deg_h: np.ndarray, tolerance: float = 0.15
                 ) -> SlopeReadout:
    """IEEE Std 952 slope read-offs (module docstring). A term is read where the local
    log-log slope is within `tolerance` of its nominal slope (the point closest to it);
    B from the minimum if the slope there is within `tolerance` of 0.

    Examples
    --------
    >>> tau = np.logspace(0, 3, 16)
    >>> s = slope_method(tau, 0.01 * 60 / np.sqrt(tau))  # pure angle random walk, deg/h
    >>> round(s.n_deg_rt_h, 6)
    0.01
    """
    tau, sig = _check_curve(tau_s, adev_deg_h)
    if tau.size < 3:
        raise GyrodriftValueError("the slope method needs at least 3 taus")
    slope = np.gradient(np.log(sig), np.log(tau))

    def at(target: float) -> int | None:
        k = int(np.argmin(np.abs(slope - target)))
        return k if abs(slope[k] - target) <= tolerance else None

    q = n = b = k_ = None
    if (i := at(-1.0)) is not None:
        # sigma = sqrt(3) Q / tau -> the line through (tau_i, sigma_i) at tau = sqrt(3) s.
        q = float(sig[i] * tau[i] / math.sqrt(3.0))
    if (i := at(-0.5)) is not None:
        # sigma = N' / sqrt(tau): value of the line at tau = 1 h = 3600 s is N in deg/sqrt(h)
        # times 1/sqrt(1 h) -> N = sigma(3600 s) * sqrt(1 h) = sigma_i sqrt(tau_i/3600).
        n = float(sig[i] * math.sqrt(tau[i] / 3600.0))
    j = int(np.argmin(sig))
    if abs(slope[j]) <= tolerance:
        b = float(sig[j] / B_FLOOR_FACTOR)
    if (i := at(0.5)) is not None:
        # sigma = K sqrt(tau / 3) with tau in h: K = line value at tau = 3 h.
        k_ = float(sig[i] * math.sqrt(3.0 * 3600.0 / tau[i]))
    return SlopeReadout(q_arcsec=q, n_deg_rt_h=n, b_deg_h=b, k_deg_h_rt_h=k_)


#: Package-level name (gyrodrift.identify_noise).
identify_noise = identify
