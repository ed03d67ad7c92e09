"""``hapticframe replay``: a recorded run's perception and mapping, re-run offline.

The ``--with`` experiment's feature extractors, classifiers, sensor models and maps are
built as a run builds them; its sensors become ``recording`` sensors of the same ids, fed
from the recording's ``/sensor/ID`` channels; no robot, planner or simulator is built. The
same :class:`~hapticframe.run._dataflow.Dataflow` a run drives is driven by the recording's
``/loop`` events (contract C of issue 17), in the order the run made them: before each,
the robot states and sensor samples the run had committed by then (the event's cumulative
counts) are pushed, in one tick, then the event is applied (a new stream, a locate, a map
update). So the sensor models and maps see what they saw in the run, whatever the sizes
of the run's look-ahead batches. The recorded movements (``/movement``) become the
:class:`~hapticframe.kinds.MovementResult` s the rebuilt components and the scoring see:
the planner's decisions are not re-made.

``metrics.json``: the core's scores recomputed (map vs scene, labels, forces), the rebuilt
components' own ``finalize`` metrics, and the recorded metrics of every component not
rebuilt (robots, the planner, the replaced sensors: the run's ``/metrics``), listed in
``run.json`` (``details.carried_metrics``).
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe._config import ComponentEntry, Experiment
from hapticframe._errors import RunError, UsageError
from hapticframe._kind import Kind
from hapticframe.kinds import ExploratoryMovement, MovementResult, RobotState
from hapticframe.record._recording import (
    _check_magic,
    _records,
    decode_message,
    find_recording,
    open_run_recording,
)
from hapticframe.run._assembly import LEAVE_OUT, Substitute, build_components
from hapticframe.run._channels import LOOP, METRICS, MOVEMENT, ROBOT_STATE, SENSOR
from hapticframe.run._components import Components
from hapticframe.run._dataflow import Dataflow
from hapticframe.run._evaluate import score_run
from hapticframe.run._results import RunSummary
from hapticframe.run._robots import share_poses
from hapticframe.run._safety import OUTSIDE_WORKSPACE
from hapticframe.run._scope import CloseErrorHandler, run_scope
from hapticframe.run._session import Session
from hapticframe.run._train import fit_before_run

__all__ = ["Recorded", "read_timeline", "replay_run", "replay_warnings"]

_log = logging.getLogger("hapticframe.replay")

#: The kinds a replay rebuilds from the ``--with`` experiment (sensors become recordings).
REBUILT = (Kind.FEATURE_EXTRACTOR, Kind.CLASSIFIER, Kind.SENSOR_MODEL, Kind.MAP)
#: Metrics about the robots and devices, not a component's own: carried from the run.
CARRIED_KEYS = ("halt_latency_samples_max", "devices")


@dataclass
class Recorded:
    """What a replay reads from a recording."""

    path: Path
    #: ``/loop`` and ``/movement`` messages in the order the run wrote them.
    timeline: list[tuple[str, dict[str, Any]]] = field(default_factory=list)
    #: Robot states by robot id: time, x, y, heading, depth (columns), movement index.
    robots: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    #: Every recorded topic (sensor channels: ``/sensor/ID``).
    topics: set[str] = field(default_factory=set)
    #: The run's ``/metrics`` (None for a cut recording).
    metrics: dict[str, Any] | None = None
    metadata: dict[str, str] = field(default_factory=dict)
    cut: str = ""


def read_timeline(path: Path) -> Recorded:
    """Read ``path`` (complete or cut) as a stream, keeping the order of its events."""
    from mcap.records import Channel, Message, Metadata

    _check_magic(path)
    stop: list[str] = []
    out = Recorded(path)
    channels: dict[int, str] = {}
    rows: dict[str, list[dict[str, Any]]] = {}
    for record in _records(path, stop):
        if isinstance(record, Channel):
            channels[record.id] = record.topic
            out.topics.add(record.topic)
        elif isinstance(record, Metadata) and record.name == "hapticframe":
            out.metadata = dict(record.metadata)
        elif isinstance(record, Message) and record.channel_id in channels:
            topic = channels[record.channel_id]
            if topic in (LOOP.name, MOVEMENT.name):
                out.timeline.append((topic, decode_message(record.data)))
            elif topic == METRICS.name:
                out.metrics = decode_message(record.data)
            elif (robot_id := ROBOT_STATE.id_of(topic)) is not None:
                rows.setdefault(robot_id, []).append(decode_message(record.data))
    out.cut = stop[0] if stop else ""
    for robot_id, messages in rows.items():
        def column(name: str, messages: list[dict[str, Any]] = messages) -> np.ndarray:
            return np.concatenate([np.asarray(m[name], dtype=np.float64).reshape(
                len(m["timestamps_s"]), -1) for m in messages])
        poses = np.hstack([column("timestamps_s"), column("positions_m"),
                           column("headings_rad"), column("depths_m")])
        index = column("movement_index").reshape(-1).astype(np.int64)
        out.robots[robot_id] = (poses, index)
    return out


def _recorded_sensor_error(path: Path, missing: list[str], topics: set[str]) -> UsageError:
    held = sorted(i for t in topics if (i := SENSOR.id_of(t)) is not None)
    return UsageError(
        f"{path} has no recorded samples of sensor{'s' if len(missing) > 1 else ''} "
        f"{', '.join(repr(m) for m in missing)}; it holds "
        f"{', '.join(repr(h) for h in held) or 'no sensor channels'}: give the --with "
        "experiment sensors of those ids (their type is replaced by the recording)")


def build_replay_components(
    experiment: Experiment, recording: Path, stack: ExitStack, training: frozenset[str],
    progress: bool = True, on_close_error: CloseErrorHandler | None = None,
) -> Components:
    """The ``--with`` experiment's perception chain, its streamed sensors as ``recording``
    sensors of the same ids (training sensors as they are); ``stack`` closes them."""
    registry = experiment.registry
    spec = registry.get(Kind.SENSOR, "recording") if "recording" in registry.names(
        Kind.SENSOR) else None

    def choose(entry: ComponentEntry) -> Substitute | str | None:
        if entry.kind is Kind.SENSOR and entry.id not in training:
            if spec is None:
                raise RunError("the 'recording' sensor (hapticframe_recording) is not "
                               "installed; reinstall hapticframe")
            config: Any = spec.spec.config.model_validate(
                {"file": str(recording), "topic": SENSOR.topic(entry.id)})
            return Substitute(spec.spec.load_factory(), config, "recording")
        if entry.kind in REBUILT or entry.kind is Kind.SENSOR:
            return None  # as configured
        return LEAVE_OUT  # robots, planners: their recorded movements stand in for them

    if on_close_error is None:
        return build_components(experiment, stack, progress=progress, choose=choose,
                                purpose=" for the replay")
    return build_components(experiment, stack, progress=progress, choose=choose,
                            purpose=" for the replay", on_close_error=on_close_error)


def _state(row: np.ndarray) -> RobotState:
    return RobotState(float(row[0]), row[1:3].copy(), float(row[3]), float(row[4]))


class _Replayer:
    """Drives a :class:`Dataflow` through the recorded ``/loop`` events."""

    def __init__(self, session: Session, flow: Dataflow, recorded: Recorded) -> None:
        self.session = session
        self.flow = flow
        self.recorded = recorded
        self.pushed: dict[str, int] = {}
        self.sensors = {sid: session.components.sensors[sid] for sid in flow.sensors}

    def push(self, counts: Mapping[str, int]) -> None:
        """Robot states, then one tick of sensor samples, up to the run's counts."""
        for robot_id, (poses, index) in self.recorded.robots.items():
            done = self.pushed.get(robot_id, 0)
            until = min(int(counts.get(f"robot/{robot_id}", 0)), len(poses))
            for k in range(done, until):
                self.flow.record_robot_state(robot_id, _state(poses[k]), int(index[k]))
            self.pushed[robot_id] = max(done, until)
        due = False
        for sensor_id, sensor in self.sensors.items():
            until = int(counts.get(f"sensor/{sensor_id}", 0))
            sensor.deliver_until(until)  # type: ignore[attr-defined]
            due = due or until > sensor.delivered  # type: ignore[attr-defined]
        if due:
            self.flow.tick()

    def run(self) -> None:
        flow, session = self.flow, self.session
        for topic, data in self.recorded.timeline:
            if topic == MOVEMENT.name:
                self.movement(data)
                continue
            self.push(data.get("counts") or {})
            event = data.get("event")
            if event == "stream_start":
                flow.start_stream(keep_force=bool(data.get("keep_force")))
            elif event == "locate_from":
                t_s = data.get("t_s")
                flow.locate_from(-math.inf if t_s is None else float(t_s))
            elif event == "flush_maps":
                flow.flush_maps()
        flow.snapshot_maps(final=True)  # as the run loop ends
        if not session.movements:  # an open loop: its force over the whole run
            _note_force(session, flow.force_max_n)

    def movement(self, data: Mapping[str, Any]) -> None:
        session, flow = self.session, self.flow
        index = int(data["index"])
        movement = ExploratoryMovement(
            start_m=np.asarray(data["start_m"], dtype=np.float64),
            end_m=np.asarray(data["end_m"], dtype=np.float64),
            speed_m_per_s=float(data.get("speed_m_per_s", 0.05)),
            depth_m=data.get("depth_m"), phase=str(data.get("phase", "")),
            label=str(data.get("label", "")))
        extra = dict(data.get("extra") or {})
        refused = data.get("halt_reason") == OUTSIDE_WORKSPACE and "refused" in extra
        if "robots" in extra and isinstance(extra["robots"], list):
            extra["robots"] = tuple(extra["robots"])
        result = MovementResult(
            index=index, movement=movement, halted=bool(data["halted"]),
            halt_reason=str(data["halt_reason"]), final_state=self.final_state(data),
            final_class="" if refused else flow.latest_class(),
            max_force_n=math.nan if refused else flow.force_max_n, extra=extra)
        session.movements.append(result)
        if session.recording is not None:
            session.recording.movement(result)
        if not refused:
            _note_force(session, flow.force_max_n)
        for component in session.components.values():
            component.on_movement_end(result)

    def final_state(self, data: Mapping[str, Any]) -> RobotState | None:
        """The robot state the movement ended in: the last one pushed (of the robot at the
        recorded final position), else one at the recorded final position."""
        final = data.get("final_position_m")
        if final is None:
            return None
        target = np.asarray(final, dtype=np.float64)
        for robot_id, (poses, _) in self.recorded.robots.items():
            done = self.pushed.get(robot_id, 0)
            if done and np.array_equal(poses[done - 1, 1:3], target):
                return _state(poses[done - 1])
        return RobotState(math.nan, target, math.nan)


def _note_force(session: Session, force_n: float) -> None:
    if not math.isnan(force_n):
        previous = session.max_measured_force_n
        session.max_measured_force_n = force_n if math.isnan(previous) else max(previous, force_n)


def replay_warnings(recorded: Recorded, experiment: Experiment,
                    training: frozenset[str]) -> list[str]:
    """What makes the replay's figures differ from a rerun of the recorded run: a cut
    recording, a streamed sensor the ``--with`` experiment names another type than the
    recorded run did, another scene (the figures are scored against the ``--with`` one)."""
    warnings = []
    if recorded.cut:
        warnings.append(f"{recorded.path} is cut ({recorded.cut}): the replay covers only "
                        "the movements it holds, and its figures are those of a shorter run")
    try:
        config = json.loads(recorded.metadata.get("config", ""))
    except ValueError:
        config = None
    if not isinstance(config, dict):
        return warnings
    resolved = experiment.resolved_config()
    recorded_types = {s.get("id"): s.get("type") for s in config.get("sensors") or []
                      if isinstance(s, dict)}
    for entry in experiment.of_kind(Kind.SENSOR):
        was = recorded_types.get(entry.id)
        if entry.id not in training and was is not None and was != entry.type:
            warnings.append(
                f"sensor {entry.id!r} was a {was!r} in the recorded run, the --with "
                f"experiment names a {entry.type!r}: its recorded samples stand in for it, "
                "and the chain built for the other type reads them")
    if "scene" in config and config.get("scene") != resolved.get("scene"):
        warnings.append("the --with experiment's scene is not the recorded run's: the "
                        "replay is scored against the --with scene")
    return warnings


def _carried(recorded: Recorded, rebuilt: set[str], metrics: dict[str, Any]
             ) -> dict[str, Any]:
    """The run's metrics of components not rebuilt, and of robots and devices."""
    if recorded.metrics is None:
        return {}
    carried: dict[str, Any] = {}
    for cid, own in (recorded.metrics.get("components") or {}).items():
        if cid in rebuilt:
            continue
        for key, value in own.items():
            if key not in metrics:
                carried[key] = value
    for key in CARRIED_KEYS:
        run_metrics = recorded.metrics.get("metrics") or {}
        if key in run_metrics and key not in metrics:
            carried[key] = run_metrics[key]
    return carried


def replay_run(
    source: str | Path,
    experiment: Experiment,
    out_dir: str | Path,
    *,
    overwrite: bool = False,
    echo: Callable[[str], None] | None = None,
    progress: bool = True,
    min_free_bytes: int | None = None,
) -> RunSummary:
    """Replay the recording ``source`` (a run's directory or its ``run.mcap``) through the
    perception and mapping chain of ``experiment``, writing results into ``out_dir`` as a
    run does (the same run scope: :func:`~hapticframe.run._scope.run_scope`).

    Raises
    ------
    UsageError
        (exit status 2) ``source`` is no recording, holds no ``/loop`` events, or lacks a
        sensor the experiment streams; ``out_dir`` is (or holds) the recording or the
        experiment file.
    ExperimentError, RunError, OutputError
        As :func:`~hapticframe.run._run.run_experiment`.
    """
    say = echo if echo is not None else (lambda _text: None)
    path = find_recording(Path(source))
    recorded = read_timeline(path)
    if not any(topic == LOOP.name for topic, _ in recorded.timeline):
        raise UsageError(
            f"{path} holds no /loop events: it was recorded before replay was possible, or "
            "cut before its first movement; record the run again with this version")
    training = frozenset(experiment.model.run.train_from.values())
    missing = [e.id for e in experiment.of_kind(Kind.SENSOR)
               if e.id not in training and SENSOR.topic(e.id) not in recorded.topics]
    if missing:
        raise _recorded_sensor_error(path, missing, recorded.topics)
    warnings = replay_warnings(recorded, experiment, training)
    for warning in warnings:  # the CLI prints them as `warning: ...` lines
        _log.warning("%s", warning)
    started_utc = datetime.now(timezone.utc).isoformat(timespec="seconds")
    head = {"status": "running", "command": "replay", "replayed_from": str(path),
            "experiment_file": str(experiment.file), "started_utc": started_utc}
    metrics: dict[str, Any] = {}
    with run_scope(out_dir, head, what="replay", overwrite=overwrite,
                   min_free_bytes=min_free_bytes, started_utc=started_utc,
                   inputs=(path, Path(source), experiment.file)) as scope:
        components = scope.build(lambda stack, on_close_error: build_replay_components(
            experiment, path, stack, training, progress, on_close_error))
        session = scope.start_session(experiment, say, recording=open_run_recording)
        session.details["replayed_from"] = str(path)
        if recorded.cut:
            session.details["replayed_cut"] = recorded.cut
        if warnings:
            session.details["replay_warnings"] = warnings
        fit_before_run(session)
        flow = Dataflow(experiment, components, session.recorder, training)
        flow.recording = session.recording
        robot_ids = [e.id for e in experiment.of_kind(Kind.ROBOT)]
        if len(robot_ids) > 1:
            share_poses(flow, robot_ids)
        _Replayer(session, flow, recorded).run()
        say(f"replayed {len(session.movements)} movements of {path}")
        metrics = score_run(session)
        # Replaced sensors count as not rebuilt: their own metrics are the run's.
        rebuilt = {cid for cid in components
                   if cid in training or cid not in components.sensors}
        carried = _carried(recorded, rebuilt, metrics)
        wall = metrics.pop("wall_time_s")
        metrics.update(carried)
        metrics["wall_time_s"] = wall
        session.details["carried_metrics"] = sorted(carried)
        if recorded.metrics is not None:
            # The replay's own /metrics carries them on: it replays the same.
            for cid, own in (recorded.metrics.get("components") or {}).items():
                if cid not in rebuilt:
                    session.component_metrics[cid] = dict(own)
        scope.save(metrics)
    summary = RunSummary(metrics, scope.out)
    return summary
