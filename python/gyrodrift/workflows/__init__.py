"""Jobs built from the areas below: characterize a whole IMU, characterize a fleet of logs."""

__all__: list[str] = []
