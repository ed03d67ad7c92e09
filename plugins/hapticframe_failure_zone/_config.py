"""Configuration of the failure-zone kernel sensor model (import-light: pydantic only)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from hapticframe import PluginConfig

__all__ = ["FailureZoneConfig"]

State = Literal["free", "jamming", "contact"]


def _same_named_states() -> dict[str, State]:
    """Each classifier class stands for the kernel state of the same name."""
    return {"free": "free", "jamming": "jamming", "contact": "contact"}


class FailureZoneConfig(PluginConfig):
    """Failure-zone kernel (dissertation Eqs. 3.2-3.4, Table 3.1).

    Three parameter schedules: ``"empirical"`` uses Table 3.1's γ_r = 1/(72·0.82ⁿ) cm⁻² and
    η = (50 + 7n)° (capped at 90°) with n the number of *pairs* of interacting movements so
    far, the sector range being the distance where the kernel halves, r = sqrt(ln 2/γ_r);
    ``"analytic"`` uses the rupture distance r = d(cot α + cot β), γ_r = ln 2/r² and the
    side-crescent formula η = asin((6.03 + 0.460 r + 0.0904 α)/r) (cm, degrees), whose
    argument is clipped to 1 (η = 90°) with a :class:`FailureZoneAngleWarning`; ``"hybrid"``
    (the default) takes r and γ_r as the analytic schedule and η from Table 3.1's line. The
    three mechanics formulas come from :mod:`hapticframe_granular`.

    The calibration fields below default to values measured against the force-rate
    classifier in the sandbox simulator; each names the dissertation's value, and the
    module docstring of :mod:`hapticframe_failure_zone._kernel` gives the measurements.
    """

    schedule: Literal["hybrid", "empirical", "analytic"] = Field(
        "hybrid",
        description="Parameter schedule: 'hybrid' (range from the rupture distance at the "
        "measured depth, side angle from Table 3.1's line), 'empirical' (Table 3.1, used for "
        "the dissertation's simulations) or 'analytic' (range and side angle from the rupture "
        "distance and the side-crescent formula).",
    )
    mixture: Literal["one-hot", "soft"] = Field(
        "one-hot",
        description="Mixture weights θ of Eq. 3.4: 'one-hot' uses the most probable state "
        "(the dissertation's binary Θ); 'soft' uses the class probabilities.",
    )
    class_states: dict[str, State] = Field(
        default_factory=_same_named_states,
        description="Kernel state ('free', 'jamming', 'contact') of each classifier class name; "
        "a classifier with classes ('free', 'contact') works unchanged.",
    )
    model_dir: str | None = Field(
        None,
        description="Directory written by the kernel's save() after fit() "
        "(failure_zone_fit.json) to load at build time: the fitted shear-band angle, "
        "sector half-angle and depth schedule replace the ones configured here.",
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
        description="Analytic and hybrid schedules: use the measurement's depth where it is "
        "finite; the depth schedule below fills in where it is NaN (or always, when False).",
    )
    initial_depth_m: float = Field(
        0.044, gt=0, le=0.3,
        description="Raking depth before any interaction (4.4 cm in the dissertation)."
    )
    depth_decrement_m: float = Field(
        0.01, ge=0, le=0.3, description="Depth removed after the first interacting movement (1 cm)."
    )
    depth_decrement_ratio: float = Field(
        0.5, ge=0, le=1,
        description="Each later decrement is this fraction of the previous one (1, 0.5, 0.25 cm).",
    )
    min_depth_m: float = Field(
        0.001, gt=0, le=0.3, description="Floor of the scheduled depth."
    )
    empirical_gamma_scale_cm2: float = Field(
        72.0, gt=0, le=1e6,
        description="Table 3.1: γ_r = 1/(scale · ratioⁿ) cm⁻²; the scale, in cm²."
    )
    empirical_gamma_ratio: float = Field(
        0.82, gt=0, le=10, description="Table 3.1: the per-pair ratio of γ_r's denominator."
    )
    empirical_eta_base_deg: float = Field(
        50.0,
        ge=0,
        le=90,
        description="Table 3.1: η = base + step · n, degrees; the base. η is capped at 90° "
        "(the failure zone lies ahead of the plate).",
    )
    empirical_eta_step_deg: float = Field(
        7.0, ge=0, le=90, description="Table 3.1: the per-pair increase of η, degrees."
    )
    # --- calibration against the classifier (module docstring of ._kernel); Eq. values ---
    free_range_scale: float = Field(
        0.85, gt=0, le=2,
        description="The free-movement sector reaches this fraction of the range r (Eqs. "
        "3.2-3.4: 1). Free movement shows that nothing lies nearer than where jamming would be "
        "detected (about 0.7 r ahead), not that the whole failure zone is empty.",
    )
    free_gamma_scale: float = Field(
        0.04, gt=0, le=100,
        description="Multiplier of γ_r in the free kernel (Eq. 3.3: 1). Below 1 the free "
        "targets stay near 0 across the free sector instead of rising to 1/2 at its end.",
    )
    jamming_shape: Literal["disc", "sector"] = Field(
        "disc",
        description="Region a jamming sample speaks about: 'sector' (Eq. 3.2: the failure "
        "zone from jamming_inner_scale to jamming_range_scale of r, within "
        "jamming_angle_scale of η) or 'disc' (a disc of jamming_disc_radius_m straight "
        "ahead whose near edge lies jamming_disc_offset_scale of r ahead: the object met "
        "is taken to curve away from the point met, as a convex object does).",
    )
    jamming_disc_offset_scale: float = Field(
        0.45, ge=0, le=3,
        description="'disc' jamming region: its near edge lies this fraction of r ahead.",
    )
    jamming_disc_radius_m: float = Field(
        0.036, gt=0, le=0.5, description="'disc' jamming region: its radius."
    )
    jamming_inner_scale: float = Field(
        0.0, ge=0, le=2,
        description="'sector' jamming region: it starts at this fraction of r (Eq. 3.2: 0).",
    )
    jamming_range_scale: float = Field(
        1.0, gt=0, le=3,
        description="'sector' jamming region: it reaches this fraction of r (Eq. 3.2: 1); the "
        "kernel keeps γ_r of the range r and is clipped at 1 beyond it.",
    )
    jamming_angle_scale: float = Field(
        1.0, gt=0, le=1,
        description="'sector' jamming region: it spans this fraction of η (Eq. 3.2: 1).",
    )
    interaction_weight: float = Field(
        1.0, gt=0, le=1e3,
        description="Weight of every jamming and contact observation relative to free ones "
        "(Eq. 3.4: 1).",
    )
    first_pair_weight: float = Field(
        0.5, gt=0, le=1,
        description="Further factor on the jamming and contact weights while n = 0 (before "
        "the first pair of interacting movements; Eq. 3.4: 1). The first pair comes from "
        "phase-1 lines, which pass the object at an unknown offset, so where they place the "
        "object is less certain than later, aimed movements.",
    )
    min_range_m: float = Field(
        0.002, gt=0, le=10.0, description="Smallest sector range (guards a vanishing depth)."
    )
    max_range_m: float = Field(
        0.25, gt=0, le=10.0, description="Largest sector range (bounds the points of a huge depth)."
    )
    sector_spacing_m: float = Field(
        0.015, gt=0,
        le=1.0,
        description="Spacing of the polar grids of sector and disc points (rings and arcs); "
        "1.5 cm is a third of the map's 5 cm hinge spacing.",
    )
    observation_spacing_m: float = Field(
        0.02, ge=0,
        le=10.0,
        description="Emit a sector only every this much fingertip travel (0: every sample); "
        "the first sample of a movement and every change of state are always emitted. 2 cm: "
        "consecutive free sectors (6 cm long at the full depth) still overlap threefold.",
    )

    @model_validator(mode="after")
    def _consistent(self) -> FailureZoneConfig:
        if self.max_range_m < self.min_range_m:
            raise ValueError("max_range_m must be at least min_range_m")
        if self.jamming_inner_scale > self.jamming_range_scale:
            raise ValueError("jamming_inner_scale must not exceed jamming_range_scale")
        if not self.class_states:
            raise ValueError("class_states must name at least one class")
        if "free" not in self.class_states.values():
            raise ValueError("class_states must map some class to 'free'")
        return self
