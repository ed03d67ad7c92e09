"""Registration of the failure-zone kernel sensor model (import-light: no numpy impl imports)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import SensorModelSpec, hookimpl

from ._config import FailureZoneConfig

__all__ = ["hapticframe_sensor_models"]


@hookimpl
def hapticframe_sensor_models() -> Iterator[SensorModelSpec]:
    """Yield the ``failure-zone-kernel`` sensor model."""
    yield SensorModelSpec(
        name="failure-zone-kernel",
        summary="Granular failure-zone kernels ahead of the fingertip (Jia 2022, Eqs. 3.2-3.4).",
        config=FailureZoneConfig,
        factory="hapticframe_failure_zone._kernel:FailureZoneKernel",
        validator="hapticframe_failure_zone._checks:check",
        capabilities=frozenset({"streaming"}),
    )
