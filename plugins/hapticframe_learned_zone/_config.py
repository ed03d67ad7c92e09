"""Configuration of the learned-zone sensor model (import-light: pydantic only)."""

from __future__ import annotations

from itertools import pairwise
from typing import Literal

from pydantic import Field, model_validator

from hapticframe import PluginConfig

__all__ = ["LearnedZoneConfig"]


class LearnedZoneConfig(PluginConfig):
    """Learned zone: what the classifier reports, as a function of where the object lies
    relative to the plate, learned from calibration recordings (issue 32 §2).

    ``hapticframe train`` fits it on the runs of ``run.calibration_runs`` and saves the
    counts into ``DIR/<id>/learned_zone.json``; ``model_dir`` loads them. Without
    ``model_dir`` the model shipped with the plugin is used: learned in the analytic
    sandbox (``data/SOURCE.md`` says how). The cell grid and depth bands below are used by
    ``fit``; a loaded model keeps the grid it was fitted on (saved with it).
    """

    model_dir: str | None = Field(
        None,
        description="Directory `hapticframe train` wrote for this sensor model "
        "(learned_zone.json); None: the model learned in the analytic sandbox that ships "
        "with the plugin.",
    )
    mixture: Literal["one-hot", "soft"] = Field(
        "one-hot",
        description="What a report is: 'one-hot' its most probable class (as the "
        "failure-zone kernel's default, and as the run's halt reads it), in the fit and in "
        "the search; 'soft' its class probabilities as a mixture (only for a classifier "
        "whose probabilities are calibrated: drag-ratio-jamming reports jamming at 0.6).",
    )
    ahead_min_m: float = Field(
        -0.03, ge=-0.5, le=0.0,
        description="fit: the cell grid starts this far ahead of the plate (negative: behind).")
    ahead_max_m: float = Field(
        0.12, gt=0.0, le=0.5, description="fit: the cell grid ends this far ahead of the plate.")
    aside_max_m: float = Field(
        0.08, gt=0.0, le=0.5,
        description="fit: the cell grid reaches this far to each side of the plate's path.")
    cell_m: float = Field(0.01, ge=0.002, le=0.1, description="fit: cell size of the grid.")
    depth_edges_m: list[float] = Field(
        default_factory=lambda: [0.0245, 0.0315, 0.039], max_length=32,
        description="fit: interior edges of the depth bands, increasing (the defaults "
        "separate the depth schedule's 2.0, 2.9, 3.4 and 4.4 cm). A band without samples "
        "borrows the table pooled over all depths.",
    )
    fit_spacing_m: float = Field(
        0.005, gt=0.0, le=0.1,
        description="fit: one sample counted per this much travel, so that a slow or "
        "stopped plate does not outweigh a moving one.",
    )
    onset_travel_m: float = Field(
        0.01, ge=0.0, le=1.0,
        description="fit: each calibration movement counts up to this much travel past its "
        "first report of a class other than the background (free), as a search halts there.",
    )
    prior_strength: float = Field(
        4.0, gt=0.0, le=1e6,
        description="Beta pseudo-counts shrinking each cell's occupancy rate per report "
        "towards coarser evidence (a depth band's towards all depths', a class's towards "
        "the cell's base rate): a cell seen less often than this says little.",
    )
    depth_prior_strength: float = Field(
        30.0, gt=0.0, le=1e6,
        description="Beta pseudo-counts shrinking a depth band's rates towards those pooled "
        "over all depths: a band needs about this many reports of a class before its own "
        "rates dominate (a calibration run has one or two movements per depth).",
    )
    observation_spacing_m: float = Field(
        0.02, ge=0.0, le=0.5,
        description="A report is placed on the map every this much travel, and whenever "
        "the reported class changes (0: every sample).",
    )
    background_likelihood: Literal["shrunk", "survival"] = Field(
        "shrunk",
        description="A report of the background class (the first, 'free'): 'shrunk' its "
        "likelihoods per cell and depth band as every class's; 'survival' p(background | "
        "occupied) shrunk along the plate's heading towards the cells farther ahead, never "
        "rising as the object nears (depths pooled): the cells nearest the plate and those "
        "it passed, rarely seen occupied because a search halts, are cleared at least as "
        "surely as the nearest seen (docs/calibration.md, 'The sandbox's blurred "
        "outlines').",
    )
    min_log_ratio: float = Field(
        0.2, ge=0.0, le=20.0,
        description="Cells whose log odds the report changes by less than this (its log "
        "likelihood ratio) are not emitted: the report says too little about them.",
    )
    full_weight_log_ratio: float = Field(
        2.0, gt=0.0, le=50.0,
        description="A cell's weight grows with the size of its log likelihood ratio up to "
        "1 at this value, times the share of its rate that its own samples carry.",
    )

    @model_validator(mode="after")
    def _check(self) -> LearnedZoneConfig:
        edges = self.depth_edges_m
        if any(not 0.0 < e < 1.0 for e in edges) or any(b <= a for a, b in pairwise(edges)):
            raise ValueError("depth_edges_m must increase strictly within (0, 1) m")
        if self.ahead_max_m - self.ahead_min_m < self.cell_m:
            raise ValueError("the grid (ahead_min_m .. ahead_max_m) must hold one cell")
        return self
