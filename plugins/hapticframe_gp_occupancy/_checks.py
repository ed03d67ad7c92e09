"""Checks of the GP occupancy map that ``validate`` runs (import-light: no numpy)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

from hapticframe import Finding, Size, ValidationContext

__all__ = ["check", "inducing_count"]


def _ceil(value: float) -> float:
    """``math.ceil`` that keeps an infinite count (a spacing of 5e-324 m) infinite."""
    return float(math.ceil(value)) if math.isfinite(value) else value

#: The thesis's 75 x 50 cm search area: the region when neither config nor scene gives one.
_DEFAULT_REGION = (0.0, 0.75, 0.0, 0.50)


def inducing_count(width_m: float, height_m: float, spacing_m: float) -> float:
    """Inducing points of a ``width x height`` region (as _functional.inducing_grid)."""
    nx = max(1, _ceil(width_m / spacing_m - 1e-9)) + 1
    ny = max(1, _ceil(height_m / spacing_m - 1e-9)) + 1
    return nx * ny


#: Dense matrices of the kernel's size a fit holds at once (the kernel, its Cholesky
#: factor, a solve's product).
_DENSE_COPIES = 3


def check(config: Any, context: ValidationContext) -> Iterator[Finding | Size]:
    """Refuse an inducing grid larger than ``max_inducing_points``; declare the dense
    matrices of the exact and the inducing fits."""
    n = config.exact_max_observations if config.method != "inducing" else 0
    yield Size("exact_max_observations",
               f"the exact fit's {n} x {n} kernel matrices", bytes=_DENSE_COPIES * 8.0 * n * n,
               remedy="lower exact_max_observations (method auto then switches to inducing "
               "points sooner)")
    m = config.max_inducing_points if config.method != "exact" else 0
    yield Size("max_inducing_points", f"the inducing fit's {m} x {m} matrices",
               bytes=_DENSE_COPIES * 8.0 * m * m, remedy="lower max_inducing_points")
    if config.method == "exact":
        return
    if config.region is not None:
        r = config.region
        x0, x1, y0, y1 = r.x_min_m, r.x_max_m, r.y_min_m, r.y_max_m
    elif context.scene is not None:
        r = context.scene.region
        x0, x1, y0, y1 = r.x_min_m, r.x_max_m, r.y_min_m, r.y_max_m
    else:
        x0, x1, y0, y1 = _DEFAULT_REGION
    count = inducing_count(x1 - x0, y1 - y0, config.inducing_spacing_m)
    if count > config.max_inducing_points:
        yield Finding(
            f"inducing spacing {config.inducing_spacing_m:g} m gives {count:.4g} inducing points "
            f"over the {x1 - x0:.3g} x {y1 - y0:.3g} m region; the limit is "
            f"max_inducing_points ({config.max_inducing_points}): increase inducing_spacing_m",
            field="inducing_spacing_m",
        )
