"""Belief-map plugin for hapticframe: ``contact-point`` sensor model and ``belief-map`` map.

Implementation modules load lazily, so importing the package stays light (no scikit-learn,
no matplotlib).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ._config import BeliefMapConfig, ContactPointConfig

if TYPE_CHECKING:
    from ._belief_map import BeliefMap
    from ._contact_point import ContactPoint

__all__ = ["BeliefMap", "BeliefMapConfig", "ContactPoint", "ContactPointConfig"]


def __getattr__(name: str) -> Any:
    if name == "BeliefMap":
        from ._belief_map import BeliefMap

        return BeliefMap
    if name == "ContactPoint":
        from ._contact_point import ContactPoint

        return ContactPoint
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
