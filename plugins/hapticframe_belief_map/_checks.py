"""Checks of the belief map that ``validate`` runs (import-light: no scikit-learn)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from hapticframe import Size, ValidationContext

__all__ = ["check"]

#: Bytes a fitted model keeps per representative and calibration fold (a support vector's
#: two coordinates, its dual coefficient and index).
_VECTOR_BYTES = 32


def check(config: Any, context: ValidationContext) -> Iterator[Size]:
    """Declare what a refit iterates over and what the kept snapshots hold."""
    points, folds = config.max_points, config.calibration_folds
    # An RBF SVC fit evaluates the kernel between pairs of representatives, once per fold.
    yield Size(
        "max_points",
        f"kernel evaluations of an SVC fit on {points} representatives, {folds} calibration "
        "folds",
        bytes=8.0 * points * points, iterations=float(folds) * points * points,
        remedy="lower max_points",
    )
    yield Size(
        "max_snapshots",
        f"{config.max_snapshots} fitted maps of up to {points} support vectors in {folds} "
        "folds each",
        bytes=float(_VECTOR_BYTES) * config.max_snapshots * points * folds,
        remedy="lower max_snapshots or max_points",
    )
