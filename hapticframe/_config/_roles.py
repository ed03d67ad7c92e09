"""Which component of an experiment plays a role the run, the checks and the live view all
need to agree on: one home for each such rule."""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

from .._kind import Kind

if TYPE_CHECKING:
    from ._validate import ComponentEntry

__all__ = ["evaluated_map_id"]


def evaluated_map_id(entries: Iterable[ComponentEntry], chosen: str | None) -> str | None:
    """The id of the map a run scores against the scene: ``chosen`` (``run.evaluation_map``,
    not checked here) when set, else the first map a planner reads, else the last map, else
    None (no map)."""
    if chosen is not None:
        return chosen
    listed = list(entries)
    maps = [e.id for e in listed if e.kind is Kind.MAP]
    for planner in listed:
        if planner.kind is Kind.PLANNER:
            for name in planner.inputs:
                if name in maps:
                    return name
    return maps[-1] if maps else None
