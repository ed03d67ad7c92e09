"""Shared machinery of the line planners: the search region, movements, outcome and figure."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe import Kind, Scene, plotting
from hapticframe.kinds import (
    BuildContext,
    ExploratoryMovement,
    Map,
    MovementResult,
    Planner,
    RunOutcome,
)

from ._config import CoverageConfig
from ._functional import Bounds, longer_side_angle_deg

__all__ = ["LinePlanner", "draw_paths", "plot_paths"]

FloatArray = NDArray[np.float64]

_PHASE_COLOURS = {"phase1": "tab:blue", "phase2": "tab:orange", "coverage": "tab:blue"}


class LinePlanner(Planner):
    """Base of planners that rake straight lines across a rectangular search region.

    Resolves the region (config, else the first input map's, else the scene's), keeps the
    tallies of finished movements per phase and draws ``paths.png`` in :meth:`finalize`.
    """

    config: CoverageConfig

    def __init__(self, config: CoverageConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self.max_movements = config.max_movements
        maps = [c for c in context.input_of_kind(Kind.MAP) if isinstance(c, Map)]
        self._maps: list[Map] = maps
        self.search_bounds: Bounds = self._resolve_bounds(config, maps, context.scene)
        self.phase1_angle_deg = (
            config.sweep_angle_deg
            if config.sweep_angle_deg is not None
            else longer_side_angle_deg(self.search_bounds)
        )
        self._finished: list[MovementResult] = []
        self._regions: list[Bounds] = []

    @staticmethod
    def _resolve_bounds(config: CoverageConfig, maps: list[Map], scene: Scene | None) -> Bounds:
        if config.region is not None:
            given = config.region
            return (given.x_min_m, given.x_max_m, given.y_min_m, given.y_max_m)
        if maps:
            mapped = maps[0].region
            return (mapped.x_min_m, mapped.x_max_m, mapped.y_min_m, mapped.y_max_m)
        if scene is not None:
            described = scene.region
            return (described.x_min_m, described.x_max_m, described.y_min_m, described.y_max_m)
        raise ValueError(
            "the planner needs a search region: set config.region, name a map in inputs, "
            "or describe a scene"
        )

    def reset(self) -> None:
        """Forget the tallies of finished movements."""
        self._finished = []
        self._regions = []

    def is_interaction(self, result: MovementResult) -> bool:
        """A movement interacted when the classifier halted it or it ended in a non-free class."""
        if result.halt_reason == "interaction":
            return True
        return bool(result.final_class) and result.final_class not in self.config.free_class_names

    @staticmethod
    def stop_point(result: MovementResult) -> FloatArray:
        """Where the fingertip stopped (the planned end when the robot reports no state)."""
        if result.final_state is not None and np.all(np.isfinite(result.final_state.position_m)):
            return np.asarray(result.final_state.position_m, dtype=np.float64)
        return np.asarray(result.movement.end_m, dtype=np.float64)

    def make_movement(
        self, start_m: FloatArray, end_m: FloatArray, phase: str, label: str
    ) -> ExploratoryMovement:
        return ExploratoryMovement(
            start_m=np.asarray(start_m, dtype=np.float64),
            end_m=np.asarray(end_m, dtype=np.float64),
            speed_m_per_s=self.config.speed_m_per_s,
            depth_m=self.config.depth_m,
            phase=phase,
            label=label,
        )

    def on_movement_end(self, result: MovementResult) -> None:
        self._finished.append(result)

    def count_phase(self, phase: str) -> int:
        """Finished movements proposed in ``phase``."""
        return sum(1 for r in self._finished if r.movement.phase == phase)

    def phase_metrics(self) -> dict[str, int]:
        """``ems_phase1`` and ``ems_phase2``: finished movements per phase."""
        return {"ems_phase1": self.count_phase("phase1"), "ems_phase2": self.count_phase("phase2")}

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        """Write ``paths.png`` and return the number of movements per phase."""
        results = list(outcome.movements) or list(self._finished)
        if not outcome.figures:
            return self.phase_metrics()
        plot_paths(
            Path(outcome.out_dir) / "paths.png",
            self.search_bounds,
            results,
            outcome.scene,
            self._regions,
            self.is_interaction,
            outcome.verdict,
        )
        return self.phase_metrics()


def plot_paths(
    path: Path,
    search_bounds: Bounds,
    results: list[MovementResult],
    scene: Scene | None,
    regions: list[Bounds],
    is_interaction: Any,
    verdict: str = "",
) -> bool:
    """Draw :func:`draw_paths` and save it; returns False when matplotlib is missing."""
    try:
        figure = draw_paths(search_bounds, results, scene, regions, is_interaction, verdict)
    except ImportError:  # plotting is an optional extra
        return False
    plotting.save_figure(figure, path)
    return True


def draw_paths(
    search_bounds: Bounds,
    results: list[MovementResult],
    scene: Scene | None,
    regions: list[Bounds],
    is_interaction: Any,
    verdict: str = "",
) -> Any:
    """The movements over the search region, as a matplotlib Figure (saying ``verdict``,
    :func:`hapticframe.plotting.draw_verdict`).

    Planned lines are dashed, the part actually raked solid (to where the fingertip stopped),
    interactions are crosses, true objects green. Of the phase-2 search regions (one per
    phase-2 movement, each refined from the last) only the latest is drawn, dotted.
    """
    figure, ax, _ = plotting.map_figure(colorbar=False)
    x0, x1, y0, y1 = search_bounds
    ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color="black", lw=1.0)
    labelled: set[str] = set()
    if regions:
        b = regions[-1]
        ax.plot([b[0], b[1], b[1], b[0], b[0]], [b[2], b[2], b[3], b[3], b[2]],
                color="tab:orange", lw=1.0, ls=":", label="latest phase-2 region")
    if scene is not None:
        plotting.draw_outlines(ax, [obj.outline() for obj in scene.objects],
                               label="buried object")
    for number, result in enumerate(results, start=1):
        mv = result.movement
        colour = _PHASE_COLOURS.get(mv.phase, "tab:purple")
        ax.plot([mv.start_m[0], mv.end_m[0]], [mv.start_m[1], mv.end_m[1]],
                color=colour, lw=0.6, ls="--", alpha=0.5,
                label=_once(labelled, "planned line"))
        stop = LinePlanner.stop_point(result)
        ax.plot([mv.start_m[0], stop[0]], [mv.start_m[1], stop[1]], color=colour, lw=1.6,
                label=_once(labelled, f"{mv.phase or 'movement'} (raked)"))
        ax.annotate(str(number), (mv.start_m[0], mv.start_m[1]), fontsize=7, color=colour,
                    xytext=(2, 2), textcoords="offset points")
        if is_interaction(result):
            ax.plot(stop[0], stop[1], marker="x", color="tab:red", ms=8, mew=2, ls="none",
                    label=_once(labelled, "interaction"))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{len(results)} exploratory movements")
    plotting.draw_verdict(ax, verdict)
    margin = 0.03 * max(x1 - x0, y1 - y0)
    plotting.layout_map(figure, ax, None, (x0 - margin, x1 + margin, y0 - margin, y1 + margin),
                        legend_columns=3)
    return figure


def _once(seen: set[str], label: str) -> str | None:
    """``label`` the first time it is asked for, so each legend entry appears once."""
    if label in seen:
        return None
    seen.add(label)
    return label
