"""Log-odds occupancy grid plugin for hapticframe (map type ``occupancy-grid``).

The implementation module loads lazily, so importing the package stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ._config import OccupancyGridConfig

if TYPE_CHECKING:
    from ._grid import OccupancyGrid

__all__ = ["OccupancyGrid", "OccupancyGridConfig"]


def __getattr__(name: str) -> Any:
    if name == "OccupancyGrid":
        from ._grid import OccupancyGrid

        return OccupancyGrid
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
