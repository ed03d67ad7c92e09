"""Bayesian Hilbert map plugin for hapticframe (map type ``bayesian-hilbert-map``).

The implementation modules load lazily so that importing the package (for example to read
its config model) does not import scipy. Its timing benchmark is ``hapticframe bench bhm``
(``hapticframe_bench``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ._config import BayesianHilbertMapConfig

if TYPE_CHECKING:
    from ._map import BayesianHilbertMap

__all__ = ["BayesianHilbertMap", "BayesianHilbertMapConfig"]


def __getattr__(name: str) -> Any:
    if name == "BayesianHilbertMap":
        from ._map import BayesianHilbertMap

        return BayesianHilbertMap
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
