"""The processor contract: flag bits, health counter names, the resync count and the timing
defaults, defined once in include/gyrodrift/imu/imu_processor.hpp and read from the compiled
module on first use (module ``__getattr__``, so importing this module needs no extension).

Examples
--------
>>> from gyrodrift.imu import contract as imu
>>> imu.describe_flags(imu.FLAG_DUPLICATE)
['duplicate']
"""

from __future__ import annotations

from typing import Any

from gyrodrift._native import core

__all__ = [
    "CHANNELS",
    "DEFAULT_PERIOD_US",
    "DEFAULT_TIME_TOLERANCE_US",
    "FLAG_CONFIG_ERROR",
    "FLAG_DUPLICATE",
    "FLAG_FILTER_FAULT",
    "FLAG_HEALTH_ALARM",
    "FLAG_NAMES",
    "FLAG_NON_FINITE",
    "FLAG_OUT_OF_ORDER",
    "FLAG_REJECTED",
    "FLAG_RESYNC",
    "FLAG_SATURATED",
    "FLAG_SEQ_GAP",
    "FLAG_STUCK",
    "FLAG_TIME_JUMP",
    "HEALTH_KEYS",
    "RESYNC_AFTER",
    "contract",
    "describe_flags",
]

#: Channels of the processor, in order: gyro x y z (rad/s), accelerometer x y z (m/s^2).
CHANNELS = 6

# The processor contract (flag bits, health counter names, defaults) is defined once, in
# include/gyrodrift/imu/imu_processor.hpp, and read from the compiled module on first use (module
# __getattr__, so `import gyrodrift` works without the extension); tests/test_imu_contract.py
# checks every other copy (the loop's JSON, the harness, the docs) against it.
_FLAG_CONSTANTS = {
    "FLAG_NON_FINITE": "non_finite",
    "FLAG_SATURATED": "saturated",
    "FLAG_STUCK": "stuck",
    "FLAG_SEQ_GAP": "seq_gap",
    "FLAG_DUPLICATE": "duplicate",
    "FLAG_OUT_OF_ORDER": "out_of_order",
    "FLAG_TIME_JUMP": "time_jump",
    "FLAG_FILTER_FAULT": "filter_fault",
    "FLAG_RESYNC": "resync",
    "FLAG_HEALTH_ALARM": "health_alarm",
    "FLAG_CONFIG_ERROR": "config_error",
    "FLAG_REJECTED": "rejected",
}
_contract_cache: dict[str, Any] = {}
# Declared here, resolved by __getattr__ below (from gyrodrift._core) on first access.
FLAG_NON_FINITE: int
FLAG_SATURATED: int
FLAG_STUCK: int
FLAG_SEQ_GAP: int
FLAG_DUPLICATE: int
FLAG_OUT_OF_ORDER: int
FLAG_TIME_JUMP: int
FLAG_FILTER_FAULT: int
FLAG_RESYNC: int
FLAG_HEALTH_ALARM: int
FLAG_CONFIG_ERROR: int
FLAG_REJECTED: int
FLAG_NAMES: dict[int, str]
RESYNC_AFTER: int
HEALTH_KEYS: tuple[str, ...]
DEFAULT_PERIOD_US: int
DEFAULT_TIME_TOLERANCE_US: int


def contract() -> dict[str, Any]:
    """The processor contract from gyrodrift._core: ``flags`` {name: bit}, ``health_keys``,
    ``resync_after``, ``default_period_us``, ``default_time_tolerance_us``.

    Examples
    --------
    >>> from gyrodrift.imu import contract as imu
    >>> c = contract()  # read from the C++ processor (imu/imu_processor.hpp) through the binding
    >>> c["flags"]["duplicate"] == imu.FLAG_DUPLICATE, c["default_period_us"]
    (True, 2500)
    """
    if not _contract_cache:
        lib = core("imu")
        _contract_cache.update(
            flags=dict(lib.IMU_FLAGS),
            health_keys=tuple(lib.IMU_HEALTH_KEYS),
            resync_after=int(lib.IMU_RESYNC_AFTER),
            default_period_us=int(lib.IMU_DEFAULT_PERIOD_US),
            default_time_tolerance_us=int(lib.IMU_DEFAULT_TIME_TOLERANCE_US),
        )
    return _contract_cache


def __getattr__(name: str) -> Any:
    if name in _FLAG_CONSTANTS:
        return contract()["flags"][_FLAG_CONSTANTS[name]]
    if name == "FLAG_NAMES":
        return {bit: flag for flag, bit in contract()["flags"].items()}
    if name == "HEALTH_KEYS":
        return contract()["health_keys"]
    if name == "RESYNC_AFTER":
        return contract()["resync_after"]
    if name == "DEFAULT_PERIOD_US":
        return contract()["default_period_us"]
    if name == "DEFAULT_TIME_TOLERANCE_US":
        return contract()["default_time_tolerance_us"]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def describe_flags(flags: int) -> list[str]:
    """Names of the bits set in a flags word.

    Examples
    --------
    >>> from gyrodrift.imu import contract as imu
    >>> describe_flags(0), describe_flags(imu.FLAG_DUPLICATE | imu.FLAG_REJECTED)
    ([], ['duplicate', 'rejected'])
    """
    return [name for name, bit in contract()["flags"].items() if flags & bit]
