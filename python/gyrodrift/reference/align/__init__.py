"""Plain-loop numpy references of the SINS alignment (paper 004), the oracles of the
C++ headers ``include/gyrodrift/nav/*.hpp`` that `gyrodrift.nav.run_alignment` runs:
strapdown, inertial-frame coarse alignment, the 12/15-state fine-alignment Kalman filter and
the whole pipeline.

Examples
--------
>>> from gyrodrift.reference.align import Strapdown
>>> Strapdown.__name__
'Strapdown'
"""

from __future__ import annotations

from gyrodrift.reference.align.coarse import InertialCoarseAlign
from gyrodrift.reference.align.fine_kf import FineAlignKF
from gyrodrift.reference.align.pipeline import run_alignment_reference
from gyrodrift.reference.align.strapdown import Strapdown

__all__ = ["FineAlignKF", "InertialCoarseAlign", "Strapdown", "run_alignment_reference"]
