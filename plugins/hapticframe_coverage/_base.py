"""Shared machinery of the line planners: the search region, movements, outcome and figure."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe import Kind, Scene
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

__all__ = ["LinePlanner", "plot_paths"]

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
            r = config.region
            return (r.x_min_m, r.x_max_m, r.y_min_m, r.y_max_m)
        if maps:
            r = maps[0].region
            return (r.x_min_m, r.x_max_m, r.y_min_m, r.y_max_m)
        if scene is not None:
            r = scene.region
            return (r.x_min_m, r.x_max_m, r.y_min_m, r.y_max_m)
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
        )
        return self.phase_metrics()


def plot_paths(
    path: Path,
    search_bounds: Bounds,
    results: list[MovementResult],
    scene: Scene | None,
    regions: list[Bounds],
    is_interaction: Any,
) -> bool:
    """Draw the movements over the search region; returns False when matplotlib is missing.

    Planned lines are dashed, the part actually raked solid (to where the fingertip stopped),
    interactions are crosses; phase-2 search regions are dotted, true objects green.
    """
    try:
        from matplotlib.figure import Figure
    except ImportError:  # plotting is an optional extra
        return False
    fig = Figure(figsize=(8.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    x0, x1, y0, y1 = search_bounds
    ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color="black", lw=1.0)
    labelled: set[str] = set()
    for b in regions:
        ax.plot([b[0], b[1], b[1], b[0], b[0]], [b[2], b[2], b[3], b[3], b[2]],
                color="tab:orange", lw=0.8, ls=":", label=_once(labelled, "phase-2 region"))
    if scene is not None:
        for obj in scene.objects:
            outline = obj.outline()
            closed = np.vstack([outline, outline[:1]])
            ax.plot(closed[:, 0], closed[:, 1], color="tab:green", lw=1.5,
                    label=_once(labelled, "buried object"))
    for number, result in enumerate(results, start=1):
        mv = result.movement
        colour = _PHASE_COLOURS.get(mv.phase, "tab:purple")
        ax.plot([mv.start_m[0], mv.end_m[0]], [mv.start_m[1], mv.end_m[1]],
                color=colour, lw=0.6, ls="--", alpha=0.5)
        stop = LinePlanner.stop_point(result)
        ax.plot([mv.start_m[0], stop[0]], [mv.start_m[1], stop[1]], color=colour, lw=1.6,
                label=_once(labelled, mv.phase or "movement"))
        ax.annotate(str(number), mv.start_m, fontsize=7, color=colour)
        if is_interaction(result):
            ax.plot(stop[0], stop[1], marker="x", color="tab:red", ms=8, mew=2, ls="none",
                    label=_once(labelled, "interaction"))
    if labelled:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{len(results)} exploratory movements")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return True


def _once(seen: set[str], label: str) -> str | None:
    """``label`` the first time it is asked for, so each legend entry appears once."""
    if label in seen:
        return None
    seen.add(label)
    return label
