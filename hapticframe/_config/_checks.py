"""Plugin validators: checks across fields, components and the scene, run at ``validate``.

A plugin's spec names a validator (``validator="package.checks:check"``); :func:`run_validators`
calls it for each component with the component's validated config and a
:class:`ValidationContext`, and turns the :class:`Finding` records it yields into located
issues (errors) and warnings. Nothing is built: a validator reads configs, never loads a
model or opens a device.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

from hapticframe._config._load import LoadedFile
from hapticframe._config._roles import evaluated_map_id
from hapticframe._config._sizes import Size, format_bytes
from hapticframe._contracts import ChannelSpec, channel_disagreement, describe_channel
from hapticframe._errors import Issue, PluginImportError
from hapticframe._kind import Kind

if TYPE_CHECKING:
    from hapticframe._config._model import ComponentEntry

__all__ = [
    "contract_mismatch",
    "ComponentView",
    "Finding",
    "ValidationContext",
    "core_checks",
    "declared_channels",
    "grid_points",
    "run_validators",
    "validator_results",
]


def _ceil(value: float) -> float:
    """``math.ceil`` that keeps an infinite count (a spacing of 5e-324 m) infinite."""
    return float(math.ceil(value)) if math.isfinite(value) else value


@dataclass(frozen=True)
class Finding:
    """One result of a plugin's validator.

    Parameters
    ----------
    message : str
        What is wrong and what to do, in one sentence or two (the component is named by
        the location; numbers with their units, estimates where a size is the problem).
    field : str
        The dotted config field it concerns (``"hinge_spacing_m"``), ``""`` for the whole
        component; it locates the message in the file.
    severity : ``"error"`` or ``"warning"``
        An error refuses the file (exit 2); a warning is reported and the file is valid
        (legal but suspicious).
    """

    message: str
    field: str = ""
    severity: Literal["error", "warning"] = "error"

    def __post_init__(self) -> None:
        if self.severity not in ("error", "warning"):
            raise ValueError(f"severity must be 'error' or 'warning', got {self.severity!r}")


@dataclass(frozen=True)
class ComponentView:
    """What a validator may read of a component: its id, kind, type and validated config."""

    id: str
    kind: Kind
    type: str
    config: Any
    inputs: tuple[str, ...] = ()


@dataclass(frozen=True)
class ValidationContext:
    """What a plugin's validator sees besides its own config.

    Attributes
    ----------
    id : str
        The component's id.
    inputs : mapping of str to ComponentView
        Its inputs, by id, in the file's order.
    components : mapping of str to ComponentView
        Every component of the experiment, by id.
    scene : Scene or None
        The validated scene (``scene.region``, ``scene.objects``, ``scene.material``).
    run : RunSettings
        The validated ``run`` section.
    """

    id: str
    inputs: Mapping[str, ComponentView]
    components: Mapping[str, ComponentView]
    scene: Any
    run: Any
    extra: Mapping[str, Any] = field(default_factory=dict)

    def query_grid_points(self, width_m: float, height_m: float) -> float:
        """The most points a run queries a map of this size at, at once: its evaluation
        grid (``run.evaluation_spacing_m``) or, when it records map snapshots, its snapshot
        grid (``run.snapshot_spacing_m``). For a :class:`Size` of what a query allocates."""
        spacings = [getattr(self.run, "evaluation_spacing_m", None)]
        if getattr(self.run, "record", False) and getattr(self.run, "snapshot_rate_hz", 0):
            spacings.append(getattr(self.run, "snapshot_spacing_m", None))
        counts = [grid_points(width_m, height_m, s) for s in spacings
                  if isinstance(s, float) and s > 0]
        return max(counts, default=1.0)


def grid_points(width_m: float, height_m: float, spacing_m: float) -> float:
    """Cells of a grid of ``spacing_m`` over ``width_m x height_m``, as
    :func:`hapticframe.geometry.sample_grid` lays them (at least one a side)."""
    nx = max(1, _ceil(width_m / spacing_m - 1e-9))
    ny = max(1, _ceil(height_m / spacing_m - 1e-9))
    return nx * ny


def validator_results(
    validator: Any, config: Any, context: ValidationContext, name: str = "the plugin"
) -> tuple[list[Finding], list[Size]]:
    """What ``validator`` yields for ``config``: its findings, and the sizes it declares.

    Raises
    ------
    TypeError
        It yielded something that is neither a :class:`Finding` nor a :class:`Size`.
    """
    findings: list[Finding] = []
    sizes: list[Size] = []
    for result in validator(config, context) or ():
        if isinstance(result, Finding):
            findings.append(result)
        elif isinstance(result, Size):
            sizes.append(result)
        else:
            raise TypeError(
                f"the validator of {name} yielded {type(result).__name__}, not a "
                "hapticframe.Finding or hapticframe.Size"
            )
    return findings, sizes


def size_findings(sizes: Iterable[Size], findings: Iterable[Finding] = ()) -> list[Finding]:
    """An error finding for every size over the limits, located at its field; none for a
    field the validator's own ``findings`` already refuse (its words come first)."""
    refused = {f.field for f in findings if f.severity == "error"}
    return [Finding(problem, field=size.field) for size in sizes
            if size.field not in refused and (problem := size.problem()) is not None]


def run_validators(
    entries: Iterable[ComponentEntry], model: Any, loaded: LoadedFile, command: str = "run"
) -> tuple[list[Issue], list[Issue]]:
    """Call every component's validator; returns ``(errors, warnings)`` as located issues.

    ``command`` (``"run"`` or ``"train"``) reaches the validators as
    ``context.extra["command"]``: a file for ``hapticframe train`` may hold the untrained
    components it is about to fit."""
    entries = list(entries)
    views = {
        e.id: ComponentView(e.id, e.kind, e.type, e.config, tuple(e.inputs)) for e in entries
    }
    errors: list[Issue] = []
    warnings: list[Issue] = []
    for entry in entries:
        spec = entry.registered.spec
        if not spec.validator:
            continue
        try:
            validator = spec.load_validator()
        except PluginImportError as exc:
            errors.append(Issue(entry.path, str(exc), loaded.line_of(entry.path)))
            continue
        context = ValidationContext(
            id=entry.id,
            inputs={i: views[i] for i in entry.inputs if i in views},
            components=views,
            scene=getattr(model, "scene", None),
            run=getattr(model, "run", None),
            extra={"command": command},
        )
        findings, sizes = validator_results(
            validator, entry.config, context, f"{spec.kind} plugin {spec.name!r}"
        )
        for finding in [*findings, *size_findings(sizes, findings)]:
            path = f"{entry.path}.config.{finding.field}" if finding.field else entry.path
            line = loaded.line_of(path) or loaded.line_of(entry.path)
            issue = Issue(path, finding.message, line)
            (errors if finding.severity == "error" else warnings).append(issue)
    return errors, warnings


# --- the core's own checks across sections ------------------------------------------------

#: The most points the evaluation grid (``run.evaluation_spacing_m`` over the evaluated
#: map's region) may hold: 4e6 points are 64 MB of coordinates and one map query.
MAX_EVALUATION_POINTS = 4_000_000
#: A step of the fingertip (speed / control rate) at least this fraction of the smallest
#: object's width is reported as coarse (a warning); a step as long as the width is refused.
COARSE_STEP_FRACTION = 0.1
#: The capability of a plugin that needs a robot among its inputs (a simulated sensor
#: mounted on the simulated robot, a sensor model that locates by the robot's pose).
NEEDS_ROBOT = "needs-robot"
#: The capability of a planner that reads a map (it plans on it).
READS_MAP = "reads-map"
#: The capability of a plugin that simulates the scene (a simulated robot in its sand):
#: ``validate`` refuses an experiment without one (``scene: null`` included).
NEEDS_SCENE = "needs-scene"


def declared_channels(config: Any) -> frozenset[str] | None:
    """The channels a sensor's config says it delivers, or None when it cannot say before
    the sensor is built.

    A sensor's config model may define ``declared_channels(self)`` returning the channel
    names (``run.label_channel`` and a sensor model's ``position_m`` are then checked at
    ``validate``), or None when they depend on a file or a device.
    """
    method = getattr(config, "declared_channels", None)
    if not callable(method):
        return None
    try:
        names = method()
    except Exception:  # a plugin's convenience method never breaks validation
        return None
    return None if names is None else frozenset(str(n) for n in names)


class _Report:
    """Collects located errors and warnings."""

    def __init__(self, loaded: LoadedFile) -> None:
        self.loaded = loaded
        self.errors: list[Issue] = []
        self.warnings: list[Issue] = []

    def error(self, path: str, message: str) -> None:
        self.errors.append(Issue(path, message, self.loaded.line_of(path)))

    def warning(self, path: str, message: str) -> None:
        self.warnings.append(Issue(path, message, self.loaded.line_of(path)))


def core_checks(
    entries: Iterable[ComponentEntry], model: Any, loaded: LoadedFile
) -> tuple[list[Issue], list[Issue]]:
    """The core's checks of a validated experiment whose graph is sound: the scene as a
    whole, the closed or open loop, what each kind needs in its inputs, the run settings
    against the components, and the pace of the closed loop against ``run`` and the scene.
    Returns ``(errors, warnings)``, located."""
    entries = list(entries)
    report = _Report(loaded)
    scene = getattr(model, "scene", None)
    if scene is not None:
        for path, message in scene.problems():
            report.error(f"scene.{path}", message)
    _check_loop(entries, model.run, report)
    _check_inputs(entries, model.run, scene, report)
    _check_channels(entries, report)
    _check_run_settings(entries, model.run, scene, report)
    _check_pace(entries, model.run, scene, report)
    return report.errors, report.warnings


def _of(entries: list[ComponentEntry], kind: Kind) -> list[ComponentEntry]:
    return [e for e in entries if e.kind is kind]


def _ids(entries: Iterable[ComponentEntry]) -> str:
    return ", ".join(repr(e.id) for e in entries)


def _check_loop(entries: list[ComponentEntry], run: Any, report: _Report) -> None:
    """A closed loop has exactly one planner and at least one robot; an open loop streams
    at least one sensor."""
    planners, robots = _of(entries, Kind.PLANNER), _of(entries, Kind.ROBOT)
    if planners or robots:
        if len(planners) > 1:
            report.error(planners[1].path, (
                f"a closed loop has exactly one planner; found {len(planners)} "
                f"({_ids(planners)}): keep one"
            ))
        if not planners:
            report.error(robots[0].path, (
                f"a closed loop needs a planner to propose the movements of {_ids(robots)}: "
                "add one under planners"
            ))
        if not robots:
            report.error(planners[0].path, (
                f"a closed loop needs at least one robot to carry out the movements of "
                f"{planners[0].id!r}: add one under robots"
            ))
        return
    training = set(run.train_from.values())
    streamed = [e for e in _of(entries, Kind.SENSOR) if e.id not in training]
    if not streamed:
        report.error("", (
            "nothing to run: the experiment has no robot and no sensor to stream (add a "
            "planner and a robot for a closed loop, or a sensor for an open loop)"
        ))


def _check_inputs(
    entries: list[ComponentEntry], run: Any, scene: Any, report: _Report
) -> None:
    """What each component needs among its inputs (and the scene), as the run loop reads
    them."""
    by_id = {e.id: e for e in entries}
    training = set(run.train_from.values())
    streamed = [e for e in _of(entries, Kind.SENSOR) if e.id not in training]
    for entry in entries:
        kinds = [by_id[i].kind for i in entry.inputs if i in by_id]
        where = f"{entry.path}.inputs"
        named = f"{entry.kind} {entry.id!r} ({entry.type})"
        if NEEDS_ROBOT in entry.registered.spec.capabilities and Kind.ROBOT not in kinds:
            report.error(where, f"{named} needs a robot among its inputs: name one")
        if NEEDS_SCENE in entry.registered.spec.capabilities and scene is None:
            report.error(entry.path, (
                f"{named} simulates the scene, and the experiment has none: add a 'scene' "
                "section (region, material, objects)"
            ))
        if entry.kind in (Kind.FEATURE_EXTRACTOR, Kind.CLASSIFIER) and not entry.inputs:
            report.error(where, (
                f"{named} reads sensors or feature extractors: name at least one in inputs"
            ))
        elif entry.kind is Kind.SENSOR_MODEL:
            classifiers = kinds.count(Kind.CLASSIFIER)
            if classifiers != 1:
                report.error(where, (
                    f"{named} locates the decisions of exactly one classifier: name one "
                    f"classifier in its inputs (found {classifiers})"
                ))
            if Kind.ROBOT not in kinds:
                own = [by_id[i] for i in entry.inputs if by_id[i].kind is Kind.SENSOR]
                candidates = own + streamed
                channels = [declared_channels(c.config) for c in candidates]
                if not candidates or all(
                    names is not None and "position_m" not in names for names in channels
                ):
                    report.error(where, (
                        f"{named} needs fingertip positions: add a robot to its inputs or "
                        "use a sensor with a 'position_m' channel"
                    ))
        elif entry.kind is Kind.MAP and not entry.inputs:
            report.warning(where, (
                f"{named} has no sensor model in its inputs: it is never updated"
            ))
        elif (
            entry.kind is Kind.PLANNER and READS_MAP in entry.registered.spec.capabilities
            and Kind.MAP not in kinds
        ):
            report.warning(where, (
                f"{named} plans on a map but has none in its inputs: name the map it reads"
            ))


def contract_mismatch(
    consumer: ComponentEntry, input_id: str, input_type: str,
    produced: Mapping[str, ChannelSpec], what_input: str = "",
) -> list[str]:
    """The channels on which ``consumer``'s declared ``consumes`` and what its input
    ``input_id`` produces disagree, one message each naming both declarations."""
    consumed = consumer.registered.spec.reads
    messages = []
    for name in consumed.keys() & produced.keys():
        why = channel_disagreement(produced[name], consumed[name])
        if why:
            messages.append(
                f"{consumer.kind} {consumer.id!r} ({consumer.type}) reads "
                f"{describe_channel(name, consumed[name])}; its input {input_id!r} "
                f"({input_type}) {what_input or 'declares'} "
                f"{describe_channel(name, produced[name])} ({why}): wire it to an input that "
                "delivers what it reads, or convert the channel with a feature extractor "
                "(`hapticframe plugins --channels` lists both sides)"
            )
    return messages


def _check_channels(entries: list[ComponentEntry], report: _Report) -> None:
    """Each consumer's declared channels against what its inputs' specs produce."""
    by_id = {e.id: e for e in entries}
    for entry in entries:
        for input_id in entry.inputs:
            source = by_id.get(input_id)
            if source is None:
                continue
            for message in contract_mismatch(
                entry, input_id, source.type, source.registered.spec.produces
            ):
                report.error(f"{entry.path}.inputs", message)


#: The capability of a sensor that ends (a recording, a file): an open loop over sensors
#: that all declare it ends when they do.
FINITE = "finite"


def _sample_bytes(entry: ComponentEntry) -> tuple[float, bool]:
    """Bytes one sample of a sensor takes in trace.npz (its time and every value), and
    whether its spec declares its channels (else: one value is assumed)."""
    produces = entry.registered.spec.produces
    values = sum(math.prod(1 if n is None else n for n in c.shape) for c in produces.values())
    return 8.0 * (1 + (values if produces else 1)), bool(produces)


def _check_bounded(entries: list[ComponentEntry], run: Any, report: _Report) -> None:
    """An open loop over a sensor that never ends needs ``run.duration_s``; a closed loop
    refuses it (its length is its planner's)."""
    closed = bool(_of(entries, Kind.PLANNER) or _of(entries, Kind.ROBOT))
    if closed:
        if run.duration_s is not None:
            report.error("run.duration_s", (
                "run.duration_s bounds an open loop (no robot); this closed loop ends when "
                "its planner has no movement left or at run.max_movements: remove it"
            ))
        return
    training = set(run.train_from.values())
    endless = [e for e in _of(entries, Kind.SENSOR)
               if e.id not in training and FINITE not in e.registered.spec.capabilities]
    if not endless or run.duration_s is not None:
        return
    per_read, guessed = 0.0, []
    for entry in endless:
        size, declared = _sample_bytes(entry)
        per_read += size
        if not declared:
            guessed.append(entry.id)
    total = per_read * run.max_reads
    clock_s = run.max_reads * run.live_tick_s
    named = ", ".join(repr(i) for i in guessed)
    assumed = f"; {named} declares no channels, counted as one value a sample" if guessed else ""
    report.error("run", (
        f"this open loop streams {_ids(endless)}, which never ends (no 'finite' "
        "capability), and states no length: without run.duration_s it reads until "
        f"run.max_reads, {run.max_reads:,} reads ({clock_s:,.0f} s of the run's clock at "
        f"{run.live_tick_s:g} s a read), and writes at least {format_bytes(total)} of "
        f"samples into trace.npz and as much into run.mcap (one sample a read; k samples a "
        f"read: k times that{assumed}). Set run.duration_s (seconds of the run's clock), "
        "e.g. `run: {duration_s: 60}`"
    ))


def _check_run_settings(
    entries: list[ComponentEntry], run: Any, scene: Any, report: _Report
) -> None:
    """``run.evaluation_map`` names a map; ``run.label_channel`` is a channel of the
    sensors that deliver labels, where their configs say which channels they have; an open
    loop over a sensor that never ends states its length."""
    _check_bounded(entries, run, report)
    by_id = {e.id: e for e in entries}
    maps = _of(entries, Kind.MAP)
    if run.evaluation_map is not None and (
        run.evaluation_map not in by_id or by_id[run.evaluation_map].kind is not Kind.MAP
    ):
        found = by_id.get(run.evaluation_map)
        what = f"a {found.kind}" if found is not None else "no component"
        report.error("run.evaluation_map", (
            f"run.evaluation_map {run.evaluation_map!r} names {what}, not a map; the maps "
            f"are: {_ids(maps) or 'none'}"
        ))
    label = run.label_channel
    for source in dict.fromkeys(run.train_from.values()):
        entry = by_id.get(source)
        names = declared_channels(entry.config) if entry is not None else None
        if names is not None and label not in names:
            report.error("run.label_channel", (
                f"training sensor {source!r} delivers no channel {label!r} (its channels: "
                f"{', '.join(sorted(names)) or 'none'}); set run.label_channel to the "
                "channel that holds its labels"
            ))
    if not run.train_from and _of(entries, Kind.CLASSIFIER):
        sensors = _of(entries, Kind.SENSOR)
        declared = [declared_channels(s.config) for s in sensors]
        if sensors and all(n is not None and label not in n for n in declared):
            report.warning("run.label_channel", (
                f"no sensor delivers the label channel {label!r}: the classifiers are not "
                "scored and `hapticframe train` has no labels to fit on"
            ))


def _region_of(entry: ComponentEntry, by_id: Mapping[str, ComponentEntry], scene: Any
               ) -> tuple[Any, str] | None:
    """The region a planner or map works in, as its config, its first map or the scene
    says: ``(region, where it comes from)``, or None when nothing says."""
    own = getattr(entry.config, "region", None)
    if own is not None and hasattr(own, "x_max_m"):
        return own, f"{entry.path}.config.region"
    for name in entry.inputs:
        source = by_id.get(name)
        region = getattr(source.config, "region", None) if source is not None else None
        if source is not None and source.kind is Kind.MAP and hasattr(region, "x_max_m"):
            return region, f"{source.path}.config.region"
    if scene is not None:
        return scene.region, "scene.region"
    return None


def _sides(region: Any) -> tuple[float, float]:
    return (float(region.x_max_m - region.x_min_m), float(region.y_max_m - region.y_min_m))


def _number(config: Any, name: str) -> float | None:
    value = getattr(config, name, None)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    value = float(value)
    return value if math.isfinite(value) and value > 0 else None


def _check_pace(entries: list[ComponentEntry], run: Any, scene: Any, report: _Report) -> None:
    """The closed loop's steps against ``run`` and the scene, where the configs say the
    planner's speed (``speed_m_per_s``) and the robots' control rates (``control_rate_hz``):
    the longest line of the planner's region must end within
    ``run.max_steps_per_movement`` steps, and one step must not jump over the smallest
    object. Also bounds the evaluation grid."""
    by_id = {e.id: e for e in entries}
    planners, robots = _of(entries, Kind.PLANNER), _of(entries, Kind.ROBOT)
    objects = list(scene.objects) if scene is not None else []
    narrowest = min(objects, key=lambda o: o.min_width_m(), default=None)
    if len(planners) == 1 and robots:
        planner = planners[0]
        speed = _number(planner.config, "speed_m_per_s")
        found = _region_of(planner, by_id, scene)
        rated = [(r, rate) for r in robots
                 if (rate := _number(r.config, "control_rate_hz")) is not None]
        if speed is not None and rated:
            speed_path = f"{planner.path}.config.speed_m_per_s"
            robot, rate = max(rated, key=lambda pair: pair[1])  # the most steps per metre
            if found is not None:
                region, _ = found
                length = math.hypot(*_sides(region))
                steps = _ceil(length * rate / speed)
                if steps > run.max_steps_per_movement:
                    report.error("run.max_steps_per_movement", (
                        f"a line across the planner's region (its diagonal, {length:.4g} m) "
                        f"at {speed:.4g} m/s takes {steps:.4g} steps of robot {robot.id!r} at "
                        f"{rate:.4g} Hz, more than run.max_steps_per_movement "
                        f"({run.max_steps_per_movement}): raise it or the planner's "
                        "speed_m_per_s"
                    ))
                else:
                    _check_ramps(rated, length, speed, run, report)
            step_m = speed / min(rate for _, rate in rated)
            if narrowest is not None:
                width = narrowest.min_width_m()
                if step_m >= width:
                    report.error(speed_path, (
                        f"one control step covers {step_m:.4g} m ({speed:.4g} m/s at "
                        f"{min(r for _, r in rated):.4g} Hz), as much as the smallest "
                        f"object is wide ({width:.4g} m): the fingertip could jump over it; "
                        "lower the speed"
                    ))
                elif step_m >= COARSE_STEP_FRACTION * width:
                    report.warning(speed_path, (
                        f"one control step covers {step_m:.4g} m, {step_m / width:.0%} of "
                        f"the smallest object's width ({width:.4g} m): the fingertip meets "
                        "it in few steps"
                    ))
    if len(planners) == 1:
        _check_workspaces(planners[0], robots, by_id, scene, report)
    evaluated = _evaluated_map(entries, run)
    if objects and evaluated is not None:
        found = _region_of(evaluated, by_id, scene)
        if found is not None:
            entry = evaluated
            width, height = _sides(found[0])
            spacing = run.evaluation_spacing_m
            points = (width / spacing + 1) * (height / spacing + 1)
            if points > MAX_EVALUATION_POINTS:
                report.error("run.evaluation_spacing_m", (
                    f"scoring map {entry.id!r} on its {width:.4g} x {height:.4g} m region at "
                    f"{spacing:g} m spacing takes {points:.3g} grid points (about "
                    f"{format_bytes(points * GRID_POINT_BYTES)}); the limit is "
                    f"{MAX_EVALUATION_POINTS:.3g}: raise run.evaluation_spacing_m"
                ))
    _check_snapshots(entries, run, scene, report)


def _movement_s(length_m: float, speed: float, acceleration: float) -> float:
    """Duration of a trapezoidal movement (ramps at ``acceleration``, cruise at ``speed``);
    a movement too short to reach the speed is a triangle."""
    if length_m * acceleration >= speed * speed:
        return length_m / speed + speed / acceleration
    return 2.0 * math.sqrt(length_m / acceleration)


def _check_ramps(rated: list[tuple[ComponentEntry, float]], length: float, speed: float,
                 run: Any, report: _Report) -> None:
    """A robot that ramps its speed (``acceleration_m_per_s2``) must still end the longest
    line within ``run.max_steps_per_movement`` steps: a tiny acceleration makes a movement
    that never ends."""
    for robot, rate in rated:
        acceleration = _number(robot.config, "acceleration_m_per_s2")
        if acceleration is None:
            continue
        steps = _ceil(_movement_s(length, speed, acceleration) * rate)
        if steps > run.max_steps_per_movement:
            # The smallest acceleration that ends the line within the limit.
            budget_s = run.max_steps_per_movement / rate
            least = 4 * length / budget_s**2 if budget_s >= 2 * length / speed \
                else speed / (budget_s - length / speed)
            report.error(f"{robot.path}.config.acceleration_m_per_s2", (
                f"a line across the planner's region ({length:.4g} m) at {speed:.4g} m/s, "
                f"ramped at {acceleration:.4g} m/s², takes {steps:.4g} steps at {rate:.4g} "
                f"Hz, more than run.max_steps_per_movement ({run.max_steps_per_movement}): "
                f"the acceleration must be at least {least:.4g} m/s² (or None)"
            ))


def _check_workspaces(planner: ComponentEntry, robots: list[ComponentEntry],
                      by_id: Mapping[str, ComponentEntry], scene: Any, report: _Report) -> None:
    """A robot whose ``workspace`` misses the planner's region entirely could carry out no
    movement: every line starts outside it."""
    found = _region_of(planner, by_id, scene)
    if found is None:
        return
    region, where = found
    for robot in robots:
        space = getattr(robot.config, "workspace", None)
        if space is None or not hasattr(space, "x_max_m"):
            continue
        width = min(space.x_max_m, region.x_max_m) - max(space.x_min_m, region.x_min_m)
        height = min(space.y_max_m, region.y_max_m) - max(space.y_min_m, region.y_min_m)
        if width <= 0 or height <= 0:
            report.error(f"{robot.path}.config.workspace", (
                f"the workspace of robot {robot.id!r} (x {space.x_min_m:g} to "
                f"{space.x_max_m:g} m, y {space.y_min_m:g} to {space.y_max_m:g} m) lies "
                f"outside the region planner {planner.id!r} searches ({where}: x "
                f"{region.x_min_m:g} to {region.x_max_m:g} m, y {region.y_min_m:g} to "
                f"{region.y_max_m:g} m): every movement would be refused; make them overlap"
            ))


#: Bytes a map query on a grid holds per point: its coordinates, mean and std (float64),
#: and the recorded grid message.
GRID_POINT_BYTES = 48


def _check_snapshots(entries: list[ComponentEntry], run: Any, scene: Any, report: _Report
                     ) -> None:
    """Each map snapshot that ``run.mcap`` records queries its map on a grid of
    ``run.snapshot_spacing_m``: at most :data:`MAX_EVALUATION_POINTS` points."""
    if not (run.record and run.snapshot_rate_hz > 0):
        return
    by_id = {e.id: e for e in entries}
    spacing = run.snapshot_spacing_m
    worst: tuple[float, ComponentEntry, float, float] | None = None
    for entry in _of(entries, Kind.MAP):
        found = _region_of(entry, by_id, scene)
        if found is None:
            continue
        width, height = _sides(found[0])
        points = grid_points(width, height, spacing)
        if worst is None or points > worst[0]:
            worst = (points, entry, width, height)
    if worst is not None and worst[0] > MAX_EVALUATION_POINTS:
        points, entry, width, height = worst
        report.error("run.snapshot_spacing_m", (
            f"a snapshot of map {entry.id!r} on its {width:.4g} x {height:.4g} m region at "
            f"{spacing:g} m spacing takes {points:.3g} grid points (about "
            f"{format_bytes(points * GRID_POINT_BYTES)} a snapshot); the limit is "
            f"{MAX_EVALUATION_POINTS:.3g}: raise run.snapshot_spacing_m, or set "
            "run.snapshot_rate_hz: 0 to record no snapshots"
        ))


def _evaluated_map(entries: list[ComponentEntry], run: Any) -> ComponentEntry | None:
    """The map a run scores against the scene (:func:`evaluated_map_id`), None when
    ``run.evaluation_map`` names no map."""
    maps = {e.id: e for e in _of(entries, Kind.MAP)}
    chosen = evaluated_map_id(entries, run.evaluation_map)
    return None if chosen is None else maps.get(chosen)
