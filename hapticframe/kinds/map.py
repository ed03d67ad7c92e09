"""Map interface: occupancy with uncertainty, queryable at arbitrary points.

Contract
--------
- :meth:`Map.update` fuses observations (streaming); :meth:`Map.fit` forgets everything and
  fuses one batch. Updating with consecutive parts gives a map close to fitting the union
  (exactly equal for maps whose update is exact, such as log-odds grids).
- :meth:`Map.query` returns a :class:`MapEstimate` for any ``(q, 2)`` float array of points
  in metres, including points outside :attr:`Map.region` and an empty array. Before any
  update the mean is the prior (0.5 for an uninformed map).

What the base does (template method)
------------------------------------
:meth:`Map.query` turns the points into a float64 ``(q, 2)`` array (one point ``(2,)`` is one
row), refuses any other shape and NaN or infinity with ``ValueError``, answers an empty query
itself, and calls the plugin's :meth:`Map._query` with the checked, non-empty array.
"""

from __future__ import annotations

from abc import abstractmethod
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hapticframe._kind import Kind
from hapticframe.kinds._base import Component
from hapticframe.kinds._records import MapEstimate, Observations, Region

__all__ = ["Map", "query_points"]


class Map(Component):
    """A continuous or gridded occupancy map of the search region."""

    kind: ClassVar[Kind] = Kind.MAP

    @property
    @abstractmethod
    def region(self) -> Region:
        """The mapped region."""

    @abstractmethod
    def update(self, observations: Observations) -> None:
        """Fuse new observations into the map."""

    def fit(self, observations: Observations) -> None:
        """Forget previous observations and fuse ``observations`` (batch use)."""
        self.reset()
        self.update(observations)

    def query(self, points_m: ArrayLike) -> MapEstimate:
        """Occupancy probability and its standard deviation at ``points_m`` (q, 2).

        Checks the points (:func:`query_points`), then calls :meth:`_query`.
        """
        points = query_points(points_m)
        if points.shape[0] == 0:
            return MapEstimate(np.empty(0), np.empty(0))
        return self._query(points)

    def _query(self, points_m: NDArray[np.float64]) -> MapEstimate:
        """The estimate at ``points_m``: a finite float64 ``(q, 2)`` array, ``q >= 1``.

        The plugin's hook behind :meth:`query`; a map overrides this (or :meth:`query`).
        """
        raise NotImplementedError(f"{type(self).__name__} must override Map._query")


def query_points(points_m: ArrayLike) -> NDArray[np.float64]:
    """``points_m`` as a float64 ``(q, 2)`` array (one point ``(2,)`` becomes one row; any
    empty input ``(0, 2)``); ``ValueError`` for another shape, NaN or infinity."""
    p = np.asarray(points_m, dtype=np.float64)
    if p.size == 0:
        return np.empty((0, 2))
    if p.ndim == 1 and p.shape == (2,):
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"points_m must have shape (q, 2), got {p.shape}")
    if not np.isfinite(p).all():
        raise ValueError("query points must be finite (got NaN or infinity)")
    return p
