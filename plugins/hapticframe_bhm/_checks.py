"""Checks of the Bayesian Hilbert map that ``validate`` runs (import-light: no numpy)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

from hapticframe import Finding, Size, ValidationContext

__all__ = ["check"]


def _ceil(value: float) -> float:
    """``math.ceil`` that keeps an infinite count (a spacing of 5e-324 m) infinite."""
    return float(math.ceil(value)) if math.isfinite(value) else value


#: Largest weight-vector length (the precision is a dense D x D matrix; _dense reads it here).
MAX_WEIGHTS = 5000
#: The thesis's 75 x 50 cm search area: the region when neither config nor scene gives one.
_DEFAULT_REGION = (0.0, 0.75, 0.0, 0.50)


def _hinges(low: float, high: float, spacing: float) -> float:
    """Hinges along one axis as hinge_axis places them: the span, both edges, one padding."""
    return max(1.0, _ceil((high - low) / spacing - 1e-9)) + 3.0


def _tile_sides(config: Any, hinges: float) -> tuple[float, float]:
    """(core, side): hinges along one axis of a tile's core and of the largest tile (as
    hapticframe_bhm._tiled lays them out)."""
    scale = config.length_scale_free_m
    if config.region_dependent_smoothing:
        scale = max(scale, config.length_scale_interaction_m)
    if config.automorphing_kernels:
        scale *= config.automorphing_range[1]
    # window_half_width of _windowed: features beyond it are below 1e-6.
    reach = max(0, _ceil(math.sqrt(-2.0 * math.log(1e-6)) * scale / config.hinge_spacing_m
                             - 0.5))
    if config.tile_size_m is None:
        core = max(1, 4 * reach)
    else:
        core = max(1, _ceil(config.tile_size_m / config.hinge_spacing_m - 0.5))
    return float(core), float(min(hinges, core + 4 * reach))


#: Dense D x D matrices a posterior holds at once while it is updated (precision, its
#: Cholesky factor, the update's product).
_DENSE_COPIES = 3
#: Arrays of (points x samples) a Monte Carlo std holds at once: activations and sigma(a).
_MC_COPIES = 2


def check(config: Any, context: ValidationContext) -> Iterator[Finding | Size]:
    """Refuse a hinge grid whose dense posterior, or whose tiles' posteriors, the map cannot
    hold; declare what the hinge grid and the Monte Carlo std allocate."""
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
    region = f"the {x1 - x0:.3g} x {y1 - y0:.3g} m region"
    if weights <= config.dense_weights_max:
        yield Size(
            "hinge_spacing_m",
            f"one dense posterior of {weights:.3g} weights over {region}",
            bytes=_DENSE_COPIES * 8.0 * weights * weights, iterations=weights,
            remedy="increase hinge_spacing_m",
        )
    else:
        (core_x, side_x), (core_y, side_y) = _tile_sides(config, nx), _tile_sides(config, ny)
        tile = side_x * side_y + int(config.bias)
        tiles = _ceil(nx / core_x) * _ceil(ny / core_y)
        if tile > MAX_WEIGHTS:
            gib = 8.0 * weights * weights / 2**30
            yield Finding(
                f"hinge spacing {spacing:g} m gives {weights:.3g} weights over {region} (a "
                f"{gib:.3g} GiB covariance), and tiles of {tile:.3g} weights; the limit is "
                f"{MAX_WEIGHTS} weights per dense posterior: increase hinge_spacing_m (or set "
                "a smaller tile_size_m)",
                field="hinge_spacing_m",
            )
        else:
            yield Size(
                "hinge_spacing_m",
                f"{tiles:.3g} tiles of {tile:.3g} weights each over {region}, when "
                "observations reach them all",
                bytes=8.0 * tiles * tile * tile + _DENSE_COPIES * 8.0 * tile * tile,
                iterations=tiles, remedy="increase hinge_spacing_m or tile_size_m",
            )
    samples = config.monte_carlo_samples if config.std_method == "monte_carlo" else 0
    points = context.query_grid_points(x1 - x0, y1 - y0)
    yield Size(
        "monte_carlo_samples",
        f"std_method {config.std_method}: {samples} weight samples at the {points:.4g} points of "
        "the run's largest map query (run.evaluation_spacing_m, run.snapshot_spacing_m)",
        bytes=8.0 * samples * (_MC_COPIES * points + min(weights, config.dense_weights_max)),
        remedy="lower monte_carlo_samples, use std_method: surrogate, or coarsen the run's "
        "evaluation and snapshot grids",
    )
