"""Coverage planners for haptic search: the two-phase strategy and a boustrophedon baseline.

``two-phase-coverage`` follows Jia (2022), section 3.4.4: binary-search coverage lines until
the first interaction, the same line from the opposite side, then next-best lines chosen on
the occupancy map (Eq. 3.9) in a shrinking region. ``coverage`` rakes every line in order.
Implementations are imported on first use, so importing this package stays light.
"""

from __future__ import annotations

from typing import Any

from ._config import CoverageConfig, TwoPhaseCoverageConfig

__all__ = ["BoustrophedonCoverage", "CoverageConfig", "TwoPhaseCoverage", "TwoPhaseCoverageConfig"]


def __getattr__(name: str) -> Any:
    if name == "TwoPhaseCoverage":
        from ._two_phase import TwoPhaseCoverage

        return TwoPhaseCoverage
    if name == "BoustrophedonCoverage":
        from ._coverage import BoustrophedonCoverage

        return BoustrophedonCoverage
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
