"""Defaults that several areas share, written once.

Examples
--------
>>> DEFAULT_SAMPLE_RATE_HZ
400.0
"""

from __future__ import annotations

__all__ = ["DEFAULT_SAMPLE_RATE_HZ"]

#: The IMU sample rate assumed when none is given, Hz: the shipped processor configuration's,
#: the simulator's, the alignment study's (the 2014 paper's 400 Hz IMU) and the prefilter
#: responses'.
DEFAULT_SAMPLE_RATE_HZ = 400.0
