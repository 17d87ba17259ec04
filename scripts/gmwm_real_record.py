#!/usr/bin/env python3
"""Noise identification of the shared ring-laser record: per gyro axis, GMWM with
WIC model selection on the scales tau_j >= 2.56 s (above the vehicle-vibration peak), the
IEEE 952 Allan fit (model selection, 95 % intervals, lag-1 ACF noise types for the
edf) on the range where its model holds, and the old all-terms NNLS fit of the whole curve.

    PYTHONPATH=python:build/dev-NAME/py python scripts/gmwm_real_record.py [PATH]

tests/test_identify_real.py checks the same fits (fitted total inside the empirical
interval at every tau / scale used).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

#: per axis: GMWM scale range (s), Allan fit range (s); chosen where the models hold
GMWM_TAU_MIN_S = 2.56
ALLAN_FIT_MIN_S = {"x": 5.0, "y": 20.0, "z": 5.0}


#: The shared real record beside the checkout (../shared/data, see its README).
SHARED_RECORD = str(Path(__file__).resolve().parents[2] / "shared" / "data" / "lasergyro.imu")

def load_axes(path: str | Path) -> dict[str, np.ndarray]:
    """Gyro rates in deg/h per axis (PSINS counts x 0.1 arcsec per 10 ms sample)."""
    from gyrodrift.io.psins import read_psins_imu

    rec = read_psins_imu(path)
    rate = rec.dtheta / rec.dt_s * (180.0 / np.pi) * 3600.0
    return {ax: np.ascontiguousarray(rate[:, k]) for k, ax in enumerate("xyz")}


def main(argv: list[str]) -> int:
    import gyrodrift
    from gyrodrift.stability import ieee952
    from gyrodrift.stability.allan_fit import fit_allan
    from gyrodrift.stability.gmwm import identify_gmwm

    path = argv[0] if argv else SHARED_RECORD
    for ax, x in load_axes(path).items():
        print(f"\n## axis {ax} (mean {x.mean():.3f} deg/h)")
        t0 = time.perf_counter()
        g = identify_gmwm(x, 100.0, model="auto", tau_range=(GMWM_TAU_MIN_S, np.inf))
        inside = (g.wv_fit >= g.wv_ci_low) & (g.wv_fit <= g.wv_ci_high)
        other = next(c for c in g.candidates if c[0] != g.model)
        print(f"GMWM ({time.perf_counter() - t0:.0f} s), scales {g.tau_s[0]:g}..{g.tau_s[-1]:g}"
              f" s: model {g.model}, fitted total inside the 95 % WV interval at "
              f"{int(inside.sum())}/{inside.size} scales; WIC {g.wic:.2f}; best other "
              f"candidate {other[0]} (WIC {other[1]:.2f})")
        for p in g.params:
            d = ("" if p.density is None else
                 f" = {p.density:.3g} [{p.density_ci_low:.3g}, {p.density_ci_high:.3g}] "
                 f"{p.density_unit}")
            print(f"  {p.name} = {p.value:.4g} [{p.ci_low:.4g}, {p.ci_high:.4g}] {p.unit}{d}")
        r = gyrodrift.oadev(x, 100.0, taus="octave", ci=0.95, alpha="acf")
        f = fit_allan(r.tau_s, r.adev, r.edf, fit_range=(ALLAN_FIT_MIN_S[ax], np.inf), ci=0.95)
        inside = ((f.fit_adev >= r.ci_low) & (f.fit_adev <= r.ci_high))[f.fit_used]
        print(f"Allan fit, taus {f.tau_min_s:g}..{f.tau_max_s:g} s: "
              + ", ".join(f"{t.name} = {t.value:.4g} [{t.ci_low:.4g}, {t.ci_high:.4g}] {t.unit}"
                          for t in f.terms)
              + f"; dropped {','.join(f.dropped)}; inside the 95 % interval at "
              f"{int(inside.sum())}/{inside.size} taus")
        rd = gyrodrift.oadev(x, 100.0, taus="octave", alpha="slope")  # the old default
        old = ieee952.identify(rd.tau_s, rd.adev, rd.edf)
        model = ieee952.allan_model_deg_h(rd.tau_s, old.q_arcsec, old.n_deg_rt_h, old.b_deg_h,
                                           old.k_deg_h_rt_h, old.r_deg_h2)
        ratio = model / rd.adev
        print(f"old all-terms NNLS fit (whole curve, slope noise types): Q = {old.q_arcsec:.3g} "
              f"arcsec, N = {old.n_deg_rt_h:.3g} deg/sqrt(h), B = {old.b_deg_h:.3g} deg/h, "
              f"K = {old.k_deg_h_rt_h:.3g} deg/h/sqrt(h), R = {old.r_deg_h2:.3g} deg/h^2; "
              f"model/data {ratio.min():.3g}..{ratio.max():.3g}")
        sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
