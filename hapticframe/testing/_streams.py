"""Checks for the stream-processing kinds: sensors, feature extractors and classifiers."""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np

from hapticframe._kind import Kind
from hapticframe._registry import Registry
from hapticframe._specs import PluginSpec
from hapticframe.kinds import (
    Classifier,
    ClassProbabilities,
    FeatureExtractor,
    InputAlignment,
    Robot,
    SampleBatch,
    Sensor,
    concatenate_batches,
)
from hapticframe.run._streams import InputAligner, merge_batches
from hapticframe.testing._common import check
from hapticframe.testing._harness import (
    CheckFailure,
    crossing_movement,
    make_component,
    raised_by_record_validation,
    release_component,
    synthetic_batch,
)

__all__ = [
    "LIVE_READS",
    "MAX_FINITE_DURATION_S",
    "MAX_FINITE_READS",
    "CLOCK_PERIODS",
    "check_aligned_inputs_stream_as_batch",
    "check_sensor_keeps_time",
    "check_sensor_read_all_matches_reads",
    "check_sensor_valid_samples_finite",
    "drive_sensor",
    "exercise_stream",
    "undeclared_end",
]

_EXTREMES = ("zero", "constant", "huge", "tiny", "nan")


#: Reads of a live sensor (one that does not end) in one drive: it is read until it ends
#: or this many reads (or :data:`MAX_FINITE_DURATION_S` of its own clock) have been made,
#: so that a sensor which ends without declaring ``finite`` is found out.
LIVE_READS = 1000
#: Bounds on driving a finite sensor to its end: reads, and seconds of its own clock.
MAX_FINITE_READS = 20_000
MAX_FINITE_DURATION_S = 600.0


def drive_sensor(
    sensor: Sensor, reads: int | None = None, *, finite: bool = False
) -> list[SampleBatch]:
    """Read ``sensor`` until it ends, stepping the robot it is mounted on (if any).

    Every sensor is read until ``exhausted`` or a bound: a ``finite`` one (its spec declares
    the capability) at most :data:`MAX_FINITE_READS` reads (a :class:`CheckFailure` when it
    has not ended by then), any other at most :data:`LIVE_READS`; both at most
    :data:`MAX_FINITE_DURATION_S` seconds of their own timestamps. ``reads`` overrides the
    read bound. Whether a sensor that does not declare ``finite`` ended is
    ``sensor.exhausted`` afterwards (see :func:`undeclared_end`).
    """
    robots = [c for c in sensor.context.inputs.values() if isinstance(c, Robot)]
    robot = robots[0] if robots else None
    if robot is not None:
        robot.begin(crossing_movement(sensor.context.scene))
    to_end = reads is None and finite
    limit = reads if reads is not None else (MAX_FINITE_READS if finite else LIVE_READS)
    batches: list[SampleBatch] = []
    first_t: float | None = None
    clock = sensor.context.clock
    for _ in range(limit):
        if robot is not None and robot.step() is None:
            robot.begin(crossing_movement(sensor.context.scene))
            robot.step()
        elif robot is None and not clock.follows:
            clock.advance()  # one control period per read, as an open loop's
        if sensor.exhausted:
            return batches
        batch = sensor.read()
        batches.append(batch)
        if len(batch):
            first_t = float(batch.timestamps_s[0]) if first_t is None else first_t
            if float(batch.timestamps_s[-1]) - first_t > MAX_FINITE_DURATION_S:
                break
    if to_end and not sensor.exhausted:
        raise CheckFailure(
            f"sensor {sensor.id!r} declares the 'finite' capability but was not exhausted "
            f"after {len(batches)} reads ({_span_s(batches):.4g} s of samples; the kit reads "
            f"at most {MAX_FINITE_READS} reads or {MAX_FINITE_DURATION_S:g} s): a finite "
            "source must end, and its check_config should describe a short one"
        )
    return batches


def undeclared_end(spec: PluginSpec, sensor: Sensor, batches: list[SampleBatch]) -> str:
    """The advice for a sensor that ended without declaring ``finite`` ("" otherwise)."""
    if "finite" in spec.capabilities or not sensor.exhausted:
        return ""
    return (
        f"sensor {spec.name!r} ended (exhausted) after {len(batches)} reads but does not "
        "declare the 'finite' capability: add \"finite\" to its spec's capabilities, so that "
        "runs, training and the kit treat it as a source that ends (the kit then checks its "
        "read_all() and iter_recordings() against its reads)"
    )


def _span_s(batches: list[SampleBatch]) -> float:
    times = [b.timestamps_s for b in batches if len(b)]
    return float(times[-1][-1] - times[0][0]) if times else 0.0


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


def _drive(spec: PluginSpec, sensor: Sensor) -> list[SampleBatch]:
    return drive_sensor(sensor, finite="finite" in spec.capabilities)


@check(Kind.SENSOR)
def check_sensor_contract(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Declared channels arrive as float64 ``(n, *shape)`` with strictly increasing times.

    Every sensor is read until it ends (bounded: see :func:`drive_sensor`); one that ends
    without declaring the ``finite`` capability fails, told to declare it.
    """
    sensor = make_component(spec, registry=registry, interface=Sensor)
    try:
        channels = dict(sensor.channels)
        for name, info in channels.items():
            if not info.unit or not info.rate_hz > 0:
                raise CheckFailure(
                    f"channel {name!r} needs a unit and a positive rate_hz, got {info}"
                )
        batches = _drive(spec, sensor)
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
            raise CheckFailure(f"{len(batches)} reads delivered no samples")
        advice = undeclared_end(spec, sensor, batches)
        if advice:
            raise CheckFailure(advice)
    finally:
        release_component(sensor)


#: Control periods the kit drives a sensor for in :func:`check_sensor_keeps_time`.
CLOCK_PERIODS = 100


@check(Kind.SENSOR)
def check_sensor_keeps_time(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Driven for :data:`CLOCK_PERIODS` control periods of the run's clock, a sensor's time
    advances by as many periods, within one sample of its slowest channel.

    The kit advances the clock one period per read (or steps the robot the sensor is mounted
    on, whose time the clock is) and compares how far the sensor's latest sample moved with
    how far the clock moved. A sensor on a time counter of its own (a fixed number of
    samples per read) runs ahead or behind the robot in a run, which ends such a run as no
    result. Sources that replay their own time (``finite``) and live devices (the wall
    clock paces them) are not held to it.
    """
    if "finite" in spec.capabilities:
        return
    sensor = make_component(spec, registry=registry, interface=Sensor)
    try:
        if bool(getattr(sensor, "live", False)):
            return
        clock = sensor.context.clock
        rates = [float(c.rate_hz) for c in sensor.channels.values() if c.rate_hz > 0]
        sample_s = 1.0 / min(rates) if rates else 0.0
        robots = [c for c in sensor.context.inputs.values() if isinstance(c, Robot)]
        robot = robots[0] if robots else None
        if robot is not None:
            robot.begin(crossing_movement(sensor.context.scene))
        marks: list[tuple[float, float]] = []  # (clock time, sensor's latest sample) per read
        for _ in range(CLOCK_PERIODS):
            if robot is not None:
                if robot.step() is None:
                    robot.begin(crossing_movement(sensor.context.scene))
                    robot.step()
            elif not clock.follows:
                clock.advance()
            if sensor.exhausted:
                break
            batch = sensor.read()
            if len(batch):
                marks.append((clock.now_s(), float(batch.timestamps_s[-1])))
        if len(marks) < 2:
            raise CheckFailure(
                f"sensor {spec.name!r} delivered samples in {len(marks)} of {CLOCK_PERIODS} "
                "reads, one control period apart: too few to tell whether it keeps the "
                "run's time"
            )
        (clock_0, sensor_0), (clock_n, sensor_n) = marks[0], marks[-1]
        moved_clock, moved_sensor = clock_n - clock_0, sensor_n - sensor_0
        if abs(moved_sensor - moved_clock) > sample_s + 1e-9:
            periods = moved_clock / clock.period_s
            ratio = moved_sensor / moved_clock if moved_clock > 0 else math.inf
            raise CheckFailure(
                f"sensor {spec.name!r}: over {periods:.0f} control periods of the run's clock "
                f"({moved_clock:.4g} s, period {clock.period_s:g} s) its time advanced "
                f"{moved_sensor:.4g} s ({ratio:.3g}x the robot's; allowed: one sample, "
                f"{sample_s:.4g} s). In a run it would end as no result, out of step with the "
                "robot. Fix: stamp samples with the run's clock, "
                "`times = self.context.clock.due_times(rate_hz, after_s=self.last_t)`, and "
                "deliver those samples (none when none is due) instead of a fixed number "
                "per read (docs/plugin-authoring.md, 'A software sensor')"
            )
    finally:
        release_component(sensor)


@check(Kind.SENSOR)
def check_sensor_valid_samples_finite(
    spec: PluginSpec, *, registry: Registry | None = None
) -> None:
    """Every sample a batch marks valid (``valid`` absent or True) is finite in every channel.

    A sensor that cannot measure a sample (a corrupted word, a stale reading) marks it
    invalid in ``batch.valid``; a NaN or infinity it calls valid would reach the models.
    Every sample is looked at: the sensor is read until it ends (or the kit's bound).
    """
    sensor = make_component(spec, registry=registry, interface=Sensor)
    try:
        batches = _drive(spec, sensor)
    finally:
        release_component(sensor)
    for i, batch in enumerate(batches):
        if not len(batch):
            continue
        for name, array in batch.channels.items():
            per_sample = array.reshape(len(batch), -1)
            bad = ~np.all(np.isfinite(per_sample), axis=1)
            if name in batch.valid:
                bad &= batch.valid[name]
            if bad.any():
                first = int(np.flatnonzero(bad)[0])
                marked = "marks valid" if name in batch.valid else "gives no validity for"
                raise CheckFailure(
                    f"read {i} delivered NaN or infinity in channel {name!r} at "
                    f"t = {batch.timestamps_s[first]:.6g} s ({int(bad.sum())} sample(s)), which "
                    f"the batch {marked}: mark what the sensor could not measure invalid "
                    f"(SampleBatch(..., valid={{{name!r}: mask}})) instead of passing a silent NaN"
                )


def _batches_differ(first: SampleBatch, second: SampleBatch) -> str:
    """What differs between two batches ("" when they agree to 1e-9)."""
    if first.timestamps_s.shape != second.timestamps_s.shape:
        return f"{len(first)} samples against {len(second)}"
    if not np.allclose(first.timestamps_s, second.timestamps_s, rtol=0, atol=1e-9):
        worst = float(np.max(np.abs(first.timestamps_s - second.timestamps_s)))
        return f"timestamps that differ by up to {worst:.3g} s"
    if set(first.channels) != set(second.channels):
        return f"channels {sorted(first.channels)} against {sorted(second.channels)}"
    for name, array in first.channels.items():
        other = second.channels[name]
        if array.shape != other.shape:
            return f"channel {name!r} of shape {array.shape} against {other.shape}"
        if not np.array_equal(np.isnan(array), np.isnan(other)):
            return f"channel {name!r} with NaN in other samples"
        if not np.allclose(array, other, rtol=1e-9, atol=1e-9, equal_nan=True):
            with np.errstate(invalid="ignore"):
                worst = float(np.nanmax(np.abs(array - other)))
            return f"channel {name!r} values that differ by up to {worst:.3g}"
    everywhere = np.ones(len(first), dtype=bool)
    for name in set(first.valid) | set(second.valid):
        first_valid = first.valid.get(name, everywhere)
        if not np.array_equal(first_valid, second.valid.get(name, everywhere)):
            return f"validity flags of channel {name!r} that differ"
    return ""


def _whole(batches: list[SampleBatch], sensor: Sensor, what: str) -> SampleBatch:
    nonempty = [b for b in batches if len(b)]
    if not nonempty:
        return SampleBatch.empty(sensor.channels)
    try:
        return concatenate_batches(nonempty)
    except ValueError as exc:
        raise CheckFailure(f"{what} do not join into one batch: {exc}") from exc


@check(Kind.SENSOR)
def check_sensor_read_all_matches_reads(
    spec: PluginSpec, *, registry: Registry | None = None
) -> None:
    """A finite sensor's ``read_all()`` and ``iter_recordings()`` give its successive ``read()``s.

    Batch use (training, ``read_all``) and streaming use (the run loop's ``read``) must see
    the same samples. A sensor without the ``finite`` capability is checked the same when
    it ends within the kit's bound (and told to declare ``finite``); a live one passes.
    """
    streamed = make_component(spec, registry=registry, interface=Sensor)
    try:
        batches = _drive(spec, streamed)
        if "finite" not in spec.capabilities and not streamed.exhausted:
            return  # a live source: it has no whole to read
        advice = undeclared_end(spec, streamed, batches)
        reads = _whole(batches, streamed, "the successive read()s")
    finally:
        release_component(streamed)
    drained = make_component(spec, registry=registry, interface=Sensor)
    try:
        whole = drained.read_all()
    except RuntimeError as exc:
        raise CheckFailure(f"read_all() did not end: {exc}") from exc
    finally:
        release_component(drained)
    difference = _batches_differ(reads, whole)
    if difference:
        raise CheckFailure(
            f"read_all() and successive read()s of fresh sensors built with the same seed "
            f"differ: {difference} ({len(reads)} samples read one batch at a time). Batch "
            "and streaming use must deliver the same samples" + (f"; {advice}" if advice else "")
        )
    split = make_component(spec, registry=registry, interface=Sensor)
    try:
        recordings = list(itertools.islice(split.iter_recordings(), MAX_FINITE_READS))
    finally:
        release_component(split)
    difference = _batches_differ(_whole(recordings, split, "the recordings"), whole)
    if difference:
        raise CheckFailure(
            f"iter_recordings(), joined, and read_all() differ: {difference} "
            f"({len(recordings)} recordings). The recordings must split the source, not "
            "change it"
        )


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
                    raise CheckFailure(
                        f"output times {t[0]}..{t[-1]} are not increasing within the input's "
                        "range"
                    )
                last_t = float(t[-1])
            if isinstance(component, FeatureExtractor):
                declared = dict(component.output_channels)
                if set(arrays) != set(declared):
                    raise CheckFailure(
                        f"features {sorted(arrays)} differ from output_channels "
                        f"{sorted(declared)}"
                    )
                for name, array in arrays.items():
                    if array.shape[1:] != tuple(declared[name].shape):
                        raise CheckFailure(
                            f"feature {name!r} has per-sample shape {array.shape[1:]}, declared "
                            f"{tuple(declared[name].shape)}"
                        )
                    if not np.all(np.isfinite(array)):
                        raise CheckFailure(
                            f"feature {name!r} contains NaN or infinity for finite input"
                        )
            elif isinstance(component, Classifier):
                probs = arrays["probabilities"]
                if probs.shape[1] != len(component.classes):
                    raise CheckFailure(
                        f"{probs.shape[1]} probability columns for classes {component.classes}"
                    )
    except CheckFailure:
        raise
    except Exception as exc:
        raise _fail_on_error(spec, "finite synthetic input", exc) from exc
    finally:
        release_component(component)


@check(Kind.FEATURE_EXTRACTOR, Kind.CLASSIFIER)
def check_streaming_matches_batch(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Chunked streaming updates give the batch result (to 1e-9)."""
    component = _stream_component(spec, registry)
    batch = synthetic_batch(spec, 240, rng=np.random.default_rng(2))
    try:
        whole_t, whole_a = _batch_outputs(component, batch)
        component.reset()
        sizes = np.random.default_rng(3).integers(1, 38, size=240)
        parts, start = [], 0
        for size in sizes:
            if start >= 240:
                break
            parts.append(_outputs(component, batch.select(slice(start, start + int(size)))))
            start += int(size)
    finally:
        release_component(component)
    _compare_stream(parts, whole_t, whole_a)


def _batch_outputs(component: Any, batch: SampleBatch) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    if isinstance(component, Classifier):
        whole = component.predict_proba(batch)
        return whole.timestamps_s, {"probabilities": whole.probabilities}
    out = component.transform(batch)
    return out.timestamps_s, dict(out.channels)


def _compare_stream(
    parts: list[tuple[np.ndarray, dict[str, np.ndarray]]],
    whole_t: np.ndarray,
    whole_a: dict[str, np.ndarray],
    how: str = "update() in chunks",
) -> None:
    times = np.concatenate([p[0] for p in parts]) if parts else np.empty(0)
    if times.shape != whole_t.shape or not np.allclose(times, whole_t, atol=1e-12):
        raise CheckFailure(
            f"streaming produced {len(times)} outputs, the batch path {len(whole_t)} "
            "(or at other times)"
        )
    for name, array in whole_a.items():
        streamed = np.concatenate([p[1][name] for p in parts]) if parts else np.empty_like(array)
        if not np.allclose(streamed, array, rtol=1e-9, atol=1e-9, equal_nan=True):
            worst = (
                float(np.nanmax(np.abs(streamed - array)))
                if streamed.shape == array.shape else np.inf
            )
            raise CheckFailure(
                f"streaming and batch outputs of {name!r} differ (max |diff| {worst:.3g}); "
                f"{how} must equal the batch path"
            )


def two_clock_inputs(
    spec: PluginSpec, alignment: InputAlignment, n: int, rng: np.random.Generator
) -> tuple[SampleBatch, SampleBatch]:
    """Two inputs on different clocks in the layout of ``spec.consumes``.

    The first ``consumes`` channel is the first input, at ``spec.sample_rate_hz``; the
    other channels are a second input at about a third of that rate (faster when
    ``alignment.max_age_s`` asks for it), with jittered timestamps, starting before the
    first input and ending after it, so that every joined sample is valid.
    """
    names = list(spec.consumes)
    first = synthetic_batch(spec, n, rng=rng)
    dt = 1.0 / spec.sample_rate_hz
    period = min(2.7 * dt, 0.45 * alignment.max_age_s)
    t_first = first.timestamps_s
    m = int(np.ceil((t_first[-1] - t_first[0]) / period)) + 3
    jitter = rng.uniform(-0.05, 0.05, m) * period
    t_second = t_first[0] - 0.5 * period + period * np.arange(m) + jitter
    second = synthetic_batch(spec, m, rng=rng)
    return (
        SampleBatch(t_first, {names[0]: first.channels[names[0]]}),
        SampleBatch(t_second, {k: second.channels[k] for k in names[1:]}),
    )


@check(Kind.FEATURE_EXTRACTOR, Kind.CLASSIFIER)
def check_aligned_inputs_stream_as_batch(
    spec: PluginSpec, *, registry: Registry | None = None
) -> None:
    """Inputs on different clocks, joined tick by tick, give the batch result (to 1e-9).

    For a component whose ``input_alignment`` is ``hold`` or ``linear``: the first
    ``consumes`` channel comes from one input at ``sample_rate_hz``, the other channels from
    a second input at another rate (:func:`two_clock_inputs`). Both are cut into random
    ticks (the second input's a little later, as a run reads its sensors one after the
    other), joined by the run's aligner and fed to ``update()``; the outputs must
    equal the batch path (``transform`` or ``predict_proba``) on the whole recordings
    joined at once, as training joins them. A component that aligns exactly, or consumes
    one channel, passes without further checks.
    """
    component = _stream_component(spec, registry)
    try:
        alignment = component.input_alignment
        if alignment.method == "exact" or len(spec.consumes) < 2:
            return
        rng = np.random.default_rng(6)
        first, second = two_clock_inputs(spec, alignment, 240, rng)
        consumer = f"kit-{spec.name}"
        whole_t, whole_a = _batch_outputs(
            component, merge_batches([first, second], consumer, alignment)
        )
        component.reset()
        aligner = InputAligner(alignment, consumer)
        # Tick boundaries anywhere between samples, 1 to 37 first-input samples apart; the
        # second input is read up to a few first-input periods later in each tick, as
        # sensors read one after the other are.
        ends = np.cumsum(rng.integers(1, 38, size=240))
        ends = ends[ends < len(first)]
        dt = 1.0 / spec.sample_rate_hz
        cuts = [*(first.timestamps_s[ends - 1] + rng.uniform(0, dt, len(ends))), np.inf]
        skews = rng.uniform(0, 3 * dt, len(cuts))
        parts, low, low_second = [], -np.inf, -np.inf
        for high, skew in zip(cuts, skews, strict=True):
            high_second = max(high + skew, low_second)
            ticks = [
                first.select((first.timestamps_s > low) & (first.timestamps_s <= high)),
                second.select((second.timestamps_s > low_second)
                              & (second.timestamps_s <= high_second)),
            ]
            parts.append(_outputs(component, aligner.push(ticks)))
            low, low_second = high, high_second
    except CheckFailure:
        raise
    except Exception as exc:
        raise _fail_on_error(spec, "two inputs on different clocks", exc) from exc
    finally:
        release_component(component)
    _compare_stream(parts, whole_t, whole_a, "update() on inputs aligned tick by tick")


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
        release_component(component)


def sensor_outputs(sensor: Sensor, spec: PluginSpec) -> list[Any]:
    batches = _drive(spec, sensor)
    nonempty = [b for b in batches if len(b)]
    if not nonempty:
        return []
    joined = concatenate_batches(nonempty)
    return [joined.timestamps_s, dict(joined.channels)]
