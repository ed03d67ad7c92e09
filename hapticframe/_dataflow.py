"""Moving data between built components: one tick of the sensor → … → map chain.

The run loop (:mod:`hapticframe._session`) decides when to tick; this module knows how
samples become features, class probabilities, located measurements and map observations,
and records everything for ``trace.npz``.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._config import ComponentEntry, Experiment
from ._errors import RunError
from ._kind import Kind
from .kinds import (
    ClassProbabilities,
    Classifier,
    Component,
    FeatureExtractor,
    LocatedMeasurement,
    Map,
    Observations,
    RobotState,
    SampleBatch,
    Sensor,
    SensorModel,
)

__all__ = ["Dataflow", "PoseHistory", "TraceRecorder"]


class TraceRecorder:
    """Collects arrays per key and writes them to one ``.npz`` (no pickles)."""

    def __init__(self) -> None:
        self._parts: dict[str, list[np.ndarray]] = defaultdict(list)
        self._fixed: dict[str, np.ndarray] = {}

    def add(self, key: str, array: np.ndarray) -> None:
        self._parts[key].append(np.asarray(array))

    def set(self, key: str, array: np.ndarray) -> None:
        self._fixed[key] = np.asarray(array)

    def arrays(self) -> dict[str, np.ndarray]:
        out = {k: np.concatenate(v) if v else np.empty(0) for k, v in self._parts.items()}
        out.update(self._fixed)
        return out

    def save(self, path: str) -> None:
        arrays = self.arrays()
        for key, value in arrays.items():
            if value.dtype == object:  # pragma: no cover - guarded by construction
                raise RunError(f"trace entry {key!r} is not a plain array")
        np.savez_compressed(path, **arrays)


class PoseHistory:
    """Fingertip poses over time, interpolated at the times of classifier outputs.

    Poses are kept in growable arrays, so interpolation costs no copying per tick.
    """

    def __init__(self) -> None:
        self._n = 0
        self._t = np.empty(256)
        self._pose = np.empty((256, 4))  # x, y, heading (unwrapped), depth

    def add_state(self, state: RobotState) -> None:
        self.add(state.timestamp_s, state.position_m, state.heading_rad, state.depth_m)

    def add(self, t: float, xy: ArrayLike, heading: float, depth: float) -> None:
        if self._n and t <= self._t[self._n - 1]:
            return  # a repeated or stale pose adds nothing
        if self._n == len(self._t):
            self._t = np.concatenate([self._t, np.empty(len(self._t))])
            self._pose = np.concatenate([self._pose, np.empty_like(self._pose)])
        if self._n:  # unwrap so that interpolation never swings through ±pi
            previous = self._pose[self._n - 1, 2]
            heading = previous + (heading - previous + np.pi) % (2 * np.pi) - np.pi
        x, y = np.asarray(xy, dtype=np.float64)
        self._t[self._n] = t
        self._pose[self._n] = (x, y, heading, depth)
        self._n += 1

    def add_batch(self, batch: SampleBatch) -> None:
        """Poses from a sensor's ``position_m`` (and optional heading/depth) channels."""
        pos = batch.channels["position_m"]
        if "heading_rad" in batch.channels:
            heading = batch.channels["heading_rad"].reshape(-1)
        else:
            prev = self._pose[self._n - 1, :2] if self._n else (pos[0] if len(pos) else np.zeros(2))
            steps = np.diff(np.vstack([prev, pos]), axis=0)
            heading = np.arctan2(steps[:, 1], steps[:, 0])
        depth = batch.channels["depth_m"].reshape(-1) if "depth_m" in batch.channels else np.full(len(batch), np.nan)
        for i in range(len(batch)):
            self.add(batch.timestamps_s[i], pos[i], heading[i], depth[i])

    def at(self, times: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        if not self._n:
            raise RunError("a sensor model needs fingertip poses, but none were recorded yet")
        t = self._t[: self._n]
        pose = self._pose[: self._n]
        x, y, heading = (np.interp(times, t, pose[:, k]) for k in range(3))
        depth_known = pose[:, 3]
        if np.all(np.isfinite(depth_known)):
            depth = np.interp(times, t, depth_known)
        else:
            depth = np.full(len(times), np.nan)
        return np.column_stack([x, y]), heading, depth


def merge_batches(batches: Sequence[SampleBatch], consumer: str) -> SampleBatch:
    """Join the batches of several inputs sample by sample (they must share timestamps)."""
    if len(batches) == 1:
        return batches[0]
    first = batches[0]
    channels: dict[str, np.ndarray] = {}
    valid: dict[str, np.ndarray] = {}
    for batch in batches:
        if batch.timestamps_s.shape != first.timestamps_s.shape or not np.array_equal(
            batch.timestamps_s, first.timestamps_s
        ):
            raise RunError(
                f"the inputs of {consumer!r} deliver samples at different times; give it "
                "inputs that share a clock, or one input"
            )
        for name, array in batch.channels.items():
            if name in channels:
                raise RunError(f"two inputs of {consumer!r} both provide channel {name!r}")
            channels[name] = array
        valid.update(batch.valid)
    return SampleBatch(first.timestamps_s, channels, valid)


class Dataflow:
    """Ticks the perception chain of an experiment and routes observations to maps."""

    def __init__(
        self, experiment: Experiment, components: Mapping[str, Component], recorder: TraceRecorder
    ) -> None:
        self.components = components
        self.recorder = recorder
        self.entries: dict[str, ComponentEntry] = {e.id: e for e in experiment.components}
        order = [e.id for e in experiment.components]
        self.sensors = [i for i in order if self.entries[i].kind is Kind.SENSOR]
        self.extractors = [i for i in order if self.entries[i].kind is Kind.FEATURE_EXTRACTOR]
        self.classifiers = [i for i in order if self.entries[i].kind is Kind.CLASSIFIER]
        self.sensor_models = [i for i in order if self.entries[i].kind is Kind.SENSOR_MODEL]
        self.maps = [i for i in order if self.entries[i].kind is Kind.MAP]
        self.poses: dict[str, PoseHistory] = {}
        self.latest: dict[str, ClassProbabilities] = {}
        self.pending: dict[str, list[Observations]] = {m: [] for m in self.maps}
        self.force_max_n = float("nan")
        self._plan_sensor_models()
        for sensor_id in self.sensors:
            channels = components[sensor_id].channels  # type: ignore[attr-defined]
            for name, info in channels.items():
                recorder.set(f"sensor/{sensor_id}/{name}/unit", np.array(info.unit))

    def _plan_sensor_models(self) -> None:
        """Pick each sensor model's classifier and pose source, or say what is missing."""
        self.sm_classifier: dict[str, str] = {}
        self.sm_pose_source: dict[str, str] = {}
        for sm in self.sensor_models:
            entry = self.entries[sm]
            classifiers = [i for i in entry.inputs if self.entries[i].kind is Kind.CLASSIFIER]
            if len(classifiers) != 1:
                raise RunError(f"sensor model {sm!r} needs exactly one classifier in its inputs")
            self.sm_classifier[sm] = classifiers[0]
            robots = [i for i in entry.inputs if self.entries[i].kind is Kind.ROBOT]
            if robots:
                self.sm_pose_source[sm] = robots[0]
                continue
            for sensor_id in [i for i in entry.inputs if self.entries[i].kind is Kind.SENSOR] + self.sensors:
                if "position_m" in self.components[sensor_id].channels:  # type: ignore[attr-defined]
                    self.sm_pose_source[sm] = sensor_id
                    break
            else:
                raise RunError(
                    f"sensor model {sm!r} needs fingertip positions: add a robot to its inputs "
                    "or use a sensor with a 'position_m' channel"
                )
        for source in set(self.sm_pose_source.values()):
            self.poses[source] = PoseHistory()

    @property
    def primary_classifier(self) -> str | None:
        if self.sensor_models:
            return self.sm_classifier[self.sensor_models[0]]
        return self.classifiers[0] if self.classifiers else None

    def record_robot_state(self, robot_id: str, state: RobotState, movement_index: int) -> None:
        if robot_id in self.poses:
            self.poses[robot_id].add_state(state)
        rec = self.recorder
        rec.add(f"robot/{robot_id}/timestamps_s", np.array([state.timestamp_s]))
        rec.add(f"robot/{robot_id}/position_m", state.position_m[None, :])
        rec.add(f"robot/{robot_id}/heading_rad", np.array([state.heading_rad]))
        rec.add(f"robot/{robot_id}/depth_m", np.array([state.depth_m]))
        rec.add(f"robot/{robot_id}/movement_index", np.array([movement_index]))

    def _inputs(self, consumer: str, outputs: Mapping[str, SampleBatch]) -> SampleBatch:
        names = [i for i in self.entries[consumer].inputs if i in outputs]
        if not names:
            raise RunError(f"{consumer!r} has no sensor or feature input")
        return merge_batches([outputs[i] for i in names], consumer)

    def tick(self) -> bool:
        """Read every sensor once and push the samples through. True if any sample arrived."""
        outputs: dict[str, SampleBatch] = {}
        arrived = False
        for sensor_id in self.sensors:
            sensor: Sensor = self.components[sensor_id]  # type: ignore[assignment]
            batch = sensor.read()
            outputs[sensor_id] = batch
            arrived |= len(batch) > 0
            self._record_batch("sensor", sensor_id, batch)
            self._track_force(sensor, batch)
            if sensor_id in self.poses and len(batch):
                self.poses[sensor_id].add_batch(batch)
        for fe_id in self.extractors:
            extractor: FeatureExtractor = self.components[fe_id]  # type: ignore[assignment]
            out = extractor.update(self._inputs(fe_id, outputs))
            outputs[fe_id] = out
            self._record_batch("feature_extractor", fe_id, out)
        for clf_id in self.classifiers:
            classifier: Classifier = self.components[clf_id]  # type: ignore[assignment]
            probs = classifier.update(self._inputs(clf_id, outputs))
            if len(probs):
                self.latest[clf_id] = probs
                self.recorder.add(f"classifier/{clf_id}/timestamps_s", probs.timestamps_s)
                self.recorder.add(f"classifier/{clf_id}/probabilities", probs.probabilities)
                self.recorder.set(f"classifier/{clf_id}/classes", np.array(probs.classes))
            self._observe(clf_id, probs)
        return arrived

    def _observe(self, clf_id: str, probs: ClassProbabilities) -> None:
        if not len(probs):
            return
        for sm_id in self.sensor_models:
            if self.sm_classifier[sm_id] != clf_id:
                continue
            positions, headings, depths = self.poses[self.sm_pose_source[sm_id]].at(probs.timestamps_s)
            located = LocatedMeasurement(
                probs.timestamps_s, positions, headings, probs.probabilities, probs.classes, depths
            )
            model: SensorModel = self.components[sm_id]  # type: ignore[assignment]
            obs = model.observe(located)
            if len(obs):
                self.recorder.add(f"sensor_model/{sm_id}/points_m", obs.points_m)
                self.recorder.add(f"sensor_model/{sm_id}/targets", obs.targets)
                self.recorder.add(f"sensor_model/{sm_id}/weights", obs.weights)  # type: ignore[arg-type]
                for map_id in self.maps:
                    if sm_id in self.entries[map_id].inputs:
                        self.pending[map_id].append(obs)

    def flush_maps(self) -> None:
        """Fuse pending observations into their maps."""
        for map_id, parts in self.pending.items():
            if parts:
                merged = Observations.concatenate(parts)
                self.pending[map_id] = []
                the_map: Map = self.components[map_id]  # type: ignore[assignment]
                the_map.update(merged)

    def _record_batch(self, kind: str, cid: str, batch: SampleBatch) -> None:
        if not len(batch):
            return
        self.recorder.add(f"{kind}/{cid}/timestamps_s", batch.timestamps_s)
        for name, array in batch.channels.items():
            self.recorder.add(f"{kind}/{cid}/{name}", array)

    def _track_force(self, sensor: Sensor, batch: SampleBatch) -> None:
        for name, info in sensor.channels.items():
            if info.unit == "N" and len(batch):
                values = batch.channels[name].reshape(len(batch), -1)
                norms = np.linalg.norm(values, axis=1)
                finite = norms[np.isfinite(norms)]
                if finite.size:
                    self.force_max_n = float(np.fmax(self.force_max_n, finite.max()))

    def start_stream(self) -> None:
        """A new movement starts a new stream: forget classifier and feature state."""
        self.latest.clear()
        self.force_max_n = float("nan")
        for cid in self.extractors + self.classifiers:
            self.components[cid].reset()

    def interaction_detected(self) -> str | None:
        """The class name if the primary classifier's latest sample is not background."""
        clf = self.primary_classifier
        if clf is None or clf not in self.latest:
            return None
        probs = self.latest[clf]
        label = int(probs.labels[-1])
        return probs.classes[label] if label != 0 else None

    def latest_class(self) -> str:
        clf = self.primary_classifier
        if clf is None or clf not in self.latest:
            return ""
        probs = self.latest[clf]
        return probs.classes[int(probs.labels[-1])]
