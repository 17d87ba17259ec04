"""The lag-statistics re-identification on the shared real record (lasergyro.imu, the z gyro,
the [monitor] defaults as in scripts/monitor_real_record.py): a drift whose innovation filter
is too slow for the identifier's L = 8 lags is refused by the truncation guard at every fit,
and the learned model and its gain stay in use; the alarms do not depend on the identifier
(docs/validation/monitor-real-record.md, "Re-identification over time")."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from gyrodrift.imu.config import MonitorConfig
from gyrodrift.imu.monitor import reference_from_record, run_monitor
from gyrodrift.io.psins import read_psins_imu
from gyrodrift.reference.lag_drift import innovation_pole

RATE_HZ = 100.0
LEARN_S = 600.0
#: The lag identifier's lags and the truncation its Whittle fit accepts (rho^L at most this):
#: include/gyrodrift/filters/lag_drift_identifier.hpp, docs/validation/online-identification.md
#: ("Whittle without the first samples, by L").
LAGS = 8
TRUNCATION_TOL = 3e-3


def test_real_record_slow_drift_is_refused_as_truncation(lasergyro_path: Path) -> None:
    rec = read_psins_imu(lasergyro_path)
    y = np.ascontiguousarray(rec.dtheta[:, 2] / rec.dt_s)
    ref = reference_from_record(y, RATE_HZ, LEARN_S, MonitorConfig().octaves)
    a1, a2, q, r, _ = ref.drift
    # The precondition, from the numpy reference: the learned model's innovation pole (0.81)
    # puts rho^L far above the tolerance (0.18), so no nearby estimate passes either.
    assert innovation_pole(a1, a2, q, r) ** LAGS > 10 * TRUNCATION_TOL
    lag = run_monitor(y, RATE_HZ, ref, settings=MonitorConfig(reidentify=True, identifier="lag"),
                      report_every_s=5.0, dtype=np.float32)
    applied = np.flatnonzero(np.diff(np.r_[0, lag.retunes + lag.refused_retunes]) > 0)
    # A fit requested at 600 s and every 60 s after, each applied 15 s later: 21 in 1847 s.
    assert lag.t_s[applied].tolist() == [615.0 + 60.0 * k for k in range(21)]
    assert lag.retunes[-1] == 0 and lag.refused_retunes[-1] == 21
    assert {lag.status[i] for i in applied} == {"fallback"}
    assert {lag.fit_status[i] for i in applied} == {"truncation"}
    # The learned model and its gain in use at every report (float state: the model as
    # stored in float, the gain the one computed before any fit).
    for name, value in zip(("a1", "a2", "q", "r"), (a1, a2, q, r), strict=True):
        np.testing.assert_allclose(getattr(lag, name), value, rtol=1e-6)
    assert np.all(lag.gain0 == lag.gain0[0]) and np.all(lag.gain1 == lag.gain1[0])
    # The alarms compare against the reference, not the model in use.
    rec_run = run_monitor(y, RATE_HZ, ref, settings=MonitorConfig(reidentify=True),
                          report_every_s=5.0, dtype=np.float32)
    assert rec_run.retunes[-1] > 0
    assert rec_run.trips == lag.trips and np.array_equal(rec_run.health, lag.health)
