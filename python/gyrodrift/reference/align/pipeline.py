"""Whole alignment over arrays of increments: optional gyro prefilter (+ matching accelerometer
delay), inertial-frame coarse alignment, then strapdown + fine-alignment KF with feedback.
Reference for nav/align_pipeline.hpp (same order of operations, same results within 1e-9).
"""

from __future__ import annotations

import numpy as np

from gyrodrift.nav.align_config import AlignConfig, AlignResult
from gyrodrift.nav.attitude import dcm2euler, dcm2q, q2dcm, qmul, qnormalize, rv2q
from gyrodrift.nav.earth import earth_params

from .coarse import InertialCoarseAlign
from .fine_kf import FineAlignKF
from .strapdown import Strapdown

__all__ = ["run_alignment_reference"]


def run_alignment_reference(dtheta: np.ndarray, dv: np.ndarray,
                            cfg: AlignConfig) -> AlignResult:
    """Plain-loop reference. Returns the per-KF-update histories as an `AlignResult`
    (bad_samples 0, failed False: the reference has no fault handling).
    Alignment starts after the warm-up max(n_taps - 1, delay) samples that fill the prefilter
    window and the delay line (see nav/align_pipeline.hpp for why).

    Examples
    --------
    >>> from gyrodrift.nav import AlignConfig, imu_increments, scenario
    >>> sc = scenario("static")
    >>> dth, dv = imu_increments(sc, 100 * 50, 0.01)  # 50 s at rest, 100 Hz
    >>> cfg = AlignConfig(dt_s=0.01, lat_rad=sc.lat_rad, h_m=sc.h_m, coarse_s=30.0)
    >>> res = run_alignment_reference(dth, dv, cfg)
    >>> res.failed, res.att.shape, np.rad2deg(res.att[-1]).round(3) + 0.0
    (False, (50, 3), array([ 0.,  0., 30.]))
    """
    dtheta = np.asarray(dtheta, dtype=float)
    dv = np.asarray(dv, dtype=float)
    n = dtheta.shape[0]
    n_coarse = cfg.coarse_samples()
    if dtheta.shape != (n, 3) or dv.shape != (n, 3):
        raise ValueError("dtheta and dv must both have shape (n, 3)")
    if n <= n_coarse:
        raise ValueError(f"need more than {n_coarse} samples (coarse alignment), got {n}")
    taps = None if cfg.taps is None else np.asarray(cfg.taps, dtype=float)
    nt = 0 if taps is None else len(taps)
    coarse = InertialCoarseAlign(n_coarse, cfg.dt_s, cfg.lat_rad, cfg.h_m,
                                 cfg.coarse_position_integral)
    kf: FineAlignKF | None = None
    sd: Strapdown | None = None
    eb = np.zeros(3)
    db = np.zeros(3)
    dvn_sum = np.zeros(3)
    count = 0
    hist: dict[str, list] = {"t_s": [], "att": [], "eb": [], "db": [], "p_phi": []}
    n_stage = cfg.heading_stage_cycles()
    q_spec, q_stage = cfg.q_diag(), cfg.q_stage_diag()
    cycles = 0
    coarse_cnb = np.eye(3)
    d = cfg.accel_delay_samples
    warmup = max(nt - 1, d) if nt > 0 else d
    if n <= warmup + n_coarse:
        raise ValueError(f"need more than {warmup + n_coarse} samples (warm-up + coarse)")
    for k_in in range(n):
        k = k_in - warmup
        if k < 0:
            continue
        g = dtheta[k_in]
        if taps is not None and k_in >= nt - 1:
            # y_k = sum_i b_i x_{k-i}, taps newest first (gyrodrift.filters.fir)
            g = taps @ dtheta[k_in - nt + 1:k_in + 1][::-1]
        a = dv[k_in - d] if k_in >= d else dv[k_in]
        if k < n_coarse:
            if coarse.add(g, a):
                coarse_cnb = coarse.solve()
                sd = Strapdown(dcm2q(coarse_cnb), np.zeros(3), cfg.lat_rad, cfg.lon_rad, cfg.h_m)
                kf = FineAlignKF(cfg.n_states, cfg.p0_diag(), cfg.q_diag(),
                                 np.full(3, cfg.zv_sigma_m_s ** 2), cfg.floor_diag())
            continue
        assert sd is not None and kf is not None
        dvn_sum += sd.step(g - eb * cfg.dt_s, a - db * cfg.dt_s, cfg.dt_s)
        count += 1
        if count < cfg.kf_every:
            continue
        t_kf = count * cfg.dt_s
        fn = dvn_sum / t_kf
        ep = earth_params(sd.pos[0], sd.pos[2], sd.vn)
        if n_stage > 0 and cycles == n_stage:
            # End of acquisition: drop what the drift/bias states learnt under the wrong
            # small-angle model (psi leaks into eps_E as W cos L sin psi); restart from P0.
            kf = FineAlignKF(cfg.n_states, cfg.p0_diag(), cfg.q_diag(),
                             np.full(3, cfg.zv_sigma_m_s ** 2), cfg.floor_diag())
            eb = np.zeros(3)
            db = np.zeros(3)
        kf.q = q_stage if cycles < n_stage else q_spec
        cycles += 1
        kf.predict(kf.transition(q2dcm(sd.q), fn, sd.vn, ep, sd.pos[0]), t_kf)
        x = kf.update(sd.vn)
        # Feedback: C_true = (I + [phi x]) C_est, v -= dv, position -= dp, biases accumulate.
        sd.q = qnormalize(qmul(rv2q(x[0:3]), sd.q))
        sd.vn = sd.vn - x[3:6]
        if cfg.n_states == 15:
            sd.pos = sd.pos - np.array([x[7] / ep.rm_h_m,
                                        x[6] / (ep.rn_h_m * np.cos(sd.pos[0])), x[8]])
        eb = eb + x[kf.i_eb:kf.i_eb + 3]
        db = db + x[kf.i_db:kf.i_db + 3]
        dvn_sum = np.zeros(3)
        count = 0
        hist["t_s"].append((k_in + 1 - d) * cfg.dt_s)
        hist["att"].append(dcm2euler(q2dcm(sd.q)))
        hist["eb"].append(eb.copy())
        hist["db"].append(db.copy())
        hist["p_phi"].append(np.sqrt(np.diag(kf.P)[0:3]))
    def arr(key: str) -> np.ndarray:
        return np.array(hist[key]).reshape(-1, 3) if key != "t_s" else np.array(hist[key])

    return AlignResult(arr("t_s"), arr("att"), arr("eb"), arr("db"), arr("p_phi"), coarse_cnb)
