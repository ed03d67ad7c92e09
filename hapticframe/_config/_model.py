"""The experiment model, built afresh from the registry as tagged unions on ``type``."""

from __future__ import annotations

import functools
import operator
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import pluggy
from pydantic import BaseModel, ConfigDict, Field, ValidationError, create_model

from hapticframe._config._roles import evaluated_map_id
from hapticframe._defaults import OUTLINE_LEVEL
from hapticframe._errors import Issue
from hapticframe._kind import Kind
from hapticframe._registry import Registered, Registry
from hapticframe._scene import NAME_PATTERN, Scene
from hapticframe._specs import PluginSpec

__all__ = [
    "ComponentEntry",
    "Experiment",
    "ID_PATTERN",
    "SCHEMA_VERSION",
    "ExperimentRoot",
    "RunSettings",
    "build_experiment_model",
]

SCHEMA_VERSION = 1
ID_PATTERN = r"^[A-Za-z][A-Za-z0-9_-]{0,63}$"
MODULE_PATTERN = r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$"

_STRICT = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

#: A component id as experiment files write it.
_ComponentId = Annotated[str, Field(pattern=ID_PATTERN)]
#: A channel name: the characters of an id (no spaces, no control characters).
CHANNEL_PATTERN = r"^[A-Za-z_][A-Za-z0-9_.-]{0,63}$"
#: Free text: no control characters but tab and newline.
TEXT_PATTERN = r"^[^\x00-\x08\x0b-\x1f\x7f-\x9f]*$"
#: An integer that is written as one: ``true`` and ``"7"`` are refused, not read as 1 and 7.
_Count = Annotated[int, Field(strict=True)]


class RunSettings(BaseModel):
    """How ``hapticframe run`` drives the components."""

    model_config = _STRICT
    halt_on_interaction: bool = Field(
        True,
        description="Stop an exploratory movement as soon as a classifier's most probable "
        "class is not its background class (classes[0]).",
    )
    max_movements: _Count = Field(50, ge=1, le=10_000, description="Upper bound on movements.")
    max_steps_per_movement: _Count = Field(
        100_000, ge=1, le=100_000_000,
        description="Robot steps per movement. `validate` refuses a value below the steps "
        "the longest line of the planner's region takes at its speed and the robot's control "
        "rate, where the configs say both (planner `speed_m_per_s`, robot `control_rate_hz`).",
    )
    max_reads: _Count = Field(
        1_000_000, ge=1, le=10**10,
        description="Safety bound on the sensor reads of an open-loop run (no robot): a run "
        "that reaches it before its sensors end (or its duration_s) stopped at a limit and "
        "is no result (run.json: status failed, details.limit; exit 1).",
    )
    duration_s: float | None = Field(
        None, gt=0, le=1e7,
        description="An open-loop run's length in seconds of the run's clock, which moves "
        "one control period (live_tick_s) per read: the run reads its sensors "
        "ceil(duration_s / live_tick_s) times. Required when a streamed sensor never ends "
        "(does not declare 'finite'); None: until every sensor ends. A closed loop ends with "
        "its planner or max_movements instead.",
    )
    map_update_every_steps: _Count = Field(
        0, ge=0,
        description="Update maps every N steps during a movement; 0 updates once per movement.",
    )
    lookahead_steps: _Count = Field(
        64, ge=1, le=4096,
        description="Robot steps a closed loop may simulate ahead and classify as one batch "
        "when the robot, the streamed sensors, the feature extractors and the classifiers "
        "can all rewind (simulators); a batch that holds an interaction is rewound and "
        "replayed one step at a time, so results are the same for every value. 1 steps one "
        "at a time.",
    )
    outline_level: float = Field(
        OUTLINE_LEVEL, gt=0, lt=1,
        description="Occupancy level of the estimated outline (thesis: 0.6).",
    )
    evaluation_map: _ComponentId | None = Field(
        None,
        description="Map id scored against the scene (it must name a map of the "
        "experiment); default: the planner's map.",
    )
    found_within_m: float | None = Field(
        None, gt=0, le=10.0,
        description="Scoring: the object counts as found when the estimated centroid lies "
        "within this distance of the nearest true object's centroid; None: within that "
        "object's reach (the largest distance from its centroid to its outline: the radius "
        "of a circle, the semi-major axis of an ellipse), i.e. the estimate lies in the "
        "circle about the true centroid that holds the object. metrics.json records the "
        "distance used (found_within_m).",
    )
    label_channel: str = Field(
        "contact", pattern=CHANNEL_PATTERN,
        description="Sensor channel holding per-sample class labels for `hapticframe train` "
        "and `train_from`.",
    )
    train_from: dict[_ComponentId, _ComponentId] = Field(
        default_factory=dict,
        description="Fit the feature extractors and classifiers before the run, as `hapticframe "
        "train` would: maps the id of a sensor the run streams to the id of a finite sensor "
        "whose recordings stand in for it while fitting. Training sensors are not streamed "
        "during the run and no component may name them in its inputs.",
    )
    calibration_runs: list[Annotated[str, Field(min_length=1, max_length=4096)]] = Field(
        default_factory=list, max_length=1000,
        description="`hapticframe train`: recorded calibration runs (their --out "
        "directories) to fit the sensor models that learn from calibration recordings "
        "(TrainableSensorModel, e.g. learned-zone): robot poses, what the sensor model's "
        "classifier reported and the scene's known objects. `train --calibration DIR` adds "
        "one. Record them over an object buried where you know it, with "
        "run.halt_on_interaction: false.",
    )
    figures: bool = Field(
        True, description="Let components write their figures (benchmarks switch this off)."
    )
    evaluation_spacing_m: float = Field(
        0.0025, gt=0, le=0.05, description="Grid spacing for outline and centroid estimates."
    )
    force_limit_n: float | None = Field(
        80.0, gt=0, le=100_000,
        description="Safety: the first valid sample of a streamed sensor's force channel "
        "(unit N; the magnitude over its components) above this halts the robot in the same "
        "tick, reason 'force_limit' (dissertation 3.5.3.3: 80 N). The halt latency in robot "
        "steps goes to metrics.json (halt_latency_samples_max). null disables the limit.",
    )
    force_stall_s: float | None = Field(
        0.25, gt=0, le=3600,
        description="Safety: while a movement is active, no valid force sample for this long "
        "(by the robot's state timestamps) halts the robot, reason 'force_stream_stalled'. "
        "Only in runs that stream a force sensor; null disables it.",
    )
    stall_resumes: _Count = Field(
        2, ge=0, le=100,
        description="A movement halted for a stalled force stream ('force_stream_stalled', "
        "e.g. a sensor being replugged) resumes this many times at most: the same robot "
        "continues the line from where it stopped once the stall check passes again, the "
        "parts one movement; then it ends halted. 0: never resume.",
    )
    record: bool = Field(
        True,
        description="Record the run as it happens into run.mcap (every sensor batch, "
        "classifier output, observation, robot state, movement, halt and device health), "
        "synced to disk about once a second so that a killed run keeps all but its last "
        "second (`hapticframe recover`).",
    )
    snapshot_rate_hz: float = Field(
        5.0, ge=0, le=1000,
        description="Map snapshots in run.mcap (`/map/<id>/grid`, foxglove.Grid: occupancy "
        "mean and std) and fingertip poses (`/robot/<id>/pose`) per second of model time; "
        "a snapshot is taken when the maps are updated and one is due. 0: none.",
    )
    snapshot_spacing_m: float = Field(
        0.01, gt=0, le=0.1,
        description="Grid spacing of the map snapshots in run.mcap (metres); coarser where "
        "the region needs more than snapshot_max_cells cells at this spacing.",
    )
    snapshot_max_cells: int = Field(
        16384, ge=1, le=10_000_000,
        description="Most grid cells in one map snapshot: over a large region the snapshot's "
        "spacing grows until its grid has at most this many, so that recording costs the "
        "same share of the run at every region size (16384: the 0.75 x 0.5 m search area "
        "at 1 cm, a 3 x 2 m region at 1.9 cm, 10 x 10 m at 7.9 cm).",
    )
    snapshot_cpu_share: float = Field(
        0.03, gt=0, le=1.0,
        description="Largest share of the run's CPU time that map snapshots may take (0.03: "
        "the recording's other writes took 4-7 % of a 10 x 10 m search as measured, and the whole "
        "recording's budget is 10 %): a "
        "snapshot that is due is skipped while the snapshots so far took more (the maps' "
        "last state is always written). Small maps stay at snapshot_rate_hz; a large map's "
        "snapshots (the grid moments of each tile changed since the last one; unchanged "
        "tiles' are kept) thin out, so the snapshots cost at most this share at every "
        "region size. 1: every due snapshot.",
    )
    live_tick_s: float = Field(
        0.01, gt=0, le=10.0,
        description="With a live device (real hardware), the shortest wall-clock time between "
        "two reads of an open loop's sensors; a closed loop waits the robot's control period "
        "per step instead. Simulated and emulated runs are never paced.",
    )


def _default_factory(config: type[BaseModel]) -> Any:
    try:
        config()
    except ValidationError:
        return ...  # required: the plugin has no usable defaults
    return Field(default_factory=config)


def _variant(spec: PluginSpec) -> type[BaseModel]:
    title = "".join(part.capitalize() for part in spec.name.replace("_", "-").split("-"))
    default = _default_factory(spec.config)
    config_field: Any = (spec.config, default)
    # The tag's value is known only at run time: a type built from it is a value to mypy.
    tag: Any = Literal[spec.name]
    return create_model(
        f"{title}{''.join(p.capitalize() for p in spec.kind.value.split('_'))}Component",
        __config__=_STRICT,
        __doc__=spec.summary,
        id=(str, Field(pattern=ID_PATTERN, description="Unique instance name.")),
        type=(tag, Field(description=spec.summary)),
        config=config_field,
        inputs=(list[_ComponentId],
                Field(default_factory=list, description="Ids of the components this one reads.")),
    )


def _section_type(registry: Registry, kind: Kind) -> Any:
    variants = [_variant(registry.plugins[kind][name].spec) for name in registry.names(kind)]
    if not variants:
        # No plugin of this kind is installed: the section must stay empty.
        return (list[dict[str, Any]], Field(default_factory=list, max_length=0))
    # Built from the installed plugins at run time: to mypy a value, not a type.
    members: Any = functools.reduce(operator.or_, variants)
    union: Any = Annotated[members, Field(discriminator="type")]
    section: Any = list[union]
    return (section, Field(default_factory=list))


class ExperimentRoot(BaseModel):
    """The sections of an experiment file that every registry shares.

    :func:`build_experiment_model` adds one list per plugin kind (``sensors``, ``maps``, ...),
    typed by the installed plugins; the core reads components from
    :attr:`Experiment.components <hapticframe.Experiment.components>`, and these fields
    from ``experiment.model``.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False,
                              title="hapticframe experiment")

    # Literal[SCHEMA_VERSION]: a type checker accepts only a literal value here.
    schema_version: Literal[1] = Field(description="Experiment file format version.")
    name: str = Field(
        pattern=NAME_PATTERN,
        description="Name of the experiment: one line of at most 200 characters, no control "
        "characters.",
    )
    description: str = Field(
        "", max_length=10_000, pattern=TEXT_PATTERN,
        description="Free text (tabs and newlines, no other control characters).",
    )
    seed: int = Field(
        ge=0, lt=2**63, strict=True,
        description="Seeds every component's random generator: a non-negative integer "
        "(`true` or a string is refused).",
    )
    scene: Scene | None = Field(None, description="What the simulated world contains.")
    run: RunSettings = Field(default_factory=RunSettings)


_CACHE: dict[str, type[ExperimentRoot]] = {}


def build_experiment_model(registry: Registry) -> type[ExperimentRoot]:
    """The root model of an experiment file for the plugins in ``registry`` (cached)."""
    key = registry.fingerprint()
    cached = _CACHE.get(key)
    if cached is not None:
        return cached
    sections = {kind.section: _section_type(registry, kind) for kind in Kind}
    model = create_model(
        "Experiment",
        __base__=ExperimentRoot,
        __doc__="A hapticframe experiment: the components to build and how to run them.",
        **sections,
    )
    _CACHE[key] = model
    return model


@dataclass(frozen=True)
class ComponentEntry:
    """One validated component of an experiment."""

    kind: Kind
    id: str
    type: str
    config: BaseModel
    inputs: tuple[str, ...]
    registered: Registered
    path: str  # dotted location in the file, e.g. "maps[0]"


@dataclass(frozen=True)
class Experiment:
    """A validated experiment: the root model and its components in build order."""

    file: str
    model: ExperimentRoot
    components: tuple[ComponentEntry, ...]
    registry: Registry
    plugin_manager: pluggy.PluginManager
    #: Legal but suspicious: what plugin validators warned about (located).
    warnings: tuple[Issue, ...] = ()
    #: What ``--set`` changed of the file before validation: one JSON-ready record per
    #: override (see :mod:`hapticframe._config._overrides`).
    overrides: tuple[dict[str, Any], ...] = ()

    @property
    def seed(self) -> int:
        return self.model.seed

    def resolved_config(self) -> dict[str, Any]:
        """The experiment with every default filled in, as JSON-ready data."""
        return self.model.model_dump(mode="json")

    def of_kind(self, kind: Kind) -> list[ComponentEntry]:
        return [c for c in self.components if c.kind is kind]

    def evaluated_map(self) -> str | None:
        """The id of the map the run scores against the scene (``run.evaluation_map``, else
        the first map a planner reads, else the last map; see :func:`evaluated_map_id`)."""
        return evaluated_map_id(self.components, self.model.run.evaluation_map)
