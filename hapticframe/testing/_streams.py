"""Checks for the stream-processing kinds: sensors, feature extractors and classifiers."""

from __future__ import annotations

from typing import Any

import numpy as np

from .._kind import Kind
from .._registry import Registry
from .._specs import PluginSpec
from ..kinds import (
    ClassProbabilities,
    Classifier,
    FeatureExtractor,
    Robot,
    SampleBatch,
    Sensor,
    concatenate_batches,
)
from ._common import check
from ._harness import (
    CheckFailure,
    crossing_movement,
    make_component,
    raised_by_record_validation,
    synthetic_batch,
)

__all__ = ["drive_sensor", "exercise_stream"]

_EXTREMES = ("zero", "constant", "huge", "tiny", "nan")


def drive_sensor(sensor: Sensor, reads: int = 30) -> list[SampleBatch]:
    """Read ``sensor`` repeatedly, stepping the robot it is mounted on (if any)."""
    robots = [c for c in sensor.context.inputs.values() if isinstance(c, Robot)]
    robot = robots[0] if robots else None
    if robot is not None:
        robot.begin(crossing_movement(sensor.context.scene))
    batches = []
    for _ in range(reads):
        if robot is not None and robot.step() is None:
            robot.begin(crossing_movement(sensor.context.scene))
            robot.step()
        if sensor.exhausted:
            break
        batches.append(sensor.read())
    return batches


def _outputs(component: Any, batch: SampleBatch) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    out = component.update(batch)
    if isinstance(out, ClassProbabilities):
        return out.timestamps_s, {"probabilities": out.probabilities}
    return out.timestamps_s, dict(out.channels)


def exercise_stream(component: Any, spec: PluginSpec, seed: int = 0) -> list[Any]:
    """Feed 300 synthetic samples in chunks of 50; return every output."""
    batch = synthetic_batch(spec, 300, rng=np.random.default_rng(seed))
    component.reset()
    outs = []
    for start in range(0, 300, 50):
        outs.append(_outputs(component, batch.select(slice(start, start + 50))))
    return outs


def _fail_on_error(spec: PluginSpec, what: str, exc: Exception) -> CheckFailure:
    if raised_by_record_validation(exc):
        return CheckFailure(f"{spec.kind} {spec.name!r} produced invalid output on {what}: {exc}")
    return CheckFailure(f"{spec.kind} {spec.name!r} raised {type(exc).__name__} on {what}: {exc}")


@check(Kind.SENSOR)
def check_sensor_contract(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Declared channels arrive as float64 ``(n, *shape)`` with strictly increasing times."""
    sensor: Sensor = make_component(spec, registry=registry)  # type: ignore[assignment]
    try:
        channels = dict(sensor.channels)
        for name, info in channels.items():
            if not info.unit or not info.rate_hz > 0:
                raise CheckFailure(f"channel {name!r} needs a unit and a positive rate_hz, got {info}")
        batches = drive_sensor(sensor)
        last_t = -np.inf
        delivered = 0
        for i, batch in enumerate(batches):
            if set(batch.channels) != set(channels):
                raise CheckFailure(
                    f"read {i} delivered channels {sorted(batch.channels)}, but the sensor "
                    f"declares {sorted(channels)}"
                )
            for name, info in channels.items():
                array = batch.channels[name]
                if array.dtype != np.float64 or array.shape[1:] != tuple(info.shape):
                    raise CheckFailure(
                        f"channel {name!r} has shape {array.shape[1:]} per sample and dtype "
                        f"{array.dtype}; declared {tuple(info.shape)} float64"
                    )
            if len(batch):
                if batch.timestamps_s[0] <= last_t:
                    raise CheckFailure(
                        f"timestamps go back between reads: {batch.timestamps_s[0]} after {last_t}"
                    )
                last_t = float(batch.timestamps_s[-1])
                delivered += len(batch)
        if not delivered:
            raise CheckFailure("30 reads delivered no samples")
        if "finite" in spec.capabilities:
            sensor.read_all()
    finally:
        sensor.close()


def _stream_component(spec: PluginSpec, registry: Registry | None) -> Any:
    return make_component(spec, registry=registry)


@check(Kind.FEATURE_EXTRACTOR, Kind.CLASSIFIER)
def check_stream_contract(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Outputs have the declared layout, float64 dtype and increasing times in the input's range."""
    component = _stream_component(spec, registry)
    batch = synthetic_batch(spec, 300, rng=np.random.default_rng(1))
    last_t = -np.inf
    try:
        for start in range(0, 300, 50):
            t, arrays = _outputs(component, batch.select(slice(start, start + 50)))
            if len(t):
                if t[0] <= last_t or t[-1] > batch.timestamps_s[-1] + 1e-9:
                    raise CheckFailure(f"output times {t[0]}..{t[-1]} are not increasing within the input's range")
                last_t = float(t[-1])
            if isinstance(component, FeatureExtractor):
                declared = dict(component.output_channels)
                if set(arrays) != set(declared):
                    raise CheckFailure(f"features {sorted(arrays)} differ from output_channels {sorted(declared)}")
                for name, array in arrays.items():
                    if array.shape[1:] != tuple(declared[name].shape):
                        raise CheckFailure(
                            f"feature {name!r} has per-sample shape {array.shape[1:]}, declared "
                            f"{tuple(declared[name].shape)}"
                        )
                    if not np.all(np.isfinite(array)):
                        raise CheckFailure(f"feature {name!r} contains NaN or infinity for finite input")
            elif isinstance(component, Classifier):
                probs = arrays["probabilities"]
                if probs.shape[1] != len(component.classes):
                    raise CheckFailure(f"{probs.shape[1]} probability columns for classes {component.classes}")
    except CheckFailure:
        raise
    except Exception as exc:
        raise _fail_on_error(spec, "finite synthetic input", exc) from exc
    finally:
        component.close()


@check(Kind.FEATURE_EXTRACTOR, Kind.CLASSIFIER)
def check_streaming_matches_batch(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Chunked streaming updates give the batch result (to 1e-9)."""
    component = _stream_component(spec, registry)
    batch = synthetic_batch(spec, 240, rng=np.random.default_rng(2))
    try:
        if isinstance(component, Classifier):
            whole = component.predict_proba(batch)
            whole_t, whole_a = whole.timestamps_s, {"probabilities": whole.probabilities}
        else:
            out = component.transform(batch)
            whole_t, whole_a = out.timestamps_s, dict(out.channels)
        component.reset()
        sizes = np.random.default_rng(3).integers(1, 38, size=240)
        parts, start = [], 0
        for size in sizes:
            if start >= 240:
                break
            parts.append(_outputs(component, batch.select(slice(start, start + int(size)))))
            start += int(size)
    finally:
        component.close()
    times = np.concatenate([p[0] for p in parts]) if parts else np.empty(0)
    if times.shape != whole_t.shape or not np.allclose(times, whole_t, atol=1e-12):
        raise CheckFailure(
            f"streaming produced {len(times)} outputs, the batch path {len(whole_t)} "
            "(or at other times)"
        )
    for name, array in whole_a.items():
        streamed = np.concatenate([p[1][name] for p in parts]) if parts else np.empty_like(array)
        if not np.allclose(streamed, array, rtol=1e-9, atol=1e-9, equal_nan=True):
            worst = float(np.nanmax(np.abs(streamed - array))) if streamed.shape == array.shape else np.inf
            raise CheckFailure(
                f"streaming and batch outputs of {name!r} differ (max |diff| {worst:.3g}); "
                "update() in chunks must equal the batch path"
            )


@check(Kind.FEATURE_EXTRACTOR, Kind.CLASSIFIER)
def check_numerical_extremes(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Zero, constant, huge, tiny and NaN inputs give finite output or a clear ValueError."""
    component = _stream_component(spec, registry)
    try:
        for fill in _EXTREMES:
            for n in (1, 120):
                batch = synthetic_batch(spec, n, rng=np.random.default_rng(4), fill=fill)
                component.reset()
                try:
                    _, arrays = _outputs(component, batch)
                except ValueError as exc:
                    if raised_by_record_validation(exc):
                        raise _fail_on_error(spec, f"{fill} input of {n} sample(s)", exc) from exc
                    continue  # a clear error is acceptable
                except Exception as exc:
                    raise _fail_on_error(spec, f"{fill} input of {n} sample(s)", exc) from exc
                for name, array in arrays.items():
                    if not np.all(np.isfinite(array)):
                        raise CheckFailure(
                            f"{spec.kind} {spec.name!r} returned NaN or infinity in {name!r} for "
                            f"{fill} input of {n} sample(s): silent NaNs are not allowed"
                        )
    finally:
        component.close()


def sensor_outputs(sensor: Sensor) -> list[Any]:
    batches = drive_sensor(sensor, reads=20)
    nonempty = [b for b in batches if len(b)]
    if not nonempty:
        return []
    joined = concatenate_batches(nonempty)
    return [joined.timestamps_s, dict(joined.channels)]
