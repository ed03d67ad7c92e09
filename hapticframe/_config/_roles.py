"""Which component of an experiment plays a role the run, the checks and the live view all
need to agree on: one home for each such rule."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Protocol

from hapticframe._kind import Kind

__all__ = ["RoleEntry", "evaluated_map_id"]


class RoleEntry(Protocol):
    """What a rule reads of an experiment's component (``ComponentEntry`` has it)."""

    @property
    def kind(self) -> Kind: ...

    @property
    def id(self) -> str: ...

    @property
    def inputs(self) -> tuple[str, ...]: ...


def evaluated_map_id(entries: Iterable[RoleEntry], chosen: str | None) -> str | None:
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
