"""Assemble an experiment's components and run them: ``hapticframe run``.

A run with a planner and a robot is a closed loop of exploratory movements; a run
without them streams its sensors until they are exhausted. Either way the run writes
``run.json`` (metadata), ``metrics.json``, ``trace.npz`` and the components' figures into
its output directory. An experiment that fails to build writes nothing.
"""

from __future__ import annotations

import json
import math
import platform
import time
import zlib
from collections.abc import Callable, Mapping
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from ._config import Experiment, RunSettings
from ._dataflow import Dataflow, TraceRecorder
from ._errors import ExperimentError, HapticframeError, Issue, RunError, UsageError
from ._evaluate import evaluate_labels, evaluate_map, save_label_figure, save_outline_figure
from ._kind import Kind
from ._version import __version__
from .kinds import (
    BuildContext,
    Classifier,
    Component,
    FeatureExtractor,
    Map,
    MovementResult,
    Planner,
    Robot,
    RunOutcome,
    Sensor,
    SensorModel,
)

__all__ = ["RunSummary", "Session", "build_components", "component_rng", "run_experiment"]

_INTERFACES: dict[Kind, type[Component]] = {
    Kind.SENSOR: Sensor,
    Kind.FEATURE_EXTRACTOR: FeatureExtractor,
    Kind.CLASSIFIER: Classifier,
    Kind.SENSOR_MODEL: SensorModel,
    Kind.MAP: Map,
    Kind.PLANNER: Planner,
    Kind.ROBOT: Robot,
}


def component_rng(seed: int, component_id: str) -> np.random.Generator:
    """The generator of one component: independent streams per id, fixed by the seed."""
    return np.random.default_rng(
        np.random.SeedSequence(seed, spawn_key=(zlib.crc32(component_id.encode("utf-8")),))
    )


def build_components(experiment: Experiment, *, progress: bool = True) -> dict[str, Component]:
    """Import and construct every component, inputs first.

    ``progress`` is handed to each component (:attr:`BuildContext.progress`).

    Raises
    ------
    ExperimentError
        When a plugin rejects its configuration while being built (exit status 2).
    PluginImportError
        When an implementation cannot be imported.
    """
    scene = experiment.model.scene  # type: ignore[attr-defined]
    built: dict[str, Component] = {}
    for entry in experiment.components:
        factory = entry.registered.spec.load_factory()
        context = BuildContext(
            id=entry.id,
            rng=component_rng(experiment.seed, entry.id),
            inputs={name: built[name] for name in entry.inputs},
            scene=scene,
            progress=progress,
        )
        try:
            component = factory(entry.config, context)
        except (ValueError, TypeError, KeyError) as exc:
            for other in built.values():
                other.close()
            raise ExperimentError(experiment.file, [Issue(
                entry.path, f"cannot build {entry.id!r} ({entry.kind} {entry.type!r}): {exc}",
            )]) from exc
        interface = _INTERFACES[entry.kind]
        if not isinstance(component, interface):
            raise RunError(
                f"{entry.kind} plugin {entry.type!r} built a {type(component).__name__}, which "
                f"is not a hapticframe.kinds.{interface.__name__}"
            )
        built[entry.id] = component
    return built


class Session:
    """One run of an experiment: its components, output directory and record."""

    def __init__(
        self, experiment: Experiment, out_dir: Path, echo: Callable[[str], None] = print
    ) -> None:
        self.experiment = experiment
        self.out_dir = out_dir
        self.echo = echo
        self.settings: RunSettings = experiment.model.run  # type: ignore[attr-defined]
        self.components: dict[str, Component] = {}
        self.movements: list[MovementResult] = []
        self.recorder = TraceRecorder()
        self.metadata: dict[str, Any] = {}
        self.started = time.perf_counter()

    @property
    def hook(self) -> Any:
        return self.experiment.plugin_manager.hook

    def of_kind(self, kind: Kind) -> list[Component]:
        return [self.components[e.id] for e in self.experiment.of_kind(kind)]

    # --- the loops ----------------------------------------------------------------------

    @property
    def training_sensors(self) -> frozenset[str]:
        """Sensors read only to fit components before the run (``run.train_from``)."""
        return frozenset(self.settings.train_from.values())

    def fit_before_run(self) -> None:
        """Fit feature extractors and classifiers on the training sensors' recordings."""
        sources = self.settings.train_from
        if not sources:
            return
        from ._train import collect_recordings, fit_components  # _train imports this module

        started = time.perf_counter()
        recordings = collect_recordings(self.components, sources)
        self.echo(
            f"fitting before the run on {len(recordings)} recordings of "
            f"{', '.join(sorted(set(sources.values())))}"
        )
        trained = fit_components(
            self.experiment, self.components, recordings, self.settings.label_channel, self.echo
        )
        self.metadata["training"] = {
            "recordings": len(recordings),
            "trained": trained,
            "reports": {cid: getattr(self.components[cid], "training_report", None) for cid in trained},
            "wall_time_s": time.perf_counter() - started,
        }

    def run_loop(self) -> None:
        planners, robots = self.of_kind(Kind.PLANNER), self.of_kind(Kind.ROBOT)
        flow = Dataflow(self.experiment, self.components, self.recorder, self.training_sensors)
        if planners or robots:
            if len(planners) != 1 or len(robots) != 1:
                raise RunError(
                    "a closed-loop run needs exactly one planner and one robot "
                    f"(found {len(planners)} planner(s) and {len(robots)} robot(s))"
                )
            self._closed_loop(flow, planners[0], robots[0])  # type: ignore[arg-type]
        else:
            self._open_loop(flow)

    def _closed_loop(self, flow: Dataflow, planner: Planner, robot: Robot) -> None:
        limit = min(self.settings.max_movements, planner.max_movements)
        chain: list[Component] = [robot, *(self.components[i] for i in flow.rewindable)]
        lookahead = self.settings.lookahead_steps
        for index in range(limit):
            movement = planner.propose()
            if movement is None:
                return
            flow.start_stream()
            robot.begin(movement)
            if lookahead > 1 and any(c.checkpoint() is None for c in chain):
                lookahead = 1  # a component that cannot rewind: one step at a time
            steps, halted_by_loop = self._movement(flow, robot, index, chain, lookahead)
            flow.flush_maps()
            reason = halted_by_loop or robot.halt_reason
            result = MovementResult(
                index=index,
                movement=movement,
                halted=bool(reason),
                halt_reason=reason,
                final_state=robot.state,
                final_class=flow.latest_class(),
                max_force_n=flow.force_max_n,
            )
            self.movements.append(result)
            self._progress(result, steps)
            for component in self.components.values():
                component.on_movement_end(result)
        self.echo(f"stopped after {limit} movements (the movement limit)")

    def _movement(
        self, flow: Dataflow, robot: Robot, index: int, chain: list[Component], lookahead: int
    ) -> tuple[int, str]:
        """Step the robot through the movement it has begun; returns the steps taken and
        ``"interaction"`` when the loop halted it.

        With ``lookahead > 1`` the robot runs up to that many steps ahead and the chain
        classifies them as one batch. A batch in which the primary classifier reports an
        interaction is rewound (``chain``: the robot, streamed sensors, extractors and
        classifiers) and replayed one step at a time, so the loop halts at the same step,
        with the same records, as without look-ahead. Batches end on multiples of
        ``run.map_update_every_steps`` so that maps are updated at the same steps too.
        """
        # Settings read once: the step loop below runs some 20,000 times per search.
        every = self.settings.map_update_every_steps
        halt_on_interaction = self.settings.halt_on_interaction
        max_steps = self.settings.max_steps_per_movement
        robot_id = robot.id
        halted_by_loop = ""
        steps = 0
        replay_until = 0  # steps below this run one at a time (a rewound batch)
        while True:
            if steps >= max_steps:
                raise RunError(f"movement {index + 1} did not end within {max_steps} steps")
            batch = min(lookahead, max_steps - steps)
            if every:
                batch = min(batch, every - steps % every)
            if batch > 1 and steps >= replay_until and not halted_by_loop:
                snapshots = [component.checkpoint() for component in chain]
                states = []
                for _ in range(batch):
                    state = robot.step()
                    if state is None:
                        break
                    states.append(state)
                if not states:
                    break
                outputs, classified = flow.read_and_classify()
                if halt_on_interaction and flow.holds_interaction(classified):
                    for component, snapshot in zip(chain, snapshots):
                        component.rewind(snapshot)
                    replay_until = steps + len(states)
                    continue
                for state in states:
                    flow.record_robot_state(robot_id, state, index)
                flow.commit(outputs, classified)
                steps += len(states)
            else:
                state = robot.step()
                if state is None:
                    break
                steps += 1
                flow.record_robot_state(robot_id, state, index)
                flow.tick()
                if halt_on_interaction and not halted_by_loop:
                    detected = flow.interaction_detected()
                    if detected is not None:
                        halted_by_loop = "interaction"
                        robot.halt("interaction")
            if every and steps % every == 0:
                flow.flush_maps()
        return steps, halted_by_loop

    def _open_loop(self, flow: Dataflow) -> None:
        sensors: list[Sensor] = [
            s for s in self.of_kind(Kind.SENSOR) if s.id not in self.training_sensors  # type: ignore[misc]
        ]
        if not sensors:
            raise RunError("nothing to run: the experiment has no sensors and no robot")
        for reads in range(1, self.settings.max_reads + 1):
            if all(s.exhausted for s in sensors):
                break
            flow.tick()
            flow.flush_maps()
        else:
            self.echo(f"stopped after {self.settings.max_reads} reads (run.max_reads)")
        self.metadata["sensor_reads"] = reads

    def _progress(self, result: MovementResult, steps: int) -> None:
        m = result.movement
        force = "" if math.isnan(result.max_force_n) else f"  max force {result.max_force_n:5.1f} N"
        state = result.final_class or "-"
        # Fixed-width fields first and the free-form label last, so the columns line up.
        label = f"  {m.label}" if m.label else ""
        self.echo(
            f"EM {result.index + 1:>3} {m.phase or '':<7} "
            f"{result.halt_reason or 'completed':<12} state {state:<8} "
            f"{steps:>5d} steps{force:<18}{label}"
        )

    # --- results --------------------------------------------------------------------------

    def metrics(self, wall_time_s: float) -> dict[str, Any]:
        out: dict[str, Any] = {"movements": len(self.movements)}
        scene = self.experiment.model.scene  # type: ignore[attr-defined]
        map_id = self._evaluation_map()
        if scene is not None and scene.objects and map_id is not None:
            # The robot knows where it met the object: the estimate is the blob nearest there.
            met = [r.final_state.position_m for r in self.movements
                   if r.interacted and r.final_state is not None]
            the_map: Map = self.components[map_id]  # type: ignore[assignment]
            out.update(evaluate_map(
                the_map,
                scene,
                level=self.settings.outline_level,
                spacing_m=self.settings.evaluation_spacing_m,
                near_m=np.mean(met, axis=0) if met else None,
            ))
            outline = out.pop("_outline")
            out["evaluated_map"] = map_id
            if self.settings.figures:
                save_outline_figure(
                    self.out_dir / "outline.png", the_map.region, scene, self.movements, outline,
                    out["estimated_centroid_m"], self.settings.outline_level,
                )
        out.update(self._label_metrics())
        outcome = RunOutcome(
            self.out_dir, scene, tuple(self.movements), self.components, wall_time_s,
            figures=self.settings.figures, outline_level=self.settings.outline_level,
        )
        for cid, component in self.components.items():
            for key, value in dict(component.finalize(outcome)).items():
                if key in out:
                    raise RunError(f"metric {key!r} of {cid!r} clashes with another metric")
                out[key] = value
        out["wall_time_s"] = time.perf_counter() - self.started
        return out

    def _primary_classifier(self) -> str | None:
        """The classifier whose decisions drive the run (as :class:`Dataflow` picks it): the
        one feeding the first sensor model, else the first classifier."""
        for entry in self.experiment.of_kind(Kind.SENSOR_MODEL):
            for name in entry.inputs:
                if self.components[name].kind is Kind.CLASSIFIER:
                    return name
        classifiers = self.experiment.of_kind(Kind.CLASSIFIER)
        return classifiers[0].id if classifiers else None

    def _label_metrics(self) -> dict[str, Any]:
        """Score the primary classifier against the first streamed sensor that has a
        ``run.label_channel`` channel (a synthetic or labelled recording); writes
        ``labels.png``. Nothing when there is no such sensor or no classifier output."""
        name = self.settings.label_channel
        clf = self._primary_classifier()
        sources = [
            e.id for e in self.experiment.of_kind(Kind.SENSOR)
            if e.id not in self.training_sensors
            and name in self.components[e.id].channels  # type: ignore[attr-defined]
        ]
        if clf is None or not sources:
            return {}
        arrays = self.recorder.arrays()
        times = arrays.get(f"classifier/{clf}/timestamps_s")
        probabilities = arrays.get(f"classifier/{clf}/probabilities")
        labels = arrays.get(f"sensor/{sources[0]}/{name}")
        if times is None or probabilities is None or labels is None or not len(times):
            return {}
        label_times = arrays[f"sensor/{sources[0]}/timestamps_s"]
        result = evaluate_labels(times, probabilities, label_times, labels, name)
        events = result.pop("_events")
        if self.settings.figures and result[f"{name}_frames"]:
            classes = tuple(self.components[clf].classes)  # type: ignore[attr-defined]
            save_label_figure(self.out_dir / "labels.png", times, probabilities, classes,
                              label_times, labels, events, name)
        return {**result, f"{name}_labels_from": sources[0]}

    def _evaluation_map(self) -> str | None:
        if self.settings.evaluation_map is not None:
            if self.settings.evaluation_map not in self.components:
                raise RunError(f"run.evaluation_map {self.settings.evaluation_map!r} is not a component id")
            return self.settings.evaluation_map
        for entry in self.experiment.of_kind(Kind.PLANNER):
            for name in entry.inputs:
                if self.components[name].kind is Kind.MAP:
                    return name
        maps = self.experiment.of_kind(Kind.MAP)
        return maps[-1].id if maps else None

    def run_record(self, status: str, wall_time_s: float, error: str | None) -> dict[str, Any]:
        plugins = [
            {
                "id": e.id,
                "kind": e.kind.value,
                "type": e.type,
                "distribution": e.registered.source.distribution,
                "version": e.registered.source.version,
                "entry_point": e.registered.source.entry_point,
            }
            for e in self.experiment.components
        ]
        extra: dict[str, Any] = {}
        for part in self.hook.hapticframe_run_metadata(session=self):
            if part:
                extra.update(part)
        return {
            "status": status,
            "error": error,
            "experiment_file": str(self.experiment.file),
            "name": self.experiment.model.name,  # type: ignore[attr-defined]
            "seed": self.experiment.seed,
            "started_utc": self.metadata.get("started_utc"),
            "wall_time_s": wall_time_s,
            "movements": len(self.movements),
            "versions": {
                "hapticframe": __version__,
                "python": platform.python_version(),
                "numpy": np.__version__,
                "platform": platform.platform(),
            },
            "plugins": plugins,
            "plugin_metadata": extra,
            "resolved_config": self.experiment.resolved_config(),
            "details": {k: v for k, v in self.metadata.items() if k != "started_utc"},
        }


class RunSummary(dict):  # type: ignore[type-arg]
    """The metrics of a finished run (a dict), plus where they were written."""

    out_dir: Path


def _prepare_out_dir(out_dir: Path, overwrite: bool) -> None:
    if out_dir.exists() and not out_dir.is_dir():
        raise UsageError(f"--out {out_dir} exists and is not a directory")
    if out_dir.exists() and (out_dir / "run.json").exists() and not overwrite:
        raise UsageError(
            f"--out {out_dir} already holds a run (run.json); choose another directory or "
            "pass --overwrite"
        )


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def _write_json(path: Path, data: Mapping[str, Any]) -> None:
    clean = json.loads(json.dumps(data, default=_json_default, allow_nan=True))
    text = json.dumps(_nan_to_none(clean), indent=2, sort_keys=True, allow_nan=False)
    path.write_text(text + "\n", encoding="utf-8")


def _nan_to_none(value: Any) -> Any:
    # JSON has no NaN: an unknown figure is written as null, never as a bogus number.
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _nan_to_none(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_nan_to_none(v) for v in value]
    return value


def run_experiment(
    experiment: Experiment,
    out_dir: str | Path,
    *,
    overwrite: bool = False,
    echo: Callable[[str], None] = print,
    progress: bool = True,
) -> RunSummary:
    """Build and run ``experiment``, writing results into ``out_dir``.

    ``echo`` receives the progress lines; ``progress=False`` also asks the components to
    draw no progress bars of their own (``--quiet``).

    Returns
    -------
    RunSummary
        The metrics written to ``metrics.json``.

    Raises
    ------
    ExperimentError, UsageError
        Before anything is written (exit status 2).
    RunError
        When the run fails; ``run.json`` then records the failure (exit status 1).
    """
    out = Path(out_dir)
    _prepare_out_dir(out, overwrite)
    session = Session(experiment, out, echo)
    session.components = build_components(experiment, progress=progress)  # before any write
    out.mkdir(parents=True, exist_ok=True)
    session.metadata["started_utc"] = datetime.now(timezone.utc).isoformat(timespec="seconds")
    status, error = "failed", None
    try:
        session.hook.hapticframe_session_start(session=session)
        session.fit_before_run()
        session.run_loop()
        metrics = session.metrics(time.perf_counter() - session.started)
        session.recorder.save(str(out / "trace.npz"))
        _write_json(out / "metrics.json", metrics)
        status = "ok"
    except HapticframeError as exc:
        error = str(exc)
        raise
    except Exception as exc:
        error = f"{type(exc).__name__}: {exc}"
        raise RunError(f"the run failed: {error}") from exc
    finally:
        wall = time.perf_counter() - session.started
        try:
            session.hook.hapticframe_session_finish(session=session, status=status)
        finally:
            for component in session.components.values():
                component.close()
            _write_json(out / "run.json", session.run_record(status, wall, error))
    summary = RunSummary(metrics)
    summary.out_dir = out
    return summary
