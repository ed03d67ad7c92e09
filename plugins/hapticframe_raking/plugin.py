"""Registration of the ``raking-estimator`` classifier (import-light)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import ChannelSpec, ClassifierSpec, Knob, SensorModelSpec, hookimpl

from ._config import DistanceEstimateConfig, RakingEstimatorConfig

__all__ = ["SENSOR_MODEL_SPECS", "SPECS", "hapticframe_classifiers", "hapticframe_sensor_models"]

SPECS = (
    ClassifierSpec(
        name="raking-estimator",
        summary="Distance (with uncertainty), direction and depth of a buried object from a "
        "raking tool's 4-taxel 3-axis tactile forces, per sample (real data: Chen et al. 2024).",
        config=RakingEstimatorConfig,
        factory="hapticframe_raking._estimator:RakingEstimator",
        capabilities=frozenset({"trainable"}),
        requires=("torch",),
        consumes={"taxel_force": ChannelSpec(
            (4, 3), "", "every component: 4 taxels x (x, y, z), flattened to 12 features")},
        sample_rate_hz=10.0,
        check_config={"pretrained": True},
        knobs=(
            Knob("window_steps", "a longer window: more context per estimate, more time per "
                 "step", values=(5, 10, 20)),
            Knob("hidden_units", "more units: a richer model, slower steps and training",
                 values=(16, 32, 64)),
        ),
    ),
)


@hookimpl
def hapticframe_classifiers() -> Iterator[ClassifierSpec]:
    yield from SPECS


SENSOR_MODEL_SPECS = (
    SensorModelSpec(
        name="distance-estimate",
        summary="Each observation at the raking-estimator's distance and direction ahead of "
        "the tool, weighted by the estimate's certainty (the failure zone's fixed distance "
        "without an estimator).",
        config=DistanceEstimateConfig,
        factory="hapticframe_raking._sensor_model:DistanceEstimateSensorModel",
    ),
)


@hookimpl
def hapticframe_sensor_models() -> Iterator[SensorModelSpec]:
    yield from SENSOR_MODEL_SPECS
