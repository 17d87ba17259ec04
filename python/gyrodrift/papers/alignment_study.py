"""Monte Carlo alignment study: runs of the C++ pipeline on simulated rocking-base
records with and without the real-time wavelet prefilter, statistics against theory, the
prefilter mechanism study, and the real-data heading-consistency run.

Definitions used in every table:

- heading error psi(t) = phi_U(t), the Up misalignment of the computed attitude (estimated -
  true clockwise heading), sampled at the KF updates;
- convergence time (band criterion): the first fine-alignment time t_c with
  ``|psi(t) - psi(end)| <= 1 arcmin`` for all t >= t_c, per run; a run whose band is entered only
  in the last minute counts as not converged;
- theory: steady-state heading -eps_E/(W cos L) + (nab_E/g) tan L and level nab/g with the
  nav-frame projection of the simulated constant biases at the mean attitude; the ARW limit
  sigma_psi(T) = N/(W cos L sqrt(T)) at the fine-alignment time T.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from gyrodrift.defaults import DEFAULT_SAMPLE_RATE_HZ
from gyrodrift.errors import GyrodriftError, GyrodriftValueError
from gyrodrift.filters.fir import apply_fir, forced_fir_taps, group_delay_dc_samples
from gyrodrift.nav.align_config import AlignConfig
from gyrodrift.nav.alignment import run_alignment
from gyrodrift.nav.earth import EARTH_RATE_RAD_S, gravity_m_s2
from gyrodrift.nav.trajectory import Scenario, dcm_batch, imu_increments, scenario, truth_at
from gyrodrift.papers.imu_errors import (
    ImuErrors,
    add_imu_errors,
    kf_noise_from_samples,
    kf_noise_from_spec,
)
from gyrodrift.units import ARCMIN, ARCSEC, DPH, DPSH, UG

__all__ = [
    "BAND_RAD",
    "MECHANISMS",
    "PUBLISHED_RAW_ROW",
    "PUBLISHED_ROW",
    "ConfigResult",
    "StudyConfig",
    "convergence_time_s",
    "fmt",
    "markdown_table",
    "misalignment_batch",
    "run_study",
    "summary_rows",
    "theory",
]

BAND_RAD = ARCMIN


def convergence_time_s(t_s: np.ndarray, psi: np.ndarray, band_rad: float = BAND_RAD,
                       min_hold_s: float = 60.0) -> float:
    """First t with ``|psi(t') - psi(end)| <= band`` for all t' >= t; NaN (not converged) when the
    band is entered less than min_hold_s before the end (it would then hold trivially).

    Examples
    --------
    >>> t = np.arange(0.0, 600.0, 1.0)
    >>> psi = np.where(t < 100.0, 1e-2, 0.0)  # settles at t = 100 s
    >>> convergence_time_s(t, psi)
    100.0
    """
    outside = np.abs(psi - psi[-1]) > band_rad
    if not outside.any():
        return float(t_s[0])
    last_out = int(np.nonzero(outside)[0][-1])
    if last_out + 1 >= len(t_s) or t_s[last_out + 1] > t_s[-1] - min_hold_s:
        return float("nan")
    return float(t_s[last_out + 1])


@dataclass
class StudyConfig:
    """Settings of a Monte Carlo alignment study (record length in s, rates in Hz).

    Examples
    --------
    >>> StudyConfig(scenario="static", runs=2).duration_s
    1800.0
    """
    scenario: str = "ship_mild"
    runs: int = 30
    duration_s: float = 1800.0
    rate_hz: float = DEFAULT_SAMPLE_RATE_HZ
    coarse_s: float = 60.0
    kf_hz: float = 10.0
    n_states: int = 15
    errors: ImuErrors = field(default_factory=ImuErrors)
    kf_noise: str = "spec"  # "spec" or "samples" (raw per-sample scatter, see imu_errors)
    seed: int = 2014
    accel_delay: bool = True  # delay the accelerometers by the prefilter's group delay
    offset_s: float = 60.0  # runs start at a random offset in [0, offset_s] of the truth


@dataclass
class ConfigResult:
    """The runs of one configuration (raw gyro or wavelet prefilter): errors per KF update,
    convergence times, wall time.

    Examples
    --------
    >>> st = StudyConfig(scenario="static", runs=2, duration_s=120.0, rate_hz=100.0, coarse_s=30.0)
    >>> res, _ = run_study(st, configs=(False,))
    >>> r = res[False]
    >>> r.label, r.psi.shape, r.conv_s.shape
    ('raw gyro', (2, 900), (2,))
    """
    label: str
    t_fine_s: np.ndarray  # fine-alignment time of each KF update
    psi: np.ndarray  # (runs, m) heading error, rad
    level: np.ndarray  # (runs, m, 2) phi_E, phi_N, rad
    conv_s: np.ndarray  # (runs,) band-criterion convergence time (NaN = not converged)
    wall_s: float
    samples: int


def _truth(sc: Scenario, n: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    return imu_increments(sc, n, dt)


def _cfg(sc: Scenario, st: StudyConfig, prefilter: bool, arw: float, vrw: float,
         taps: np.ndarray) -> AlignConfig:
    dt = 1.0 / st.rate_hz
    delay = round(group_delay_dc_samples(taps)) if (prefilter and st.accel_delay) else 0
    stage_s = sc.heading_stage_s if st.coarse_s <= sc.heading_stage_max_coarse_s else 0.0
    return AlignConfig(
        dt_s=dt, lat_rad=sc.lat_rad, lon_rad=sc.lon_rad, h_m=sc.h_m, coarse_s=st.coarse_s,
        n_states=st.n_states, kf_every=max(1, round(st.rate_hz / st.kf_hz)),
        arw_rad_s_rt_hz=arw, vrw_m_s2_rt_hz=vrw, zv_sigma_m_s=sc.zero_velocity_sigma_m_s,
        taps=taps if prefilter else None, accel_delay_samples=delay,
        heading_stage_s=stage_s, heading_stage_q=sc.heading_stage_q)


def run_study(st: StudyConfig, configs: tuple[bool, ...] = (False, True),
              progress: bool = False) -> tuple[dict[bool, ConfigResult], dict[str, float]]:
    """Monte Carlo over st.runs seeded records (each with its own noise and rocking phase);
    returns per-configuration results (keyed by prefilter on/off) and the theory values.

    Examples
    --------
    >>> st = StudyConfig(scenario="static", runs=2, duration_s=120.0, rate_hz=100.0, coarse_s=30.0)
    >>> res, th = run_study(st)  # both configurations, two runs of 2 min each
    >>> [res[pre].label for pre in (False, True)], sorted(th)[:2]
    (['raw gyro', 'wavelet prefilter'], ['arw_20min_rad', 'arw_7min_rad'])
    """
    sc = scenario(st.scenario)
    dt = 1.0 / st.rate_hz
    n = round(st.duration_s * st.rate_hz)
    if n <= round(st.coarse_s * st.rate_hz) + 2 * round(st.rate_hz / st.kf_hz):
        raise GyrodriftValueError(
            f"--duration-s {st.duration_s:g} leaves no fine alignment after the "
            f"{st.coarse_s:g} s coarse alignment")
    taps = forced_fir_taps("db4", 256, 5)
    delay = round(group_delay_dc_samples(taps)) if st.accel_delay else 0
    # Both configurations align the same stretch of motion: the prefiltered pipeline first
    # spends len(taps) - 1 samples filling its window and then runs `delay` samples late, so
    # the raw pipeline starts `lead` samples later in the same record. Each run starts at a
    # random offset within the first minute of one long truth record (random rocking phase at
    # the start of coarse alignment, which matters on a swaying base).
    lead = len(taps) - 1 - delay
    n_off = round(st.offset_s * st.rate_hz)
    dth0, dv0 = _truth(sc, n + n_off + lead, dt)
    rng = np.random.default_rng(st.seed)
    offsets = rng.integers(0, n_off + 1, st.runs)
    results: dict[bool, ConfigResult] = {}
    t_hist: dict[bool, np.ndarray] = {}
    iterator = range(st.runs)
    if progress:
        from tqdm import tqdm

        iterator = tqdm(iterator, desc=f"{st.scenario}", unit="run")
    psi_all: dict[bool, list[np.ndarray]] = {c: [] for c in configs}
    lvl_all: dict[bool, list[np.ndarray]] = {c: [] for c in configs}
    wall = dict.fromkeys(configs, 0.0)
    cnb_mean = np.zeros((3, 3))
    for r in iterator:
        off = int(offsets[r])
        sl = slice(off, off + n + lead)
        dth_all, dv_all = add_imu_errors(dth0[sl], dv0[sl], dt, st.errors,
                                         seed=st.seed * 1000 + r)
        for pre in configs:
            first = 0 if pre else lead
            dth = np.ascontiguousarray(dth_all[first:first + n])
            dv = np.ascontiguousarray(dv_all[first:first + n])
            if st.kf_noise == "samples":
                src = apply_fir(dth, taps) if pre else dth
                arw, vrw = kf_noise_from_samples(src, dv, dt)
            else:
                arw, vrw = kf_noise_from_spec(st.errors)
            cfg = _cfg(sc, st, pre, arw, vrw, taps)
            t0 = time.perf_counter()
            out = run_alignment(dth, dv, cfg)
            wall[pre] += time.perf_counter() - t0
            if out.failed:
                raise GyrodriftError(f"alignment failed in run {r} ({st.scenario}, "
                                     f"prefilter={pre}): {out.reason}")
            t_abs = out.t_s + (off + first) * dt
            t_hist[pre] = t_abs - off * dt
            cnb = truth_at(sc, t_abs)["cnb"]
            cnb_mean += cnb.mean(axis=0)
            phi = misalignment_batch(out.att, cnb)
            psi_all[pre].append(phi[:, 2])
            lvl_all[pre].append(phi[:, :2])
    for pre in configs:
        t_fine = t_hist[pre] - t_hist[pre][0] + 1.0 / st.kf_hz  # time since fine start
        m = min(len(p) for p in psi_all[pre])
        psi = np.array([p[:m] for p in psi_all[pre]])
        results[pre] = ConfigResult(
            label="wavelet prefilter" if pre else "raw gyro",
            t_fine_s=t_fine[:m], psi=psi, level=np.array([v[:m] for v in lvl_all[pre]]),
            conv_s=np.array([convergence_time_s(t_fine[:m], p) for p in psi]),
            wall_s=wall[pre], samples=n * st.runs)
    return results, theory(sc, st, cnb_mean[None] / (st.runs * len(configs)))


def misalignment_batch(att: np.ndarray, cnb_true: np.ndarray) -> np.ndarray:
    """Vectorised `attitude.misalignment` for (m, 3) Euler angles against (m, 3, 3) truth.

    Examples
    --------
    >>> att = np.zeros((2, 3))
    >>> misalignment_batch(att, np.stack([np.eye(3)] * 2)).tolist()
    [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
    """
    c_est = dcm_batch(att.T)
    d = np.einsum("nij,nkj->nik", cnb_true, c_est)  # C_true C_est^T = I + [phi x]
    return 0.5 * np.stack([d[:, 2, 1] - d[:, 1, 2], d[:, 0, 2] - d[:, 2, 0],
                           d[:, 1, 0] - d[:, 0, 1]], axis=-1)


def theory(sc: Scenario, st: StudyConfig, cnb_hist: np.ndarray) -> dict[str, float]:
    """Steady-state heading and level errors for the simulated constant biases (projected with
    the mean attitude) and the ARW limit at 7 min and 20 min of fine alignment.

    Examples
    --------
    >>> sc = scenario("static")
    >>> th = theory(sc, StudyConfig(scenario="static"), np.eye(3)[None])  # level, heading north
    >>> sorted(th)
    ['arw_20min_rad', 'arw_7min_rad', 'phi_e_ss_rad', 'phi_n_ss_rad', 'psi_ss_rad']
    """
    c = cnb_hist.mean(axis=0)
    u, _, vt = np.linalg.svd(c)
    c = u @ vt  # nearest rotation to the mean DCM
    eps_n = c @ (np.asarray(st.errors.gyro_bias_deg_h) * DPH)
    nab_n = c @ (np.asarray(st.errors.accel_bias_ug) * UG)
    g = gravity_m_s2(sc.lat_rad, sc.h_m)
    wc = EARTH_RATE_RAD_S * np.cos(sc.lat_rad)
    n_arw = st.errors.arw_deg_rt_h * DPSH
    return {
        "psi_ss_rad": -eps_n[0] / wc + nab_n[0] / g * np.tan(sc.lat_rad),
        "phi_e_ss_rad": -nab_n[1] / g,
        "phi_n_ss_rad": nab_n[0] / g,
        "arw_7min_rad": n_arw / (wc * np.sqrt(7 * 60.0)),
        "arw_20min_rad": n_arw / (wc * np.sqrt(20 * 60.0)),
    }


def _at(res: ConfigResult, minutes: float) -> np.ndarray:
    """Heading errors of all runs at the given fine-alignment time (NaN beyond the record)."""
    k = int(np.searchsorted(res.t_fine_s, minutes * 60.0 - 1e-9))
    if k >= len(res.t_fine_s):
        return np.full(res.psi.shape[0], np.nan)
    return res.psi[:, k]


def summary_rows(name: str, results: dict[bool, ConfigResult],
                 th: dict[str, float]) -> list[dict[str, object]]:
    """One row per configuration plus the theory row (angles in arcsec, times in min).

    Examples
    --------
    >>> st = StudyConfig(scenario="static", runs=2, duration_s=120.0, rate_hz=100.0, coarse_s=30.0)
    >>> res, th = run_study(st)
    >>> rows = summary_rows("static", res, th)
    >>> [(r["config"], r["runs"]) for r in rows][:2], rows[0]["converged"]
    ([('raw gyro', 2), ('wavelet prefilter', 2)], '0/2')
    """
    rows: list[dict[str, object]] = []
    for pre in sorted(results):
        r = results[pre]
        conv = r.conv_s / 60.0
        ok = np.isfinite(conv)
        end_min = r.t_fine_s[-1] / 60.0
        rows.append({
            "scenario": name, "config": r.label, "runs": r.psi.shape[0],
            "fine_min": round(end_min, 1),
            # Median over all runs, a non-converged run counting as +inf (NaN if half fail).
            "conv_median_min": float(np.median(np.where(ok, conv, np.inf)))
            if ok.sum() * 2 > len(ok) else float("nan"),
            "converged": f"{int(ok.sum())}/{len(ok)}",
            "psi_mean_7min": float(_at(r, 7).mean() / ARCSEC),
            "psi_1sigma_7min": float(_at(r, 7).std(ddof=1) / ARCSEC) if len(ok) > 1 else 0.0,
            "psi_1sigma_20min": float(_at(r, 20).std(ddof=1) / ARCSEC) if len(ok) > 1 else 0.0,
            "psi_mean_end": float(r.psi[:, -1].mean() / ARCSEC),
            "psi_1sigma_end": float(r.psi[:, -1].std(ddof=1) / ARCSEC) if len(ok) > 1 else 0.0,
            "phiE_mean_end": float(r.level[:, -1, 0].mean() / ARCSEC),
            "phiN_mean_end": float(r.level[:, -1, 1].mean() / ARCSEC),
            "wall_s": round(r.wall_s, 2),
        })
    rows.append({
        "scenario": name, "config": "theory", "runs": "", "fine_min": "",
        "conv_median_min": "", "converged": "",
        "psi_mean_7min": th["psi_ss_rad"] / ARCSEC,
        "psi_1sigma_7min": th["arw_7min_rad"] / ARCSEC,
        "psi_1sigma_20min": th["arw_20min_rad"] / ARCSEC,
        "psi_mean_end": th["psi_ss_rad"] / ARCSEC, "psi_1sigma_end": "",
        "phiE_mean_end": th["phi_e_ss_rad"] / ARCSEC, "phiN_mean_end": th["phi_n_ss_rad"] / ARCSEC,
        "wall_s": "",
    })
    return rows


PUBLISHED_ROW: dict[str, object] = {
    "scenario": "paper 004 (vehicle RLG, 8 runs)", "config": "wavelet prefilter",
    "runs": 8, "fine_min": 20, "conv_median_min": 7.0, "converged": "8/8",
    "psi_mean_7min": "", "psi_1sigma_7min": 39.0, "psi_1sigma_20min": "",
    "psi_mean_end": "", "psi_1sigma_end": "", "phiE_mean_end": "", "phiN_mean_end": "",
    "wall_s": "",
}
PUBLISHED_RAW_ROW: dict[str, object] = {
    **PUBLISHED_ROW, "config": "raw gyro", "runs": 1, "conv_median_min": "> 20",
    "converged": "0/1", "psi_1sigma_7min": "",
}

# Mechanism study: which modelled effects make the prefilter help.
MECHANISMS: dict[str, tuple[str, ImuErrors, str]] = {
    "white+bias": ("static", ImuErrors(), "spec"),
    "quantization": ("static", ImuErrors(gyro_lsb_arcsec=0.1), "spec"),
    "dither residue": ("static", ImuErrors(dither_residue_arcsec=2.0), "spec"),
    "engine vibration": ("vehicle_engine", ImuErrors(), "spec"),
    "Q from raw scatter": ("static", ImuErrors(gyro_lsb_arcsec=0.1, dither_residue_arcsec=2.0),
                           "samples"),
}


def fmt(v: object) -> str:
    """One table cell: floats with one decimal, inf as not converged, NaN as n/a.

    Examples
    --------
    >>> fmt(1.234), fmt(float("inf")), fmt("x")
    ('1.2', 'not conv.', 'x')
    """
    if isinstance(v, float):
        if np.isinf(v):
            return "not conv."
        return "n/a" if np.isnan(v) else f"{v:.1f}"
    return str(v)


def markdown_table(rows: list[dict[str, object]]) -> str:
    """Rows of dicts (the first row's keys are the columns) as a markdown table.

    Examples
    --------
    >>> print(markdown_table([{"a": 1.0, "b": "x"}]))
    | a | b |
    |---|---|
    | 1.0 | x |
    """
    keys = list(rows[0].keys())
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(fmt(r.get(k, "")) for k in keys) + " |" for r in rows]
    return "\n".join(lines)
