"""Frequency-stability analysis and noise identification: the Allan deviation family with
its edf and noise types, the PSD, the IEEE Std 952 term fit and GMWM.

The noise identifiers a caller may choose, and the one default every command uses:

- ``allan-nnls``: the IEEE Std 952 weighted NNLS fit of the Allan variance with term
  selection (:mod:`gyrodrift.stability.allan_fit`);
- ``gmwm``: the generalized method of wavelet moments (:mod:`gyrodrift.stability.gmwm`);
- ``slope``: the IEEE Std 952 slope read-offs of one Allan curve (no fitted model).

Examples
--------
>>> DEFAULT_IDENTIFIER, MODEL_IDENTIFIERS, NOISE_IDENTIFIERS
('allan-nnls', ('allan-nnls', 'gmwm'), ('allan-nnls', 'gmwm', 'slope'))
>>> IEEE952_TERMS
('Q', 'N', 'B', 'K', 'R')
"""

__all__: list[str] = ["DEFAULT_IDENTIFIER", "IEEE952_TERMS", "MODEL_IDENTIFIERS",
                      "NOISE_IDENTIFIERS"]

#: The five IEEE Std 952 noise terms in order of the power of tau: quantization Q, angle
#: random walk N, bias instability B, rate random walk K, rate ramp R (the terms a fit may use
#: unless told otherwise).
IEEE952_TERMS: tuple[str, ...] = ("Q", "N", "B", "K", "R")

#: Every noise identifier (``gyrodrift identify --identifier``).
NOISE_IDENTIFIERS: tuple[str, ...] = ("allan-nnls", "gmwm", "slope")
#: The identifiers that give a fitted noise model per channel (whole-IMU characterization,
#: fleets, the Kalibr export): the slope read-offs give none.
MODEL_IDENTIFIERS: tuple[str, ...] = ("allan-nnls", "gmwm")
#: The one default noise identifier of the library and of every command.
DEFAULT_IDENTIFIER = "allan-nnls"
