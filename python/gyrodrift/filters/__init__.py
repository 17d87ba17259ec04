"""Drift filters and their identification: AR(2) models and AR/AR(2)-Kalman filters, the
maximum-likelihood drift model and its online re-identification, lifting wavelets and wavelet
packets, and the forced real-time wavelet prefilter as an FIR.

Examples
--------
>>> from gyrodrift.filters import OnlineDriftSettings
>>> OnlineDriftSettings().block_samples
400
"""

from gyrodrift.filters.online import DriftParams as DriftParams
from gyrodrift.filters.online import OnlineDriftIdentifier as OnlineDriftIdentifier
from gyrodrift.filters.online import OnlineDriftSettings as OnlineDriftSettings
from gyrodrift.filters.online import OnlineDriftTrace as OnlineDriftTrace
from gyrodrift.filters.online import SharedDriftIdentifier as SharedDriftIdentifier

__all__: list[str] = ["DriftParams", "OnlineDriftIdentifier", "OnlineDriftSettings",
                      "OnlineDriftTrace", "SharedDriftIdentifier"]
