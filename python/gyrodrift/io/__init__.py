"""Reading and writing records: every file reader and writer (records, IMU files, binary IMU logs,
PSINS text), the one atomic file write and strict JSON text.

Below the algorithms: nothing here computes a result from the data, so every other area may
read and write through it."""

__all__: list[str] = []
