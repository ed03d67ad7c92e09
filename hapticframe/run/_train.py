"""``hapticframe train``: fit an experiment's trainable components on its recordings.

The experiment's sensors must be finite (synthetic trials, recordings). Their recordings
(trials) flow through the components in build order: each feature extractor is fitted on
its inputs (joined as :attr:`~hapticframe.kinds.Component.input_alignment` says, as the run
joins them) and then transforms them; each classifier is fitted on its inputs with labels
taken from the sensors' label channel (``run.label_channel``, default ``contact``) at the
classifier inputs' timestamps. Sensor models that learn from calibration recordings
(:class:`~hapticframe.kinds.TrainableSensorModel`) are fitted last, on the recorded runs of
``run.calibration_runs`` (:func:`fit_sensor_models`). Components that are
:class:`~hapticframe.kinds.Persistent` write their artifacts into ``DIR/<component id>/``,
and ``DIR/train.json`` records the seed, versions, plugins, the resolved config and the
report of each :class:`~hapticframe.kinds.Trainable` component. ``train.json`` says
``status: running`` from before the build until the artifacts are in place: they are saved
into a staging folder and moved into ``DIR`` together (see
:func:`~hapticframe.run._scope.run_scope`).

This module uses :mod:`~hapticframe.run._assembly` and :mod:`~hapticframe.run._results`; the run
(:mod:`~hapticframe.run._run`) uses it to fit before its loop, never the other way round.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hapticframe._config import Experiment
from hapticframe._errors import HapticframeError, RunError, UsageError
from hapticframe._kind import Kind
from hapticframe.calibration import read_calibration_run
from hapticframe.kinds import (
    CalibrationRecording,
    Component,
    Persistent,
    SampleBatch,
    Trainable,
    TrainableSensorModel,
)
from hapticframe.run._assembly import build_components
from hapticframe.run._components import Components
from hapticframe.run._results import environment
from hapticframe.run._scope import RunScope, run_scope
from hapticframe.run._streams import merge_batches

if TYPE_CHECKING:
    from hapticframe.run._session import Session

__all__ = [
    "collect_recordings",
    "fit_before_run",
    "fit_components",
    "fit_sensor_models",
    "labels_at",
    "train_experiment",
    "training_reports",
]

_log = logging.getLogger("hapticframe.train")


def labels_at(times_s: np.ndarray, source: SampleBatch, channel: str) -> np.ndarray:
    """Integer labels of ``source[channel]`` at ``times_s`` (the latest sample not after each)."""
    if channel not in source.channels:
        raise RunError(
            f"the recordings carry no label channel {channel!r} (channels: "
            f"{', '.join(source.channels)}); set run.label_channel"
        )
    values = source.channels[channel].reshape(len(source), -1)[:, 0]
    index = np.searchsorted(source.timestamps_s, times_s, side="right") - 1
    if len(index) and (index.min() < 0 or index.max() >= len(values)):
        raise RunError("classifier inputs lie outside the time span of their recording")
    labels = values[index]
    if not np.all(np.isfinite(labels)):
        raise RunError(f"label channel {channel!r} holds NaN at some training samples")
    return np.rint(labels).astype(np.int64)


def collect_recordings(
    components: Components, sources: Mapping[str, str]
) -> list[dict[str, SampleBatch]]:
    """The recordings (trials) of finite sensors, one dict per trial.

    ``sources`` maps the sensor id the recordings stand in for to the id of the sensor that
    delivers them; every source must deliver the same number of recordings.
    """
    if not sources:
        raise UsageError("nothing to train on: the experiment has no sensors")
    per_sensor = {
        target: list(components.sensors[source].iter_recordings())
        for target, source in sources.items()
    }
    counts = {sid: len(recs) for sid, recs in per_sensor.items()}
    if len(set(counts.values())) != 1:
        raise RunError(f"sensors deliver different numbers of recordings: {counts}")
    count = next(iter(counts.values()))
    if count == 0:
        raise RunError("the training sensors delivered no recordings")
    return [{sid: recs[i] for sid, recs in per_sensor.items()} for i in range(count)]


def training_reports(
    components: Mapping[str, Component], trained: Sequence[str]
) -> dict[str, Any]:
    """The :meth:`~hapticframe.kinds.Trainable.training_report` of each fitted component
    that is :class:`~hapticframe.kinds.Trainable` (None for one that is not)."""
    reports: dict[str, Any] = {}
    for cid in trained:
        component = components[cid]
        if isinstance(component, Trainable):
            with _located(cid, type(component).__name__, "reading the training report of"):
                reports[cid] = dict(component.training_report())
        else:
            reports[cid] = None
    return reports


def fit_components(
    experiment: Experiment,
    components: Components,
    recordings: list[dict[str, SampleBatch]],
    label_channel: str,
    echo: Callable[[str], None] = _log.info,
) -> list[str]:
    """Fit the feature extractors and classifiers in build order; the ids fitted.

    Each feature extractor is fitted on its inputs and then transforms them for the
    components after it; each classifier is fitted with labels from ``label_channel``.
    ``recordings`` is extended in place with every extractor's output.
    """
    sensor_ids = [e.id for e in experiment.of_kind(Kind.SENSOR) if e.id in recordings[0]]
    trained: list[str] = []
    for entry in experiment.components:
        if entry.kind not in (Kind.FEATURE_EXTRACTOR, Kind.CLASSIFIER):
            continue
        names = [i for i in entry.inputs if i in recordings[0]]
        if not names:
            continue  # reads nothing that was recorded: left as configured
        # Aligned as the run aligns them: each recording is one stream.
        alignment = components[entry.id].input_alignment
        inputs = [merge_batches([rec[i] for i in names], entry.id, alignment)
                  for rec in recordings]
        echo(f"fitting {entry.id} ({entry.type})")
        if entry.kind is Kind.FEATURE_EXTRACTOR:
            extractor = components.feature_extractors[entry.id]
            with _located(entry.id, entry.type):
                extractor.fit(inputs)
            for rec, batch in zip(recordings, inputs, strict=True):
                rec[entry.id] = extractor.transform(batch)
        else:
            labels = [
                labels_at(batch.timestamps_s, _label_source(rec, sensor_ids, label_channel),
                          label_channel)
                for rec, batch in zip(recordings, inputs, strict=True)
            ]
            with _located(entry.id, entry.type):
                components.classifiers[entry.id].fit(inputs, labels)
        trained.append(entry.id)
    return trained


def fit_sensor_models(
    experiment: Experiment,
    components: Components,
    run_dirs: Sequence[str],
    echo: Callable[[str], None] = _log.info,
) -> list[str]:
    """Fit every sensor model that is a :class:`~hapticframe.kinds.TrainableSensorModel` on
    the calibration runs ``run_dirs``; the ids fitted.

    Each run is read with :func:`~hapticframe.read_calibration_run`: the robot the sensor
    model names among its inputs (else the trace's only robot), the classes that the
    classifier it names among its inputs reported during the run (else, in a simulation,
    the world's true states), and the run's scene. Without ``run_dirs`` nothing is fitted.

    Raises
    ------
    UsageError
        A run that is no calibration recording (naming ``run.calibration_runs[i]``), or
        runs given to an experiment with no trainable sensor model.
    """
    trainable = [e for e in experiment.of_kind(Kind.SENSOR_MODEL)
                 if isinstance(components.sensor_models[e.id], TrainableSensorModel)]
    if not run_dirs:
        return []
    if not trainable:
        models = [f"{e.id} ({e.type})" for e in experiment.of_kind(Kind.SENSOR_MODEL)]
        raise UsageError(
            "run.calibration_runs: no sensor model of the experiment learns from calibration "
            f"recordings (sensor models: {', '.join(models) or 'none'})")
    classifiers = {e.id for e in experiment.of_kind(Kind.CLASSIFIER)}
    robots = {e.id for e in experiment.of_kind(Kind.ROBOT)}
    fitted: list[str] = []
    for entry in trainable:
        classifier = next((i for i in entry.inputs if i in classifiers), None)
        robot = next((i for i in entry.inputs if i in robots), None)
        recordings: list[CalibrationRecording] = []
        for i, run_dir in enumerate(run_dirs):
            try:
                recordings.append(read_calibration_run(run_dir, robot, classifier))
            except ValueError as exc:
                raise UsageError(f"run.calibration_runs[{i}]: {exc}") from None
        echo(f"fitting {entry.id} ({entry.type}) on {len(recordings)} calibration runs "
             f"({sum(len(r) for r in recordings)} samples; classes from "
             f"{'classifier ' + repr(classifier) if classifier else 'the true states'})")
        model = components.sensor_models[entry.id]
        assert isinstance(model, TrainableSensorModel)  # chosen so above
        with _located(entry.id, entry.type):
            model.fit(recordings)
        fitted.append(entry.id)
    return fitted


def fit_before_run(session: Session) -> None:
    """Fit feature extractors and classifiers on the training sensors' recordings
    (``run.train_from``) before a run or replay; ``run.json`` records it
    (``details.training``)."""
    sources = session.settings.train_from
    if not sources:
        return
    started = time.perf_counter()
    recordings = collect_recordings(session.components, sources)
    session.echo(
        f"fitting before the run on {len(recordings)} recordings of "
        f"{', '.join(sorted(set(sources.values())))}"
    )
    trained = fit_components(session.experiment, session.components, recordings,
                             session.settings.label_channel, session.echo)
    session.details["training"] = {
        "recordings": len(recordings),
        "trained": trained,
        "reports": training_reports(session.components, trained),
        "wall_time_s": time.perf_counter() - started,
    }


@contextmanager
def _located(component_id: str, type_name: str, doing: str = "fitting") -> Iterator[None]:
    """Name the component whose ``fit`` failed (a plugin's error says what, not where)."""
    try:
        yield
    except HapticframeError:
        raise
    except Exception as exc:
        raise RunError(f"{doing} {component_id} ({type_name}) failed: "
                       f"{type(exc).__name__}: {exc}") from exc


def train_experiment(
    experiment: Experiment,
    out_dir: str | Path,
    *,
    overwrite: bool = False,
    echo: Callable[[str], None] = _log.info,
    min_free_bytes: int | None = None,
) -> dict[str, Any]:
    """Fit every trainable component of ``experiment`` and save the artifacts into ``out_dir``.

    ``out_dir`` is checked and locked first as for a run (a directory, writable,
    ``min_free_bytes`` free, no results ``overwrite`` may not replace, no other command
    writing there: :func:`~hapticframe.run._scope.run_scope`). ``train.json`` says
    ``status: running`` until the training run ends; the artifacts are saved into a
    staging folder and moved into ``out_dir`` (``DIR/<component id>/``) only once every
    one is saved, so a killed save never leaves a truncated or empty artifact where a run
    would load it. A failed training run keeps no artifacts; its ``train.json`` records
    the error.
    """
    started = time.perf_counter()
    label_channel = experiment.model.run.label_channel
    started_utc = datetime.now(timezone.utc).isoformat(timespec="seconds")
    head = {
        "seed": experiment.seed,
        "started_utc": started_utc,
        "pid": os.getpid(),
        "versions": environment(),
        "overrides": list(experiment.overrides),
    }
    done: dict[str, Any] = {}

    def final(scope: RunScope) -> dict[str, Any]:
        if scope.status == "ok":
            return done
        failed = {**head, "status": scope.status,
                  "error": scope.error if scope.error is not None else scope.signal_name,
                  "plugins": _plugins(experiment),
                  "resolved_config": experiment.resolved_config(),
                  "wall_time_s": time.perf_counter() - started}
        if scope.signal_name is not None:
            failed["signal"] = scope.signal_name
        return failed

    with run_scope(out_dir, head, what="training run", record="train.json",
                   overwrite=overwrite, min_free_bytes=min_free_bytes,
                   keep_failed=False, started_utc=started_utc) as scope:
        scope.final_record = final
        components = scope.build(lambda stack, on_close_error: build_components(
            experiment, stack, on_close_error=on_close_error))
        # With run.train_from, the training sensors stand in for the sensors a run streams.
        calibration_runs = list(experiment.model.run.calibration_runs)
        sources = dict(experiment.model.run.train_from) or {
            e.id: e.id for e in experiment.of_kind(Kind.SENSOR)
            # With calibration runs, a search's streamed sensors deliver no recordings.
            if not calibration_runs or "finite" in e.registered.spec.capabilities
        }
        if sources or not calibration_runs:
            recordings = collect_recordings(components, sources)
            echo(f"training on {len(recordings)} recordings")
            trained = fit_components(experiment, components, recordings, label_channel, echo)
        else:
            recordings, trained = [], []
        trained += fit_sensor_models(experiment, components, calibration_runs, echo)
        saved = _save(components, trained, scope.staging, scope.out)
        done.update({
            **head,
            "status": "ok",
            "error": None,
            "recordings": len(recordings),
            "calibration_runs": calibration_runs,
            "label_channel": label_channel,
            "trained": trained,
            "artifacts": saved,
            "reports": training_reports(components, trained),
            "plugins": _plugins(experiment),
            "resolved_config": experiment.resolved_config(),
            "wall_time_s": time.perf_counter() - started,
        })
        scope.succeed()
    return {**done, "files": scope.files}


def _plugins(experiment: Experiment) -> list[dict[str, Any]]:
    return [
        {"id": e.id, "kind": e.kind.value, "type": e.type,
         "distribution": e.registered.source.distribution,
         "version": e.registered.source.version}
        for e in experiment.components
    ]


def _label_source(
    recording: Mapping[str, SampleBatch], sensor_ids: Sequence[str], channel: str
) -> SampleBatch:
    for sid in sensor_ids:
        if channel in recording[sid].channels:
            return recording[sid]
    return recording[sensor_ids[0]]  # labels_at reports the missing channel


def _save(
    components: Mapping[str, Component], trained: Sequence[str], staging: Path, out: Path
) -> dict[str, str]:
    """Save each persistent component into ``staging/<id>``; return where each will be
    once the staging folder's content moves into ``out``."""
    saved = {}
    for cid in trained:
        component = components[cid]
        if isinstance(component, Persistent):
            target = staging / cid
            with _located(cid, type(component).__name__, "saving"):
                target.mkdir(parents=True, exist_ok=True)
                component.save(target)
            saved[cid] = str(out / cid)
    return saved
