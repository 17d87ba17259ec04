"""Drift filters and their identification: AR(2) models and AR/AR(2)-Kalman filters, the
maximum-likelihood drift model, its online re-identification and the whole-record lag
statistics it can be fitted from, lifting wavelets and wavelet packets, and the forced real-time
wavelet prefilter as an FIR.

Examples
--------
>>> from gyrodrift.filters import OnlineDriftSettings
>>> OnlineDriftSettings().block_samples
400
"""

from gyrodrift.filters.lag_statistics import LagDriftFitError as LagDriftFitError
from gyrodrift.filters.lag_statistics import LagDriftFitResult as LagDriftFitResult
from gyrodrift.filters.lag_statistics import LagStatistics as LagStatistics
from gyrodrift.filters.lag_statistics import lag_drift_fit as lag_drift_fit
from gyrodrift.filters.lag_statistics import lag_drift_loglike as lag_drift_loglike
from gyrodrift.filters.online import DriftParams as DriftParams
from gyrodrift.filters.online import OnlineDriftIdentifier as OnlineDriftIdentifier
from gyrodrift.filters.online import OnlineDriftSettings as OnlineDriftSettings
from gyrodrift.filters.online import OnlineDriftTrace as OnlineDriftTrace
from gyrodrift.filters.online import SharedDriftIdentifier as SharedDriftIdentifier

__all__: list[str] = ["DriftParams", "LagDriftFitError", "LagDriftFitResult", "LagStatistics",
                      "OnlineDriftIdentifier", "OnlineDriftSettings", "OnlineDriftTrace",
                      "SharedDriftIdentifier", "lag_drift_fit", "lag_drift_loglike"]
