"""Registration of the learned-zone sensor model (import-light: no numpy impl imports)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import SensorModelSpec, hookimpl

from ._config import LearnedZoneConfig

__all__ = ["hapticframe_sensor_models"]


@hookimpl
def hapticframe_sensor_models() -> Iterator[SensorModelSpec]:
    """Yield the ``learned-zone`` sensor model."""
    yield SensorModelSpec(
        name="learned-zone",
        summary="What the classifier reports, as a function of the object's place relative "
        "to the plate, learned from calibration recordings (hapticframe train).",
        config=LearnedZoneConfig,
        factory="hapticframe_learned_zone._model:LearnedZone",
        validator="hapticframe_learned_zone._checks:check",
        capabilities=frozenset({"streaming"}),
    )
