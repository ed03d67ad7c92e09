"""Belief-map plugin for hapticframe: ``contact-point`` sensor model and ``belief-map`` map.

Implementation modules load lazily, so importing the package stays light (no scikit-learn,
no matplotlib).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hapticframe import lazy_exports

from ._config import BeliefMapConfig, ContactPointConfig

if TYPE_CHECKING:
    from ._belief_map import BeliefMap
    from ._contact_point import ContactPoint

__all__ = ["BeliefMap", "BeliefMapConfig", "ContactPoint", "ContactPointConfig"]

#: Public names that load on first use, and their modules.
_LAZY = {
    "BeliefMap": "._belief_map",
    "ContactPoint": "._contact_point",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
