"""Hardware-in-the-loop replay: logs, wire encoding, pty/CAN links, the harness and report.

    from gyrodrift.replay import ReplayOptions, run_replay, read_imu_log
    result = run_replay(read_imu_log("rec.bin"), ReplayOptions(transport="serial", speed=1.0))
    print(result.report["accounting"], result.ok)
"""

from __future__ import annotations

from gyrodrift.io.imu_log import FORMATS, log_format, read_imu_log, write_imu_log
from gyrodrift.replay.faults import FaultSpec
from gyrodrift.replay.harness import ReplayError, ReplayOptions, ReplayResult, run_replay

__all__ = [
    "FORMATS",
    "FaultSpec",
    "ReplayError",
    "ReplayOptions",
    "ReplayResult",
    "log_format",
    "read_imu_log",
    "run_replay",
    "write_imu_log",
]
