"""Gaussian-process occupancy map plugin for hapticframe (map type ``gp-occupancy``).

The baseline the thesis weighed Hilbert maps against: exact GP regression with a probit
link on small sets, inducing points on large ones. The implementation module loads lazily,
so importing the package stays light. ``hapticframe bench bhm`` times it beside the BHM.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hapticframe import lazy_exports

from ._config import GPOccupancyConfig

if TYPE_CHECKING:
    from ._map import GPOccupancyMap

__all__ = ["GPOccupancyConfig", "GPOccupancyMap"]

#: Public names that load on first use, and their modules.
_LAZY = {
    "GPOccupancyMap": "._map",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
