"""Reference implementations in numpy / PyWavelets, written straight from the equations.

They are deliberately plain (loops where the equations have loops) and are the oracles the
C++ core is tested against; they are not the fast path.
"""

from __future__ import annotations

# --- foundation (issue 2) ---
# --- wavelets (issue 3) ---
# --- Allan (issue 4) ---
# --- IMU processor / codecs (issue 5) ---
# --- alignment (issue 6) ---
