"""Registration of the failure-zone kernel sensor model (import-light: no numpy impl imports)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import Knob, SensorModelSpec, hookimpl

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
        knobs=(
            # 0 (a sector every sample) is left out: swept, it found no object in 3 of 3
            # trials, the free sectors outweighing the jamming ones (docs/benchmarks.md).
            Knob("observation_spacing_m", "sectors emitted every this much travel: fewer map "
                 "points to fit, coarser evidence along a line",
                 values=(0.005, 0.01, 0.02, 0.04)),
            Knob("sector_spacing_m", "a finer polar grid per sector: a smoother kernel on the "
                 "map, points growing as 1/spacing²", values=(0.0075, 0.015, 0.03)),
        ),
    )
