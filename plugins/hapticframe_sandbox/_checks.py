"""Checks of the sandbox robot that ``validate`` runs (import-light: no numpy)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from hapticframe import Finding, Kind, ValidationContext

__all__ = ["check"]


def check(config: Any, context: ValidationContext) -> Iterator[Finding]:
    """Refuse a depth whose free drag alone trips a force limit, and a bad ``follows``."""
    # Free drag F = c d² (Figure 3.6): deeper than where it reaches a force limit, every
    # movement halts at its start without ever meeting the object.
    drag = config.drag_coefficient_n_per_m2 * config.depth_m**2
    limits = [("force_limit_n", config.force_limit_n)]
    run_limit = getattr(context.run, "force_limit_n", None)
    if run_limit is not None:
        limits.append(("run.force_limit_n", run_limit))
    for name, limit in limits:
        if drag >= limit:
            yield Finding(
                f"raking {config.depth_m:g} m deep, the free drag c d² is {drag:.4g} N, at or "
                f"above {name} ({limit:g} N): every movement would halt before reaching "
                "anything; rake shallower",
                field="depth_m",
            )
            break
    if config.follows is not None:
        followed = context.components.get(config.follows)
        if config.follows not in context.inputs:
            yield Finding(
                f"follows names {config.follows!r}, which is not among the sandbox's inputs "
                f"{list(context.inputs)}; list it in inputs",
                field="follows",
            )
        elif followed is not None and followed.kind != Kind.ROBOT:
            yield Finding(
                f"follows names {config.follows!r}, a {followed.kind.value}, not a robot",
                field="follows",
            )
