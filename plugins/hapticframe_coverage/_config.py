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
        le=10.0,
        description="Distance between neighbouring parallel lines (3.5 cm: an 8 cm object is "
        "crossed by at least two lines).",
    )
    sweep_angle_deg: float | None = Field(
        None, ge=0, lt=180,
        description="Direction of the lines, degrees from +x; None runs them along the longer "
        "side of the region (fewest lines).",
    )
    speed_m_per_s: float = Field(
        0.05, ge=1e-4, le=2.0,
        description="Commanded fingertip speed (5 cm/s).",
    )
    depth_m: float | None = Field(
        None, gt=0, le=0.3,
        description="Commanded raking depth (positive); None lets the robot keep its own.",
    )
    free_class_names: tuple[str, ...] = Field(
        ("free",),
        description="Classifier classes meaning free movement; a movement whose final class is "
        "another one counts as an interaction even when the robot halted for its own reason.",
    )
    max_movements: int = Field(
        200, ge=1, le=10_000, description="Hard cap on the movements of one run."
    )


class TwoPhaseCoverageConfig(CoverageConfig):
    """The dissertation's two-phase strategy (section 3.4.4, Table 3.1)."""

    line_spacing_m: float = Field(
        0.10, gt=0,
        le=10.0,
        description="Distance between neighbouring phase-1 lines. 10 cm: at the full raking "
        "depth the classifier detects an object whose outline passes within about 2.5 cm of "
        "the fingertip's path (more for a head-on approach), so a 9 x 5 cm ellipse (5 cm "
        "across) or an 8 cm circle within 5 cm of a line is always found.",
    )
    max_movements: int = Field(
        40, ge=1, le=10_000, description="Hard cap on all movements of one run (both phases)."
    )
    phase1_order: Literal["outer-last", "binary"] = Field(
        "outer-last",
        description="Order of the phase-1 lines: 'binary' (the middle line, then the quarters, "
        "the eighths...; the dissertation's binary search) or 'outer-last' (the same with the "
        "two lines nearest the region's edges raked last: a buried object is less often "
        "centred there).",
    )
    phase1_reverse: bool = Field(
        True,
        description="Rake the first interacting phase-1 line again from its far end before "
        "phase 2 (the dissertation). False starts phase 2 at once: one movement and one "
        "object interaction fewer, the object's far side left to phase 2.",
    )
    reverse_confirms: bool = Field(
        False,
        description="With phase1_reverse: a reverse pass that meets nothing where the first "
        "pass met something marks that report a false alarm; its interaction is dropped and "
        "phase 1 goes on with the next line (the map keeps the evidence). False: phase 2 "
        "starts after the reverse pass whatever it met (the dissertation).",
    )
    phase1_second_pass: Literal["none", "between", "across"] = Field(
        "none",
        description="When every phase-1 line was raked without an interaction, rake a second "
        "set before giving up: 'between' the lines midway between the first ones (same "
        "direction, one fewer: the spacing halves), 'across' the lines at right angles "
        "(same spacing). An object narrower than the gap, lying between two lines, is then "
        "met. 'none': the search ends (the dissertation).",
    )
    stop_short_m: float | None = Field(
        None, gt=0, le=1.0,
        description="Once the object was met stop_short_after times, each phase-2 movement "
        "ends this far before the map's outline estimate (its centroid_level curve around "
        "the centroid estimate) instead of raking through: with the failure zone's reach "
        "after those interactions (the rupture distance, about 4.7 cm after two at the "
        "sandbox's default depths) below it, the movement does not touch the object, and "
        "its free-movement evidence carves the outline from outside. Such a movement "
        "counts as an approach from its side for the 'angular-gap' stop rule. None: every "
        "movement rakes to the region's edge or until halted.",
    )
    stop_short_after: int = Field(
        2, ge=0, le=1000,
        description="Object interactions (in this object's search) after which phase-2 "
        "movements stop short (stop_short_m).",
    )
    max_phase2_movements: int = Field(
        12, ge=0, le=10_000, description="Hard cap on phase-2 movements."
    )
    min_phase2_movements: int = Field(
        1, ge=0, le=10_000,
        description="Phase-2 movements made before the stopping rule is consulted."
    )
    phase2_line_spacing_m: float = Field(
        0.02, gt=0, le=10.0, description="Spacing of the phase-2 candidate lines."
    )
    phase2_region_size_m: float | None = Field(
        0.32, gt=0,
        le=100.0, description="Side of the first phase-2 region, a square centred on the centroid "
        "estimate and kept inside the search region; None starts from the whole search "
        "region (the dissertation). A line then starts at most half this side from the "
        "object, far enough to be outside the failure zone.",
    )
    region_shrink: float = Field(
        0.25, ge=0, lt=1,
        description="Fraction by which each side of the search region shrinks before every "
        "phase-2 movement.",
    )
    min_region_size_m: float = Field(
        0.26, gt=0,
        le=100.0, description="The shrinking region's sides never fall below this (26 cm: a line "
        "through the centroid estimate starts at least 13 cm from it, outside the failure "
        "zone, about 7 cm deep, of an object reaching up to 4.5 cm from its centre).",
    )
    min_sweep_separation_deg: float = Field(
        30.0, ge=0, lt=90,
        description="A new sweep angle differs by at least this from the angles used before "
        "(modulo 180 degrees).",
    )
    sweep_rule: Literal["widest-gap", "random"] = Field(
        "widest-gap",
        description="'random': a uniformly random sweep angle at least min_sweep_separation_deg "
        "from those used before, the line raked from its low-occupancy end (the "
        "dissertation); 'widest-gap': the approach direction that faces the widest "
        "unexplored side of the object (largest angular gap between the directions the "
        "object was met from), subject to the same separation, raked from that side.",
    )
    met_from: Literal["heading", "stop-point"] = Field(
        "stop-point",
        description="How the direction an interacting movement met the object from is taken: "
        "'heading' (opposite to its direction of motion) or 'stop-point' (the direction "
        "from the centroid estimate to where it stopped, which also tells a line passing "
        "beside the centre).",
    )
    gap_step_deg: float = Field(
        5.0, gt=0, le=45,
        description="Resolution of the approach directions tried by the 'widest-gap' rule.",
    )
    min_start_distance_m: float = Field(
        0.12, ge=0,
        le=10.0,
        description="'widest-gap' rule: skip approach directions whose line would start nearer "
        "than this to the centroid estimate (inside the failure zone of the object, e.g. when "
        "it lies near the region's edge); ignored when no direction qualifies.",
    )
    occupancy_weight: float = Field(
        1.0, ge=-1e3, le=1e3,
        description="w1 of Eq. 3.9 (occupancy probability).",
    )
    uncertainty_weight: float = Field(
        0.5, ge=-1e3, le=1e3,
        description="w2 of Eq. 3.9 (occupancy std).",
    )
    distance_weight: float = Field(
        -1.0,
        ge=-1e3, le=1e3,
        description="w3 of Eq. 3.9 (squared distance to the centroid estimate, divided by the "
        "squared diagonal of the current region).",
    )
    centroid_level: float = Field(
        0.6, gt=0, lt=1, description="Occupancy level of the object blob (0.6 in the dissertation)."
    )
    grid_spacing_m: float = Field(
        0.01, gt=0, le=1.0,
        description="Grid spacing for sampling the map (centroid and stopping rule)."
    )
    score_step_m: float = Field(
        0.01, gt=0, le=1.0,
        description="Spacing of the points summed along a candidate line (Eq. 3.9)."
    )
    stop_rule: Literal["angular-gap", "uncertain-area", "mean-std"] = Field(
        "angular-gap",
        description="'angular-gap': stop once the directions the object was met from leave "
        "no gap wider than max_gap_deg; 'uncertain-area': share of the current region whose "
        "std exceeds uncertain_std (the dissertation's λ rule); 'mean-std': mean std over the "
        "region relative to 0.5.",
    )
    max_gap_deg: float = Field(
        110.0, gt=0, le=360,
        description="'angular-gap' rule: the largest allowed gap between the directions "
        "(seen from the object) of the movements that met it.",
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
    max_objects: int | None = Field(
        1, ge=1, le=1000,
        description="Objects to localise before the search ends. After an object's phase 2 "
        "stops, the remaining phase-1 lines are raked outside the found objects (their "
        "outlines dilated by found_margin_m) and the next interaction starts a new two-phase "
        "search. None: until the phase-1 lines are exhausted (every object in the region). "
        "1 (the dissertation): stop after the first object.",
    )
    found_margin_m: float = Field(
        0.05, ge=0, le=1.0,
        description="Dilation of a found object's outline (the 0.6 level curve of the map, else "
        "a disc through its interaction points) that later movements keep out of; an "
        "interaction stopping within twice this of a found object counts as meeting it again.",
    )
    min_segment_m: float = Field(
        0.05, gt=0, le=10.0,
        description="Shortest part of a line left between found objects that is still raked.",
    )

    @model_validator(mode="after")
    def _consistent(self) -> TwoPhaseCoverageConfig:
        if self.min_phase2_movements > self.max_phase2_movements:
            raise ValueError("min_phase2_movements must not exceed max_phase2_movements")
        return self
