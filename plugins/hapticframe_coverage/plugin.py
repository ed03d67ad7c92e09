"""Registration of the coverage planners (import-light: no numpy impl imports)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import Knob, PlannerSpec, hookimpl

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
        knobs=(
            Knob("line_spacing_m", "wider phase-1 lines: fewer movements before the first "
                 "contact, an object between lines missed", values=(0.06, 0.08, 0.1, 0.12)),
            Knob("max_phase2_movements", "more phase-2 movements: a closer outline, robot time "
                 "per movement", values=(4, 8, 12, 20)),
            Knob("phase2_line_spacing_m", "denser phase-2 candidate lines: a better-placed next "
                 "line, each candidate scored on the map", values=(0.01, 0.02, 0.04)),
            Knob("score_step_m", "finer points along a candidate line (Eq. 3.9): a truer score, "
                 "map queries per line", values=(0.005, 0.01, 0.02)),
            Knob("grid_spacing_m", "a finer map sample for the centroid and the stop rule: "
                 "steadier estimates, map queries growing as 1/spacing²",
                 values=(0.005, 0.01, 0.02)),
            Knob("gap_step_deg", "finer approach directions ('widest-gap'): a better-aimed line, "
                 "more directions tried", values=(2.5, 5.0, 10.0)),
            # Issue 19 §6: movements against touches of a fragile object (docs/benchmarks.md).
            Knob("max_gap_deg", "a tighter angular-gap stop: a closer centroid and outline, more "
                 "movements and object interactions", values=(50.0, 80.0, 110.0)),
            Knob("stop_short_m", "phase-2 movements ending this far before the estimated "
                 "outline: fewer object interactions, a coarser outline",
                 values=(0.05, 0.07, 0.1)),
        ),
    )
    yield PlannerSpec(
        name="coverage",
        summary="Baseline: rake every parallel coverage line in boustrophedon order.",
        config=CoverageConfig,
        factory="hapticframe_coverage._coverage:BoustrophedonCoverage",
        validator="hapticframe_coverage._checks:check",
        capabilities=frozenset({"finite"}),
        knobs=(
            Knob("line_spacing_m", "wider lines: fewer movements, an object between lines "
                 "missed or outlined coarsely", values=(0.02, 0.035, 0.05, 0.07)),
        ),
    )
