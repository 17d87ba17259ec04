"""Frequency-stability analysis and noise identification: the Allan deviation family with
its edf and noise types, the PSD, the IEEE Std 952 term fit and GMWM."""

__all__: list[str] = []
