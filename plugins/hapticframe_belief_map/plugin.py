"""Registration of ``contact-point`` and ``belief-map`` (import-light: configs only)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import Knob, MapSpec, SensorModelSpec, hookimpl

from ._config import BeliefMapConfig, ContactPointConfig

__all__ = ["hapticframe_maps", "hapticframe_sensor_models"]


@hookimpl
def hapticframe_sensor_models() -> Iterator[SensorModelSpec]:
    """Yield the ``contact-point`` sensor model."""
    yield SensorModelSpec(
        name="contact-point",
        summary="The classifier's contact probability at the fingertip, one observation per step.",
        config=ContactPointConfig,
        factory="hapticframe_belief_map._contact_point:ContactPoint",
        capabilities=frozenset({"streaming"}),
        install_hint="pip install hapticframe  (numpy); the timeline figure needs matplotlib",
    )


@hookimpl
def hapticframe_maps() -> Iterator[MapSpec]:
    """Yield the ``belief-map`` map."""
    yield MapSpec(
        name="belief-map",
        summary="RBF SVC with Platt scaling over fingertip positions (Jia 2022, App. A.4).",
        config=BeliefMapConfig,
        factory="hapticframe_belief_map._belief_map:BeliefMap",
        validator="hapticframe_belief_map._checks:check",
        capabilities=frozenset({"binned"}),
        requires=("sklearn",),
        install_hint="pip install scikit-learn  (figures need matplotlib)",
        knobs=(
            Knob("max_points", "more representatives: a finer boundary, SVC refits growing "
                 "quadratically or worse in the points", values=(100, 200, 400, 1000)),
            Knob("update_every", "refitting less often: fewer SVC fits, a staler map for the "
                 "planner", values=(1, 5, 10, 25)),
            Knob("cell_size_m", "coarser bins: fewer representatives to fit, a blurred "
                 "boundary", values=(0.001, 0.002, 0.005, 0.01)),
            Knob("calibration_folds", "more Platt folds: steadier probabilities, one SVC fit "
                 "per fold", values=(2, 3, 5)),
        ),
    )
