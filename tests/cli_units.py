"""The units the older command-line tests' records are in, stated as the command line now
requires (a .npy or text record does not say its units; the commands never guess them).

Those tests write records in deg/h (the simulator's unit) and accelerometer data in m/s^2;
:func:`with_units` adds ``--gyro-units deg/h`` (and ``--accel-units m/s^2`` for the
multi-channel commands) to a command that reads such a record and does not state them.
"""

from __future__ import annotations

from collections.abc import Sequence

#: Commands that read a record (their first positional argument).
RECORD_COMMANDS = {"allan", "identify", "psd", "fit", "filter", "compare", "characterize",
                   "fleet"}
MULTI_CHANNEL = {"characterize", "fleet"}
UNITLESS_SUFFIXES = (".npy", ".csv", ".txt", ".dat", ".tsv")


def with_units(argv: Sequence[object]) -> list[str]:
    """``argv`` as strings, with the units flags added where the command needs them."""
    args = [str(a) for a in argv]
    if not args or args[0] not in RECORD_COMMANDS:
        return args
    if not any(a.lower().endswith(UNITLESS_SUFFIXES) for a in args[1:]):
        return args
    if "--gyro-units" not in args:
        args += ["--gyro-units", "deg/h"]
    if args[0] in MULTI_CHANNEL and "--accel-units" not in args:
        args += ["--accel-units", "m/s^2"]
    return args
