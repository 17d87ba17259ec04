"""Hardware-in-the-loop replay: logs, wire encoding, pty/CAN transport, the harness and report."""

from __future__ import annotations

from gyrodrift.replay.logs import FORMATS, log_format, read_imu_log, write_imu_log

__all__ = ["FORMATS", "log_format", "read_imu_log", "write_imu_log"]
