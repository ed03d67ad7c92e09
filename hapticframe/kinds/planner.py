"""Planner interface: proposes the next exploratory movement.

Contract
--------
- :meth:`Planner.propose` returns the next :class:`ExploratoryMovement`, or ``None`` when
  the search is complete. It reads the maps it names in ``inputs`` (from
  ``self.context.inputs``).
- :meth:`Component.on_movement_end` tells the planner how the movement ended; a planner
  must not propose forever: :attr:`Planner.max_movements` bounds a run.
- Given the same seed and the same movement results, the proposals are identical.
"""

from __future__ import annotations

from abc import abstractmethod
from typing import ClassVar

from hapticframe._kind import Kind
from hapticframe.kinds._base import Component
from hapticframe.kinds._records import ExploratoryMovement

__all__ = ["Planner"]


class Planner(Component):
    """Chooses exploratory movements (coverage, information gain...)."""

    kind: ClassVar[Kind] = Kind.PLANNER

    #: An upper bound on the movements of one run, whatever the maps say.
    max_movements: int = 200

    @abstractmethod
    def propose(self) -> ExploratoryMovement | None:
        """The next movement, or None when the search is done."""

    @property
    def phase(self) -> str:
        """The planner's current phase, for progress lines. Default: empty."""
        return ""
