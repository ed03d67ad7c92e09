"""Registration of ``contact-point`` and ``belief-map`` (import-light: configs only)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import MapSpec, SensorModelSpec, hookimpl

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
        capabilities=frozenset({"binned"}),
        requires=("sklearn",),
        install_hint="pip install scikit-learn  (figures need matplotlib)",
    )
