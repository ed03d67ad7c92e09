"""Moving data between built components: one tick of the sensor → … → map chain.

The run loop (:mod:`hapticframe.run._session`) decides when to tick; this module knows how
samples become features, class probabilities, located measurements and map observations,
and records everything for ``trace.npz``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe._config import ComponentEntry, Experiment
from hapticframe._errors import RunError
from hapticframe._kind import Kind
from hapticframe.kinds import (
    ClassProbabilities,
    LocatedMeasurement,
    Observations,
    RobotState,
    SampleBatch,
    Sensor,
)
from hapticframe.run._channels import LOOP, MapSnapshot, RecordingWriter
from hapticframe.run._clock_check import StepCheck
from hapticframe.run._components import Components
from hapticframe.run._streams import InputAligner, PoseHistory, TraceRecorder, _merge_exact

__all__ = ["Dataflow"]

#: The key of the clock check's state in a :meth:`Dataflow.checkpoint` (no component id:
#: ids start with a letter).
_STEP_CHECK = "#step-check"


class Dataflow:
    """Ticks the perception chain of an experiment and routes observations to maps."""

    #: Safety bookkeeping (set per run in ``__init__``; these defaults: no limit, nothing seen).
    force_limit_n: float | None = None
    force_violation: tuple[float, float] | None = None
    valid_force_samples: int = 0
    #: The run's recording (see :attr:`recording`); maps changed since the last snapshot.
    _recording: RecordingWriter | None = None
    _maps_changed = False
    #: CPU seconds the map snapshots took, and the CPU clock at the start of the run: a
    #: snapshot that is due is taken only while the snapshots stay within
    #: ``run.snapshot_cpu_share`` of the run's CPU (the last state is always written).
    _snapshot_cpu_s = 0.0
    _last_snapshot_cpu_s = 0.0
    _snapshot_cpu_share = 1.0
    _cpu_start_s = 0.0
    #: A closed loop's check of every stream against the robot's time (None: unchecked).
    step_check: StepCheck | None = None

    def __init__(
        self,
        experiment: Experiment,
        components: Components,
        recorder: TraceRecorder,
        training_only: frozenset[str] = frozenset(),
    ) -> None:
        self.components = components
        self.recorder = recorder
        # Map snapshots in the recording (run.snapshot_*), with the scene they lie in.
        run = experiment.model.run
        self._snapshot_rate_hz = run.snapshot_rate_hz
        self._snapshot_spacing_m = run.snapshot_spacing_m
        self._snapshot_max_cells = run.snapshot_max_cells
        self._snapshot_cpu_share = run.snapshot_cpu_share
        self._cpu_start_s = time.process_time()
        self._outline_level = run.outline_level
        self.scene = experiment.model.scene
        self.recording = None
        self.entries: dict[str, ComponentEntry] = {e.id: e for e in experiment.components}
        order = [e.id for e in experiment.components]
        self.sensors = [
            i for i in order if self.entries[i].kind is Kind.SENSOR and i not in training_only
        ]
        self.extractors = [i for i in order if self.entries[i].kind is Kind.FEATURE_EXTRACTOR]
        self.classifiers = [i for i in order if self.entries[i].kind is Kind.CLASSIFIER]
        self.sensor_models = [i for i in order if self.entries[i].kind is Kind.SENSOR_MODEL]
        self.maps = [i for i in order if self.entries[i].kind is Kind.MAP]
        self.poses: dict[str, PoseHistory] = {}
        self.latest: dict[str, ClassProbabilities] = {}
        self.pending: dict[str, list[Observations]] = {m: [] for m in self.maps}
        self.force_max_n = float("nan")
        #: Classifier outputs before this time are not located (see :meth:`locate_from`).
        self.movement_start_s = -math.inf
        # Safety (hapticframe.run._safety): the force limit to watch for (the safety monitor,
        # which holds the run's limit, hands it over; None: nobody watches), the first valid
        # sample above it since the movement began, and a count of valid force samples (the
        # stall check watches it grow).
        self.force_limit_n: float | None = None
        self.force_violation: tuple[float, float] | None = None
        #: The ``sensor/channel`` of :attr:`force_violation` (what the halt line names).
        self.force_violation_stream = ""
        self.valid_force_samples = 0
        self._robot_keys: dict[str, tuple[str, ...]] = {}
        #: Committed sensor samples and robot states so far (``sensor/ID``, ``robot/ID``):
        #: the ``/loop`` events carry them so that a replay cuts the streams where the run
        #: did (contract C of issue 17).
        self.counts: dict[str, int] = {}
        self._now_s = 0.0  # the latest sample or state time committed
        self._recorded_classes: dict[str, tuple[str, ...]] = {}
        # One aligner per consumer whose inputs run on different clocks: it keeps their
        # recent samples from tick to tick (a stream), so a run joins them as training does.
        self.aligners: dict[str, InputAligner] = {}
        for cid in self.extractors + self.classifiers:
            alignment = components[cid].input_alignment
            if alignment.method != "exact":
                self.aligners[cid] = InputAligner(alignment, cid)
        self._plan_sensor_models()
        for sensor_id in self.sensors:
            channels = components.sensors[sensor_id].channels
            for name, info in channels.items():
                recorder.set(f"sensor/{sensor_id}/{name}/unit", np.array(info.unit))
        #: The streamed sensors that have a force channel (unit ``N``).
        self.force_sensors = [
            i for i in self.sensors
            if any(info.unit == "N" for info in components.sensors[i].channels.values())
        ]
        #: The force streams the stall check watches, ``(component id, channel)``: what the
        #: classifiers consume (the nearest force channels upstream of each: a force
        #: observer's output, not the sensors it reads), else the force sensors' own; and
        #: the valid, finite samples committed on each (the check watches them grow).
        self.stall_streams = self._classified_force_streams() or [
            (i, name) for i in self.force_sensors
            for name, info in components.sensors[i].channels.items() if info.unit == "N"
        ]
        self.stall_counts = [0] * len(self.stall_streams)

    def _channels_of(self, cid: str) -> Mapping[str, Any] | None:
        if cid in self.sensors:
            return self.components.sensors[cid].channels
        if cid in self.extractors:
            return self.components.feature_extractors[cid].output_channels
        return None

    def _classified_force_streams(self) -> list[tuple[str, str]]:
        """For each classifier, the force channels (unit ``N``) nearest upstream of it: an
        input's own, or, for an extractor without one, those its inputs feed it."""
        streams: list[tuple[str, str]] = []

        def visit(cid: str, seen: set[str]) -> None:
            channels = self._channels_of(cid)
            if channels is None or cid in seen:
                return
            seen.add(cid)
            forces = [(cid, name) for name, info in channels.items() if info.unit == "N"]
            if not forces and cid in self.extractors:
                for upstream in self.entries[cid].inputs:
                    visit(upstream, seen)
            streams.extend(f for f in forces if f not in streams)

        for clf_id in self.classifiers:
            for cid in self.entries[clf_id].inputs:
                visit(cid, set())
        return streams

    def stall_arrivals(self, outputs: Mapping[str, SampleBatch]) -> list[NDArray[np.float64]]:
        """The timestamps of the valid, finite samples of each of :attr:`stall_streams` in
        ``outputs`` (what :meth:`read_and_classify` made)."""
        return [_usable_times(outputs[cid], name) for cid, name in self.stall_streams]

    @property
    def recording(self) -> RecordingWriter | None:
        """The run's ``run.mcap`` (:class:`~hapticframe.record._recording.RunRecording`), fed the
        same data as ``recorder`` as it happens; None when the run records none. Setting
        one configures its map snapshots' rate and writes the scene into it."""
        return self._recording

    @recording.setter
    def recording(self, recording: RecordingWriter | None) -> None:
        self._recording = recording
        if recording is not None:
            recording.configure_snapshots(self._snapshot_rate_hz)
            recording.scene(self.scene)

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
            own = [i for i in entry.inputs if self.entries[i].kind is Kind.SENSOR]
            for sensor_id in own + self.sensors:
                if "position_m" in self.components.sensors[sensor_id].channels:
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
        keys = self._robot_keys.get(robot_id)
        if keys is None:
            names = ("timestamps_s", "position_m", "heading_rad", "depth_m", "movement_index")
            keys = self._robot_keys[robot_id] = tuple(f"robot/{robot_id}/{n}" for n in names)
        add_row = self.recorder.add_row
        add_row(keys[0], state.timestamp_s)
        add_row(keys[1], state.position_m.tolist())
        add_row(keys[2], state.heading_rad)
        add_row(keys[3], state.depth_m)
        add_row(keys[4], movement_index)
        counts = self.counts
        key = keys[0][:-len("/timestamps_s")]
        counts[key] = counts.get(key, 0) + 1
        if state.timestamp_s > self._now_s:
            self._now_s = float(state.timestamp_s)
        if self.recording is not None:
            self.recording.robot_state(robot_id, state, movement_index)

    def _inputs(self, consumer: str, outputs: Mapping[str, SampleBatch]) -> SampleBatch:
        names = [i for i in self.entries[consumer].inputs if i in outputs]
        if not names:
            raise RunError(f"{consumer!r} has no sensor or feature input")
        if len(names) == 1:
            return outputs[names[0]]
        aligner = self.aligners.get(consumer)
        if aligner is not None:
            return aligner.push([outputs[i] for i in names])
        return _merge_exact([outputs[i] for i in names], consumer)

    def tick(self) -> bool:
        """Read every sensor once and push the samples through. True if any sample arrived."""
        return self.commit(*self.read_and_classify())

    def read_and_classify(
        self,
    ) -> tuple[dict[str, SampleBatch], dict[str, ClassProbabilities]]:
        """Read every sensor once and run the extractors and classifiers; record nothing.

        The first half of :meth:`tick`: a closed loop that looks ahead inspects the
        classifiers' output before it decides to keep the samples (:meth:`commit`) or to
        rewind the components that made them.
        """
        outputs: dict[str, SampleBatch] = {}
        sensors = self.components.sensors
        step_check = self.step_check
        for sensor_id in self.sensors:
            outputs[sensor_id] = batch = sensors[sensor_id].read()
            if step_check is not None:
                step_check.check(sensor_id, batch)
        extractors = self.components.feature_extractors
        for fe_id in self.extractors:
            outputs[fe_id] = extractors[fe_id].update(self._inputs(fe_id, outputs))
        classified: dict[str, ClassProbabilities] = {}
        classifiers = self.components.classifiers
        for clf_id in self.classifiers:
            classified[clf_id] = classifiers[clf_id].update(self._inputs(clf_id, outputs))
        return outputs, classified

    def commit(
        self, outputs: Mapping[str, SampleBatch], classified: Mapping[str, ClassProbabilities]
    ) -> bool:
        """Record what :meth:`read_and_classify` produced and route it to the sensor models
        and maps (the second half of :meth:`tick`). True if any sensor sample arrived."""
        arrived = False
        for sensor_id in self.sensors:
            batch = outputs[sensor_id]
            if len(batch):
                arrived = True
                key = f"sensor/{sensor_id}"
                self.counts[key] = self.counts.get(key, 0) + len(batch)
                last = float(batch.timestamps_s[-1])
                if last > self._now_s:
                    self._now_s = last
                self._record_batch("sensor", sensor_id, batch)
                self._track_force(self.components.sensors[sensor_id], batch)
                if sensor_id in self.poses:
                    self.poses[sensor_id].add_batch(batch)
        for fe_id in self.extractors:
            self._record_batch("feature_extractor", fe_id, outputs[fe_id])
        for k, times in enumerate(self.stall_arrivals(outputs)):
            self.stall_counts[k] += len(times)
        for clf_id in self.classifiers:
            probs = classified[clf_id]
            if len(probs):
                self.latest[clf_id] = probs
                self.recorder.add(f"classifier/{clf_id}/timestamps_s", probs.timestamps_s)
                self.recorder.add(f"classifier/{clf_id}/probabilities", probs.probabilities)
                if self.recording is not None:
                    self.recording.probabilities(clf_id, probs)
                if self._recorded_classes.get(clf_id) != probs.classes:
                    self._recorded_classes[clf_id] = probs.classes
                    self.recorder.set(f"classifier/{clf_id}/classes", np.array(probs.classes))
            self._observe(clf_id, probs)
        return arrived

    def holds_interaction(self, classified: Mapping[str, ClassProbabilities]) -> bool:
        """True if any row of the primary classifier's output is not its background class
        (the rows :meth:`interaction_detected` would have seen one tick at a time)."""
        clf = self.primary_classifier
        probs = classified.get(clf) if clf is not None else None
        if probs is None or not len(probs):
            return False
        return bool(np.any(np.argmax(probs.probabilities, axis=1) != 0))

    def checkpoint(self) -> dict[str, Any]:
        """The aligners' kept samples, taken with the rewindable components' snapshots."""
        state: dict[str, Any] = {
            cid: aligner.checkpoint() for cid, aligner in self.aligners.items()
        }
        if self.step_check is not None:
            state[_STEP_CHECK] = self.step_check.checkpoint()
        return state

    def rewind(self, checkpoint: Mapping[str, Any]) -> None:
        """Return the aligners (and the clock check) to a :meth:`checkpoint`."""
        for cid, state in checkpoint.items():
            if cid == _STEP_CHECK:
                if self.step_check is not None:
                    self.step_check.rewind(state)
            else:
                self.aligners[cid].rewind(state)

    @property
    def rewindable(self) -> list[str]:
        """The components a look-ahead batch changes: streamed sensors, extractors and
        classifiers (sensor models and maps see only committed samples)."""
        return self.sensors + self.extractors + self.classifiers

    def _observe(self, clf_id: str, probs: ClassProbabilities) -> None:
        if not len(probs):
            return
        if probs.timestamps_s[0] < self.movement_start_s:
            # Samples from before the movement began (a robot's transit to its start, when
            # the fingertip is out of the sand) are not located: no pose of the movement
            # describes them.
            keep = probs.timestamps_s >= self.movement_start_s
            if not keep.any():
                return
            probs = ClassProbabilities(
                probs.timestamps_s[keep], probs.probabilities[keep], probs.classes
            )
        for sm_id in self.sensor_models:
            if self.sm_classifier[sm_id] != clf_id:
                continue
            poses = self.poses[self.sm_pose_source[sm_id]]
            positions, headings, depths = poses.at(probs.timestamps_s)
            # probs passed its checks when the classifier made it; the poses are built here.
            located = LocatedMeasurement._from_checked(probs, positions, headings, depths)
            obs = self.components.sensor_models[sm_id].observe(located)
            if self.recording is not None:
                self.recording.located(sm_id, located)
            if len(obs):
                self.recorder.add(f"sensor_model/{sm_id}/points_m", obs.points_m)
                self.recorder.add(f"sensor_model/{sm_id}/targets", obs.targets)
                self.recorder.add(f"sensor_model/{sm_id}/weights", obs.weights)
                if self.recording is not None:
                    self.recording.observations(sm_id, obs, float(probs.timestamps_s[-1]))
                for map_id in self.maps:
                    if sm_id in self.entries[map_id].inputs:
                        self.pending[map_id].append(obs)

    def loop_event(self, event: str, t_s: float | None = None, keep_force: bool = False) -> None:
        """Record ``/loop`` (``stream_start``, ``locate_from``, ``flush_maps``) with the
        counts committed so far; nothing without a recording."""
        if self.recording is None:
            return
        when = self._now_s if t_s is None else float(t_s)
        self.recording.later(LOOP.name, LOOP.schema, {
            "event": event, "t_s": when, "counts": dict(self.counts),
            "keep_force": keep_force}, when)

    def flush_maps(self) -> None:
        """Fuse pending observations into their maps."""
        self.loop_event("flush_maps")
        for map_id, parts in self.pending.items():
            if parts:
                merged = Observations.concatenate(parts)
                self.pending[map_id] = []
                self.components.maps[map_id].update(merged)
                self._maps_changed = True
        self.snapshot_maps()

    def snapshot_maps(self, *, final: bool = False) -> None:
        """Write the maps into the recording when a snapshot is due (``run.snapshot_rate_hz``
        of model time), or, ``final``, when they changed since the last one (the end of the
        run: the last state of the maps is never left out by the rate)."""
        recording = self._recording
        if recording is None:
            return
        if final:
            if not self._maps_changed or recording.snapshot_rate_hz <= 0:
                return
        elif not self._within_snapshot_budget() or not recording.snapshot_due():
            return
        self._maps_changed = False
        started = time.process_time()
        for map_id in self.maps:
            recording.map_snapshot(MapSnapshot.of(
                map_id, self.components.maps[map_id], recording.now_s,
                self._snapshot_spacing_m, self._outline_level, self._snapshot_max_cells))
        self._last_snapshot_cpu_s = time.process_time() - started
        self._snapshot_cpu_s += self._last_snapshot_cpu_s

    def _within_snapshot_budget(self) -> bool:
        """True while the snapshots so far, and one more costing as much as the last, take
        at most ``run.snapshot_cpu_share`` of the run's CPU time: a large map's snapshot
        (every changed tile's covariance) would otherwise cost a share of the run that
        grows with the region."""
        elapsed = time.process_time() - self._cpu_start_s
        planned = self._snapshot_cpu_s + self._last_snapshot_cpu_s
        return planned <= self._snapshot_cpu_share * elapsed

    def _record_batch(self, kind: str, cid: str, batch: SampleBatch) -> None:
        if not len(batch):
            return
        self.recorder.add(f"{kind}/{cid}/timestamps_s", batch.timestamps_s)
        for name, array in batch.channels.items():
            self.recorder.add(f"{kind}/{cid}/{name}", array)
        if self.recording is not None:
            units = rates = None
            if kind == "sensor":
                channels = self.components.sensors[cid].channels
                units = {n: i.unit for n, i in channels.items()}
                rates = {n: i.rate_hz for n, i in channels.items()}
            self.recording.samples(kind, cid, batch, units, rates)

    def _track_force(self, sensor: Sensor, batch: SampleBatch) -> None:
        """The largest finite force magnitude (``force_max_n``), and for safety the valid
        samples: counted, and the first above ``force_limit_n`` kept (``force_violation``)."""
        n = len(batch)
        if not n:
            return
        limit = self.force_limit_n
        for name, info in sensor.channels.items():
            if info.unit == "N":
                values = batch.channels[name]
                valid = batch.valid.get(name)
                if n == 1 and 1 <= values.size <= 2:
                    # One sample of at most two components (a closed loop's force reading):
                    # the same sum of squares and square root in plain floats.
                    squares = [v * v for v in values.ravel().tolist()]
                    norm = math.sqrt(squares[0] + squares[1] if len(squares) == 2 else squares[0])
                    if math.isfinite(norm):
                        self.force_max_n = (
                            norm if math.isnan(self.force_max_n) else max(self.force_max_n, norm)
                        )
                        if valid is None or bool(valid[0]):
                            self.valid_force_samples += 1
                            if limit is not None and norm > limit:
                                self._note_violation(float(batch.timestamps_s[0]), norm,
                                                     f"{sensor.id}/{name}")
                    continue
                values = values.reshape(n, -1)
                norms = np.linalg.norm(values, axis=1)
                usable = np.isfinite(norms)
                finite = norms[usable]
                if finite.size:
                    self.force_max_n = float(np.fmax(self.force_max_n, finite.max()))
                if valid is not None:
                    usable &= valid
                self.valid_force_samples += int(np.count_nonzero(usable))
                if limit is not None:
                    over = np.flatnonzero(usable & (norms > limit))
                    if over.size:
                        first = int(over[0])
                        self._note_violation(float(batch.timestamps_s[first]),
                                             float(norms[first]), f"{sensor.id}/{name}")

    def _note_violation(self, timestamp_s: float, force_n: float, stream: str) -> None:
        # The earliest violating sample of a commit (sensors are committed one by one).
        if self.force_violation is None or timestamp_s < self.force_violation[0]:
            self.force_violation = (timestamp_s, force_n)
            self.force_violation_stream = stream

    def take_force_violation(self) -> tuple[float, float] | None:
        """The first valid force sample above the limit committed since the last call (or
        since the movement began): ``(timestamp_s, magnitude_n)``; None when there was none."""
        violation, self.force_violation = self.force_violation, None
        return violation

    def valid_force(
        self, outputs: Mapping[str, SampleBatch]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The timestamps and magnitudes of the valid, finite force samples in ``outputs``
        (what :meth:`read_and_classify` read), in time order; what a look-ahead batch is
        checked against before it is committed."""
        times: list[NDArray[np.float64]] = []
        norms: list[NDArray[np.float64]] = []
        for sensor_id in self.force_sensors:
            batch = outputs[sensor_id]
            n = len(batch)
            if not n:
                continue
            for name, info in self.components.sensors[sensor_id].channels.items():
                if info.unit != "N":
                    continue
                magnitude = np.linalg.norm(batch.channels[name].reshape(n, -1), axis=1)
                usable = np.isfinite(magnitude)
                valid = batch.valid.get(name)
                if valid is not None:
                    usable &= valid
                times.append(batch.timestamps_s[usable])
                norms.append(magnitude[usable])
        if not times:
            return np.empty(0), np.empty(0)
        t, f = np.concatenate(times), np.concatenate(norms)
        order = np.argsort(t, kind="stable")
        return t[order], f[order]

    def start_stream(self, keep_force: bool = False) -> None:
        """A new movement starts a new stream: forget classifier and feature state (and the
        movement's largest force, unless ``keep_force``: the same movement goes on)."""
        self.loop_event("stream_start", keep_force=keep_force)
        self.movement_start_s = -math.inf
        self.latest.clear()
        if not keep_force:
            self.force_max_n = float("nan")
        self.force_violation = None
        for cid in self.extractors + self.classifiers:
            self.components[cid].reset()
        for aligner in self.aligners.values():
            aligner.reset()

    def locate_from(self, start_s: float) -> None:
        """The current movement (part) began at ``start_s``: classifier outputs timestamped
        before it (read during the robot's transit to the start) reach no sensor model."""
        self.movement_start_s = float(start_s)
        self.loop_event("locate_from", t_s=self.movement_start_s)

    def interaction_detected(self) -> str | None:
        """The class name if the primary classifier's latest sample is not background."""
        clf = self.primary_classifier
        if clf is None or clf not in self.latest:
            return None
        label = _last_label(self.latest[clf])
        return self.latest[clf].classes[label] if label != 0 else None

    def latest_class(self) -> str:
        clf = self.primary_classifier
        if clf is None or clf not in self.latest:
            return ""
        probs = self.latest[clf]
        return probs.classes[_last_label(probs)]


def _last_label(probs: ClassProbabilities) -> int:
    """``int(probs.labels[-1])`` without an arg-max over every row: the first largest entry
    of the last row (rows are finite, checked by the record)."""
    row: list[float] = probs.probabilities[-1].tolist()
    return row.index(max(row))


_NO_TIMES: NDArray[np.float64] = np.empty(0)


def _usable_times(batch: SampleBatch, channel: str) -> NDArray[np.float64]:
    """The timestamps of ``batch``'s valid samples of ``channel`` whose values are finite."""
    n = len(batch)
    if not n:
        return _NO_TIMES
    values = batch.channels[channel]
    valid = batch.valid.get(channel)
    if n == 1 and values.size <= 3:  # a closed loop's one sample: plain floats are faster
        ok = all(math.isfinite(v) for v in values.ravel().tolist())
        return batch.timestamps_s if ok and (valid is None or bool(valid[0])) else _NO_TIMES
    usable = np.all(np.isfinite(values.reshape(n, -1)), axis=1)
    if valid is not None:
        usable &= valid
    return np.asarray(batch.timestamps_s[usable], dtype=np.float64)
