"""The gyro monitor the target runs, over whole records: streaming Allan statistics, online
noise estimates (N, B, K with intervals), online re-identification of the drift model with its
retuned gain, and latched health alarms, sample by sample through the C++ core
(include/gyrodrift/imu/gyro_monitor.hpp).

INTERFACE SKELETON: :func:`run_monitor` is not implemented yet. The names, fields and units
below are fixed; the implementation fills them.

Units: every rate quantity is in the channel's base unit, rad/s (N in rad/sqrt(s), B in rad/s,
K in rad/s/sqrt(s), q and r in (rad/s)^2); the command line converts to deg/sqrt(h), deg/h and
deg/h/sqrt(h).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

__all__ = ["MonitorReference", "MonitorTrace", "run_monitor"]


@dataclass(frozen=True)
class MonitorReference:
    """What the alarms compare against and where the re-identification starts.

    drift: the configured drift model (a1, a2, q, r, mean), units rad/s and (rad/s)^2; the
    fallback of the re-identification. avar: expected Allan variance at tau0 * 2^k, (rad/s)^2,
    one value per octave (from the drift model, or learned from the first part of a record).
    source: "config" or "learned" (with the learning span in seconds in learn_s).
    """

    drift: tuple[float, float, float, float, float]
    avar: np.ndarray
    source: str = "config"
    learn_s: float = 0.0


@dataclass(frozen=True)
class MonitorTrace:
    """One row per report interval (arrays of equal length).

    t_s: time of the report, s from the record's start. n, b, k with lo/hi: online noise
    estimates and their intervals (NaN where not estimable; k_upper_limit marks rows where only
    k_hi is meaningful). a1, a2, q, r, mean: the model in use by the filter gain; gain0, gain1:
    its steady-state Kalman gain. status: the re-identification status name per row. health:
    latched alarm bits per row; alarm_names: the name of each bit (bit i = alarm_names[i]).
    trips: for each raised alarm, the statistic that tripped it (statistic, threshold, tau_s,
    t_s). reference: what the alarms compared against.
    """

    t_s: np.ndarray
    n: np.ndarray
    n_lo: np.ndarray
    n_hi: np.ndarray
    b: np.ndarray
    b_lo: np.ndarray
    b_hi: np.ndarray
    k: np.ndarray
    k_lo: np.ndarray
    k_hi: np.ndarray
    k_upper_limit: np.ndarray
    a1: np.ndarray
    a2: np.ndarray
    q: np.ndarray
    r: np.ndarray
    mean: np.ndarray
    gain0: np.ndarray
    gain1: np.ndarray
    status: tuple[str, ...]
    health: np.ndarray
    alarm_names: tuple[str, ...]
    trips: dict[str, dict[str, float]] = field(default_factory=dict)
    reference: MonitorReference | None = None

    def flags(self, row: int) -> list[str]:
        """Names of the alarms raised at report ``row`` (empty when healthy)."""
        bits = int(self.health[row])
        return [name for i, name in enumerate(self.alarm_names) if bits >> i & 1]


def run_monitor(y_rad_s: ArrayLike, rate_hz: float, reference: MonitorReference, *,
                settings: Any = None, report_every_s: float = 10.0,
                stuck: ArrayLike | None = None, saturated: ArrayLike | None = None,
                dtype: DTypeLike = np.float64) -> MonitorTrace:
    """Run the monitor over one gyro channel ``y_rad_s`` (rad/s) sampled at ``rate_hz``.

    settings: the configuration file's monitor section (None: its defaults). stuck, saturated:
    per-sample booleans from the processor's checks (None: computed as the processor does).
    """
    raise NotImplementedError("run_monitor is not implemented yet")
