"""Configuration of the ``occupancy-grid`` map (import-light: pydantic only)."""

from __future__ import annotations

import math

from pydantic import Field, model_validator

from hapticframe import PluginConfig, RegionConfig

__all__ = ["OccupancyGridConfig"]


class OccupancyGridConfig(PluginConfig):
    """Log-odds occupancy grid; defaults are OctoMap's sensor-model constants."""

    region: RegionConfig | None = Field(
        None,
        description=(
            "Mapped rectangle in metres. Default: the scene's region when the experiment has "
            "a scene, else the thesis's 0.75 x 0.50 m search area."
        ),
    )
    cell_size_m: float = Field(
        0.01, gt=0, le=10.0, description="Edge length of the square grid cells."
    )
    probability_hit: float = Field(
        0.7,
        gt=0.5,
        lt=1.0,
        description="Occupancy probability of an occupied observation (OctoMap: 0.7, +0.847 "
        "in log odds).",
    )
    probability_miss: float = Field(
        0.4,
        gt=0.0,
        lt=0.5,
        description="Occupancy probability of a free observation (OctoMap: 0.4, -0.405).",
    )
    clamping_min: float = Field(
        0.1192,
        gt=0.0,
        lt=0.5,
        description="Lower clamping bound of a cell's probability (OctoMap: 0.1192, -2.0).",
    )
    clamping_max: float = Field(
        0.971,
        gt=0.5,
        lt=1.0,
        description="Upper clamping bound of a cell's probability (OctoMap: 0.971, +3.5).",
    )

    @model_validator(mode="after")
    def _finite(self) -> OccupancyGridConfig:
        if not math.isfinite(self.cell_size_m):
            raise ValueError("cell_size_m must be finite")
        return self
