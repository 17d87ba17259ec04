"""Defaults that several areas share, written once.

Examples
--------
>>> DEFAULT_SAMPLE_RATE_HZ, PREFILTER_WAVELET, PREFILTER_WINDOW, PREFILTER_LEVEL
(400.0, 'db4', 256, 5)
"""

from __future__ import annotations

__all__ = [
    "DEFAULT_SAMPLE_RATE_HZ",
    "PREFILTER_LEVEL",
    "PREFILTER_THRESHOLD",
    "PREFILTER_WAVELET",
    "PREFILTER_WINDOW",
    "RATE_MAX_HZ",
    "RATE_MIN_HZ",
]

#: The IMU sample rate assumed when none is given, Hz: the shipped processor configuration's,
#: the simulator's, the alignment study's (the 2014 paper's 400 Hz IMU) and the prefilter
#: responses'.
DEFAULT_SAMPLE_RATE_HZ = 400.0

#: The real-time sliding-window prefilter of the 2014 paper (before SINS initial alignment):
#: db4, a window of N = 256 samples, level 5, all details zeroed ("forced"). The defaults of
#: the real-time wavelet filters, their FIR form and the processor's wavelet stage.
PREFILTER_WAVELET = "db4"
PREFILTER_WINDOW = 256
PREFILTER_LEVEL = 5
PREFILTER_THRESHOLD = "forced"

#: The sample rates a record may have, Hz, given (``--rate-hz``) or read from a file (a time
#: column, a log's timestamps, a header): outside them the analyses' fits overflow, and a
#: rate read from a file outside them means time in other units than assumed.
RATE_MIN_HZ = 1e-6
RATE_MAX_HZ = 1e9
