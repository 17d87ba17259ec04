"""Simulated gyro and IMU records with known noise terms (IEEE Std 952 terms, AR(2) drift)."""

__all__: list[str] = []
