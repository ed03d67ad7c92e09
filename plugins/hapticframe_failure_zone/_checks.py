"""Checks of the failure-zone kernel that ``validate`` runs (import-light: no numpy)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

from hapticframe import Finding, Kind, Size, ValidationContext

__all__ = ["check"]

#: Most points of one sector or disc (each observation holds them as float64 rows).
MAX_SECTOR_POINTS = 200_000


def check(config: Any, context: ValidationContext) -> Iterator[Finding | Size]:
    """Refuse a kernel without a robot or a classifier, and a sector grid too fine to hold."""
    kinds = {view.kind for view in context.inputs.values()}
    if Kind.ROBOT not in kinds:
        yield Finding(
            "the failure-zone kernel places each sector at the fingertip's position and "
            f"heading, which a robot reports: add a robot to its inputs (it has "
            f"{list(context.inputs) or 'none'})",
        )
    if Kind.CLASSIFIER not in kinds:
        yield Finding(
            "the failure-zone kernel turns a classifier's states into observations: add a "
            "classifier to its inputs",
        )
    # A disc of the largest range holds every sector and jamming disc the kernel builds.
    reach = config.max_range_m * max(1.0, config.jamming_range_scale, config.free_range_scale)
    reach = max(reach, config.jamming_disc_radius_m)
    points = math.pi * (reach / config.sector_spacing_m + 1.0) ** 2
    # One sector per sample of a batch at worst (observation_spacing_m 0); a batch holds up
    # to run.lookahead_steps samples.
    batch = max(1, int(getattr(context.run, "lookahead_steps", 1)))
    yield Size("sector_spacing_m",
               f"sectors of up to {points:.3g} points over the {reach:g} m range, for each of "
               f"up to {batch} samples of a batch", bytes=32.0 * points * batch,
               iterations=points * batch, remedy="increase sector_spacing_m")
    if points > MAX_SECTOR_POINTS:
        yield Finding(
            f"sector spacing {config.sector_spacing_m:g} m gives up to {points:.3g} points per "
            f"observation over the {reach:g} m range; the limit is {MAX_SECTOR_POINTS:.0e}: "
            "increase sector_spacing_m",
            field="sector_spacing_m",
        )
