"""Coverage planners for haptic search: the two-phase strategy and a boustrophedon baseline.

``two-phase-coverage`` follows Jia (2022), section 3.4.4: binary-search coverage lines until
the first interaction, the same line from the opposite side, then next-best lines chosen on
the occupancy map (Eq. 3.9) in a shrinking region. ``coverage`` rakes every line in order.
Implementations are imported on first use, so importing this package stays light.
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import CoverageConfig, TwoPhaseCoverageConfig

__all__ = ["BoustrophedonCoverage", "CoverageConfig", "TwoPhaseCoverage", "TwoPhaseCoverageConfig"]

#: Public names that load on first use, and their modules.
_LAZY = {
    "TwoPhaseCoverage": "._two_phase",
    "BoustrophedonCoverage": "._coverage",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
