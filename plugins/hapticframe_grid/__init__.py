"""Log-odds occupancy grid plugin for hapticframe (map type ``occupancy-grid``).

The implementation module loads lazily, so importing the package stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hapticframe import lazy_exports

from ._config import OccupancyGridConfig

if TYPE_CHECKING:
    from ._grid import OccupancyGrid

__all__ = ["OccupancyGrid", "OccupancyGridConfig"]

#: Public names that load on first use, and their modules.
_LAZY = {
    "OccupancyGrid": "._grid",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
