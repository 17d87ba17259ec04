"""Drift filters and their identification: AR(2) models and AR/AR(2)-Kalman filters, the
maximum-likelihood drift model, lifting wavelets and wavelet packets, and the forced real-time
wavelet prefilter as an FIR."""

__all__: list[str] = []
