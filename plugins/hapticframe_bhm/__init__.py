"""Bayesian Hilbert map plugin for hapticframe (map type ``bayesian-hilbert-map``).

The implementation modules load lazily so that importing the package (for example to read
its config model) does not import scipy. Its timing benchmark is ``hapticframe bench bhm``
(``hapticframe_bench``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hapticframe import lazy_exports

from ._config import BayesianHilbertMapConfig

if TYPE_CHECKING:
    from ._map import BayesianHilbertMap

__all__ = ["BayesianHilbertMap", "BayesianHilbertMapConfig"]

#: Public names that load on first use, and their modules.
_LAZY = {
    "BayesianHilbertMap": "._map",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
