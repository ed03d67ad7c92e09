"""Configuration of the coverage planners (import-light: pydantic only)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from hapticframe import PluginConfig, RegionConfig

__all__ = ["CoverageConfig", "TwoPhaseCoverageConfig"]


class CoverageConfig(PluginConfig):
    """Parallel straight-line coverage of the search region, raked in plain order."""

    region: RegionConfig | None = Field(
        None,
        description="Search region; None takes the first input map's region, else the scene's.",
    )
    line_spacing_m: float = Field(
        0.035, gt=0,
        description="Distance between neighbouring parallel lines (3.5 cm: an 8 cm object is "
        "crossed by at least two lines).",
    )
    sweep_angle_deg: float | None = Field(
        None, ge=0, lt=180,
        description="Direction of the lines, degrees from +x; None runs them along the longer "
        "side of the region (fewest lines).",
    )
    speed_m_per_s: float = Field(0.05, gt=0, description="Commanded fingertip speed (5 cm/s).")
    depth_m: float | None = Field(
        None, ge=0, description="Commanded raking depth; None lets the robot keep its own."
    )
    free_class_names: tuple[str, ...] = Field(
        ("free",),
        description="Classifier classes meaning free movement; a movement whose final class is "
        "another one counts as an interaction even when the robot halted for its own reason.",
    )
    max_movements: int = Field(
        200, ge=1, description="Hard cap on the movements of one run."
    )


class TwoPhaseCoverageConfig(CoverageConfig):
    """The dissertation's two-phase strategy (section 3.4.4, Table 3.1)."""

    max_movements: int = Field(
        40, ge=1, description="Hard cap on all movements of one run (both phases)."
    )
    max_phase2_movements: int = Field(
        12, ge=0, description="Hard cap on phase-2 movements."
    )
    min_phase2_movements: int = Field(
        1, ge=0, description="Phase-2 movements made before the stopping rule is consulted."
    )
    phase2_line_spacing_m: float = Field(
        0.02, gt=0, description="Spacing of the phase-2 candidate lines."
    )
    region_shrink: float = Field(
        0.25, ge=0, lt=1,
        description="Fraction by which each side of the search region shrinks before every "
        "phase-2 movement.",
    )
    min_region_size_m: float = Field(
        0.10, gt=0, description="The shrinking region's sides never fall below this."
    )
    min_sweep_separation_deg: float = Field(
        30.0, ge=0, lt=90,
        description="A new sweep angle differs by at least this from the angles used before "
        "(modulo 180 degrees).",
    )
    occupancy_weight: float = Field(1.0, description="w1 of Eq. 3.9 (occupancy probability).")
    uncertainty_weight: float = Field(0.5, description="w2 of Eq. 3.9 (occupancy std).")
    distance_weight: float = Field(
        -1.0,
        description="w3 of Eq. 3.9 (squared distance to the centroid estimate, divided by the "
        "squared diagonal of the current region).",
    )
    centroid_level: float = Field(
        0.6, gt=0, lt=1, description="Occupancy level of the object blob (0.6 in the dissertation)."
    )
    grid_spacing_m: float = Field(
        0.01, gt=0, description="Grid spacing for sampling the map (centroid and stopping rule)."
    )
    score_step_m: float = Field(
        0.01, gt=0, description="Spacing of the points summed along a candidate line (Eq. 3.9)."
    )
    stop_rule: Literal["uncertain-area", "mean-std"] = Field(
        "uncertain-area",
        description="'uncertain-area': share of the current region whose std exceeds "
        "uncertain_std; 'mean-std': mean std over the region relative to 0.5.",
    )
    stop_fraction: float = Field(
        0.10, ge=0, le=1, description="λ: stop when the stop rule's fraction falls below it."
    )
    uncertain_std: float = Field(
        0.15, ge=0, le=0.5, description="Std above which a cell counts as uncertain."
    )
    map_id: str | None = Field(
        None, description="Id of the input map to read; None takes the first input map."
    )

    @model_validator(mode="after")
    def _consistent(self) -> TwoPhaseCoverageConfig:
        if self.min_phase2_movements > self.max_phase2_movements:
            raise ValueError("min_phase2_movements must not exceed max_phase2_movements")
        return self
