"""Registration of the coverage planners (import-light: no numpy impl imports)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import PlannerSpec, hookimpl

from ._config import CoverageConfig, TwoPhaseCoverageConfig

__all__ = ["hapticframe_planners"]


@hookimpl
def hapticframe_planners() -> Iterator[PlannerSpec]:
    """Yield ``two-phase-coverage`` and the ``coverage`` baseline."""
    yield PlannerSpec(
        name="two-phase-coverage",
        summary="Binary-search coverage lines, then next-best lines on the map (Jia 2022, 3.4.4).",
        config=TwoPhaseCoverageConfig,
        factory="hapticframe_coverage._two_phase:TwoPhaseCoverage",
        validator="hapticframe_coverage._checks:check",
        capabilities=frozenset({"finite", "reads-map"}),
    )
    yield PlannerSpec(
        name="coverage",
        summary="Baseline: rake every parallel coverage line in boustrophedon order.",
        config=CoverageConfig,
        factory="hapticframe_coverage._coverage:BoustrophedonCoverage",
        validator="hapticframe_coverage._checks:check",
        capabilities=frozenset({"finite"}),
    )
