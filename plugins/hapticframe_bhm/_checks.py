"""Checks of the Bayesian Hilbert map that ``validate`` runs (import-light: no numpy)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

from hapticframe import Finding, ValidationContext

__all__ = ["check"]

#: Largest weight-vector length (the precision is a dense D x D matrix; _dense reads it here).
MAX_WEIGHTS = 5000
#: The thesis's 75 x 50 cm search area: the region when neither config nor scene gives one.
_DEFAULT_REGION = (0.0, 0.75, 0.0, 0.50)


def _hinges(low: float, high: float, spacing: float) -> float:
    """Hinges along one axis as hinge_axis places them: the span, both edges, one padding."""
    return max(1.0, math.ceil((high - low) / spacing - 1e-9)) + 3.0


def _tile_side(config: Any, hinges: float) -> float:
    """Hinges along one axis of the largest tile (as hapticframe_bhm._tiled lays them out)."""
    scale = config.length_scale_free_m
    if config.region_dependent_smoothing:
        scale = max(scale, config.length_scale_interaction_m)
    if config.automorphing_kernels:
        scale *= config.automorphing_range[1]
    # window_half_width of _windowed: features beyond it are below 1e-6.
    reach = max(0, math.ceil(math.sqrt(-2.0 * math.log(1e-6)) * scale / config.hinge_spacing_m
                             - 0.5))
    if config.tile_size_m is None:
        core = max(1, 4 * reach)
    else:
        core = max(1, round(config.tile_size_m / config.hinge_spacing_m))
    return float(min(hinges, core + 4 * reach))


def check(config: Any, context: ValidationContext) -> Iterator[Finding]:
    """Refuse a hinge grid whose dense posterior, or whose tiles' posteriors, the map cannot
    hold."""
    if config.region is not None:
        r = config.region
        x0, x1, y0, y1 = r.x_min_m, r.x_max_m, r.y_min_m, r.y_max_m
    elif context.scene is not None:
        r = context.scene.region
        x0, x1, y0, y1 = r.x_min_m, r.x_max_m, r.y_min_m, r.y_max_m
    else:
        x0, x1, y0, y1 = _DEFAULT_REGION
    spacing = config.hinge_spacing_m
    nx, ny = _hinges(x0, x1, spacing), _hinges(y0, y1, spacing)
    weights = nx * ny + int(config.bias)
    if weights <= config.dense_weights_max:
        return
    tile = _tile_side(config, nx) * _tile_side(config, ny) + int(config.bias)
    if tile > MAX_WEIGHTS:
        gib = 8.0 * weights * weights / 2**30
        yield Finding(
            f"hinge spacing {spacing:g} m gives {weights:.3g} weights over the "
            f"{x1 - x0:.3g} x {y1 - y0:.3g} m region (a {gib:.3g} GiB covariance), and tiles "
            f"of {tile:.3g} weights; the limit is {MAX_WEIGHTS} weights per dense posterior: "
            "increase hinge_spacing_m (or set a smaller tile_size_m)",
            field="hinge_spacing_m",
        )
