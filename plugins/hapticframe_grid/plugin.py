"""Registration of the ``occupancy-grid`` map (import-light: no numpy-heavy modules)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import Knob, MapSpec, hookimpl

from ._config import OccupancyGridConfig

__all__ = ["hapticframe_maps"]


@hookimpl
def hapticframe_maps() -> Iterator[MapSpec]:
    """Yield the log-odds occupancy grid spec."""
    yield MapSpec(
        name="occupancy-grid",
        summary="Log-odds occupancy grid with OctoMap's hit/miss/clamping constants.",
        config=OccupancyGridConfig,
        factory="hapticframe_grid._grid:OccupancyGrid",
        validator="hapticframe_grid._checks:check",
        capabilities=frozenset({"gridded", "exact-update"}),
        requires=("scipy",),
        install_hint="pip install hapticframe  (numpy and scipy); figures need matplotlib",
        knobs=(
            Knob("cell_size_m", "smaller cells: a finer outline, cells (memory and query "
                 "time) growing as 1/size²", values=(0.005, 0.01, 0.02, 0.04)),
        ),
    )
