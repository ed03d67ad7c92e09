"""Configuration of the failure-zone kernel sensor model (import-light: pydantic only)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from hapticframe import PluginConfig

__all__ = ["FailureZoneConfig"]

State = Literal["free", "jamming", "contact"]


class FailureZoneConfig(PluginConfig):
    """Failure-zone kernel (dissertation Eqs. 3.2-3.4, Table 3.1).

    Two parameter schedules: ``"empirical"`` uses Table 3.1's γ_r = 1/(72·0.82ⁿ) cm⁻² and
    η = (50 + 7n)° with n the number of *pairs* of interacting movements so far, the sector
    range being the distance where the kernel halves, r = sqrt(ln 2/γ_r); ``"analytic"``
    uses the rupture distance r = d(cot α + cot β), γ_r = ln 2/r² and the side-crescent
    formula η = asin((6.03 + 0.460 r + 0.0904 α)/r) (cm, degrees), whose argument is
    clipped to [−1, 1] with a :class:`FailureZoneAngleWarning`.
    """

    schedule: Literal["empirical", "analytic"] = Field(
        "empirical",
        description="Parameter schedule: 'empirical' (Table 3.1, used for the dissertation's "
        "simulations) or 'analytic' (rupture distance from depth and shear-band angle).",
    )
    mixture: Literal["one-hot", "soft"] = Field(
        "one-hot",
        description="Mixture weights θ of Eq. 3.4: 'one-hot' uses the most probable state "
        "(the dissertation's binary Θ); 'soft' uses the class probabilities.",
    )
    class_states: dict[str, State] = Field(
        default_factory=lambda: {"free": "free", "jamming": "jamming", "contact": "contact"},
        description="Kernel state ('free', 'jamming', 'contact') of each classifier class name; "
        "a classifier with classes ('free', 'contact') works unchanged.",
    )
    rake_angle_deg: float = Field(
        90.0, gt=0, lt=180,
        description="Angle α of the fingertip to the free surface, degrees (90: vertical raking).",
    )
    shear_band_angle_deg: float | None = Field(
        None, gt=0, lt=90,
        description="Shear-band angle β, degrees; None takes the scene material's Arthur angle, "
        "or 31.5 (φ = 42°, ψ = 12°) without a scene.",
    )
    use_measured_depth: bool = Field(
        True,
        description="Analytic schedule: use the measurement's depth where it is finite; the "
        "depth schedule below fills in where it is NaN (or always, when False).",
    )
    initial_depth_m: float = Field(
        0.044, gt=0, description="Raking depth before any interaction (4.4 cm in the dissertation)."
    )
    depth_decrement_m: float = Field(
        0.01, ge=0, description="Depth removed after the first interacting movement (1 cm)."
    )
    depth_decrement_ratio: float = Field(
        0.5, ge=0, le=1,
        description="Each later decrement is this fraction of the previous one (1, 0.5, 0.25 cm).",
    )
    min_depth_m: float = Field(
        0.001, gt=0, description="Floor of the scheduled depth."
    )
    empirical_gamma_scale_cm2: float = Field(
        72.0, gt=0, description="Table 3.1: γ_r = 1/(scale · ratioⁿ) cm⁻²; the scale, in cm²."
    )
    empirical_gamma_ratio: float = Field(
        0.82, gt=0, description="Table 3.1: the per-pair ratio of γ_r's denominator."
    )
    empirical_eta_base_deg: float = Field(
        50.0, ge=0, le=180, description="Table 3.1: η = base + step · n, degrees; the base."
    )
    empirical_eta_step_deg: float = Field(
        7.0, ge=0, description="Table 3.1: the per-pair increase of η, degrees."
    )
    min_range_m: float = Field(
        0.002, gt=0, description="Smallest sector range (guards a vanishing depth)."
    )
    max_range_m: float = Field(
        0.25, gt=0, description="Largest sector range (bounds the points of a huge depth)."
    )
    sector_spacing_m: float = Field(
        0.01, gt=0, description="Spacing of the polar grid of sector points (rings and arcs)."
    )
    observation_spacing_m: float = Field(
        0.01, ge=0,
        description="Emit a sector only every this much fingertip travel (0: every sample); "
        "the first sample of a movement and every change of state are always emitted.",
    )

    @model_validator(mode="after")
    def _consistent(self) -> FailureZoneConfig:
        if self.max_range_m < self.min_range_m:
            raise ValueError("max_range_m must be at least min_range_m")
        if not self.class_states:
            raise ValueError("class_states must name at least one class")
        if "free" not in self.class_states.values():
            raise ValueError("class_states must map some class to 'free'")
        return self
