"""The six-channel IMU processor: its configuration file, its contract (flags, health
counters), the C++ processor over whole records and the generated firmware header."""

__all__: list[str] = []
