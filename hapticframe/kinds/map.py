"""Map interface: occupancy with uncertainty, queryable at arbitrary points.

Contract
--------
- :meth:`Map.update` fuses observations (streaming); :meth:`Map.fit` forgets everything and
  fuses one batch. Updating with consecutive parts gives a map close to fitting the union
  (exactly equal for maps whose update is exact, such as log-odds grids).
- :meth:`Map.query` returns a :class:`MapEstimate` for any ``(q, 2)`` float array of points
  in metres, including points outside :attr:`Map.region` and an empty array. Before any
  update the mean is the prior (0.5 for an uninformed map).
"""

from __future__ import annotations

from abc import abstractmethod
from typing import ClassVar

from numpy.typing import ArrayLike

from hapticframe._kind import Kind
from hapticframe.kinds._base import Component
from hapticframe.kinds._records import MapEstimate, Observations, Region

__all__ = ["Map"]


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

    @abstractmethod
    def query(self, points_m: ArrayLike) -> MapEstimate:
        """Occupancy probability and its standard deviation at ``points_m`` (q, 2)."""
