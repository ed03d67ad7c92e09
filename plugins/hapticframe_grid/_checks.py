"""Checks of the occupancy grid that ``validate`` runs (import-light: no numpy)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

from hapticframe import Finding, Size, ValidationContext

__all__ = ["check"]


def _ceil(value: float) -> float:
    """``math.ceil`` that keeps an infinite count (a spacing of 5e-324 m) infinite."""
    return float(math.ceil(value)) if math.isfinite(value) else value

#: Most cells of one grid (as _grid refuses at build: 8 bytes each, 400 MB).
MAX_CELLS = 50_000_000
#: The thesis's 75 x 50 cm search area: the region when neither config nor scene gives one.
_DEFAULT_SIZE = (0.75, 0.50)


def check(config: Any, context: ValidationContext) -> Iterator[Finding | Size]:
    """Refuse a cell size that gives more cells than the grid may hold; declare its size."""
    region = config.region if config.region is not None else getattr(context.scene, "region", None)
    if region is None:
        width, height = _DEFAULT_SIZE
    else:
        width, height = region.x_max_m - region.x_min_m, region.y_max_m - region.y_min_m
    size = config.cell_size_m
    cells = max(1, _ceil(width / size - 1e-9)) * max(1, _ceil(height / size - 1e-9))
    yield Size("cell_size_m", f"{cells:.3g} cells of log-odds over the {width:.3g} x "
               f"{height:.3g} m region", bytes=8.0 * cells, iterations=cells,
               remedy="increase cell_size_m")
    if cells > MAX_CELLS:
        yield Finding(
            f"cell size {size:g} m gives {cells:.3g} cells over the {width:.3g} x {height:.3g} m "
            f"region ({8.0 * cells / 2**30:.3g} GiB); the limit is {MAX_CELLS:.0e} cells: "
            "increase cell_size_m",
            field="cell_size_m",
        )
