"""Simulated gyro and IMU records with known noise terms (IEEE Std 952 terms, AR(2) drift),
and realistic, misspecified records imitating published datasheets (`presets`)."""

from gyrodrift.simulation.presets import PRESETS as PRESETS
from gyrodrift.simulation.presets import PresetRecord as PresetRecord
from gyrodrift.simulation.presets import PresetTruth as PresetTruth
from gyrodrift.simulation.presets import SensorPreset as SensorPreset
from gyrodrift.simulation.presets import simulate_preset as simulate_preset

__all__: list[str] = ["PRESETS", "PresetRecord", "PresetTruth", "SensorPreset",
                      "simulate_preset"]
