"""Frozen spec records that registration hooks yield.

A spec describes a plugin without importing its implementation: listing, validation and
schema generation need only the spec and its (import-light) pydantic config model. The
implementation is a ``"module:attribute"`` string resolved when an experiment is built.
"""

from __future__ import annotations

import importlib
import re
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, cast

from pydantic import BaseModel, ConfigDict

from hapticframe._contracts import ChannelSpec, as_channel_specs
from hapticframe._errors import PluginImportError
from hapticframe._kind import Kind

__all__ = [
    "BenchSpec",
    "ClassifierSpec",
    "FeatureExtractorSpec",
    "Knob",
    "MapSpec",
    "PlannerSpec",
    "PluginConfig",
    "PluginSpec",
    "RobotSpec",
    "SensorModelSpec",
    "SensorSpec",
    "resolve_reference",
]

_NAME = re.compile(r"^[a-z][a-z0-9]*(?:[-_][a-z0-9]+)*$")
_REFERENCE = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_][\w.]*$")
_FIELD_PATH = re.compile(r"^[a-z_][a-z0-9_]*(?:\.[a-z_][a-z0-9_]*)*$")


class PluginConfig(BaseModel):
    """Base class for plugin config models: frozen, unknown keys are errors, and every float
    must be finite (``inf`` and ``NaN`` are refused at ``validate``).

    A field that means "no limit" is optional (``None``), never infinite. Nested models of a
    config derive from this class too, so that the same holds inside them. Keep config
    modules import-light (pydantic, stdlib): they are imported to validate experiment files
    and to write schemas, where torch or pyserial must not load.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


#: Directories that lab-local plugin modules (``--plugin-module``) were imported from.
_LOCAL_MODULE_DIRS: list[str] = []


def add_local_module_dir(directory: str) -> None:
    """Remember where a ``--plugin-module`` was imported from: implementations in its
    sibling modules are then found there too (a lab keeps registration and
    implementation apart), without leaving the directory on ``sys.path``."""
    if directory not in _LOCAL_MODULE_DIRS:
        _LOCAL_MODULE_DIRS.append(directory)


def _import_module(module_name: str) -> Any:
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        top = module_name.partition(".")[0]
        if not _LOCAL_MODULE_DIRS or (exc.name or "").partition(".")[0] != top:
            raise
    added = [d for d in _LOCAL_MODULE_DIRS if d not in sys.path]
    sys.path[:0] = added
    try:
        return importlib.import_module(module_name)
    finally:
        for directory in added:
            sys.path.remove(directory)


def resolve_reference(reference: str, *, what: str = "", install_hint: str = "") -> Any:
    """Import ``"package.module:attribute"`` and return the attribute.

    Raises
    ------
    PluginImportError
        When the module cannot be imported or lacks the attribute; the message names
        ``what`` and the install hint.
    """
    module_name, _, attr_path = reference.partition(":")
    try:
        obj: Any = _import_module(module_name)
        for part in attr_path.split("."):
            obj = getattr(obj, part)
    except ImportError as exc:
        hint = f"; {install_hint}" if install_hint else ""
        raise PluginImportError(f"{what or reference} cannot be imported: {exc}{hint}") from exc
    except AttributeError as exc:
        raise PluginImportError(
            f"{what or reference}: {reference!r} does not exist ({exc})"
        ) from exc
    return obj


@dataclass(frozen=True)
class Knob:
    """A speed/accuracy knob a plugin declares (issue 18): a config field and the values
    worth trying, for ``hapticframe sweep --declared``.

    Parameters
    ----------
    field : str
        Dotted path of the field inside the component's ``config`` (``"hinge_spacing_m"``,
        ``"kernel.length_scale_m"``).
    trades : str
        One line: what the knob trades (``"finer hinges: sharper outline, cubic fit time"``).
    values : tuple
        The meaningful values, in order; or, instead, a range:
    low, high : float
        The range's ends (``low < high``; both positive for ``scale="log"``).
    scale : {"linear", "log"}
        How :meth:`sweep_values` spaces ``points`` values over the range.
    points : int
        How many values a range gives (at least 2).
    integer : bool
        Round a range's values to distinct integers (a count: atoms, layers, samples).
    """

    field: str
    trades: str
    values: tuple[Any, ...] = ()
    low: float | None = None
    high: float | None = None
    scale: str = "linear"
    points: int = 5
    integer: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.field, str) or not _FIELD_PATH.match(self.field):
            raise ValueError(f"knob field {self.field!r} must be a dotted path of field names")
        if not isinstance(self.trades, str) or not self.trades.strip() or "\n" in self.trades:
            raise ValueError(f"knob {self.field!r}: trades must be one non-empty line")
        object.__setattr__(self, "values", tuple(self.values))
        ranged = self.low is not None or self.high is not None
        if bool(self.values) == ranged:
            raise ValueError(f"knob {self.field!r}: give either values or low and high")
        if ranged:
            if self.low is None or self.high is None or not float(self.low) < float(self.high):
                raise ValueError(f"knob {self.field!r}: needs low < high")
            if self.scale not in ("linear", "log"):
                raise ValueError(f"knob {self.field!r}: scale must be 'linear' or 'log'")
            if self.scale == "log" and float(self.low) <= 0:
                raise ValueError(f"knob {self.field!r}: a log range needs low > 0")
            if int(self.points) < 2:
                raise ValueError(f"knob {self.field!r}: a range needs at least 2 points")

    def sweep_values(self) -> tuple[Any, ...]:
        """The values to sweep: ``values``, or ``points`` values spread over the range."""
        if self.values:
            return self.values
        import numpy as np

        assert self.low is not None and self.high is not None
        space = np.geomspace if self.scale == "log" else np.linspace
        grid = space(float(self.low), float(self.high), int(self.points))
        if self.integer:
            return tuple(dict.fromkeys(int(np.rint(v)) for v in grid))
        return tuple(float(v) for v in grid)


@dataclass(frozen=True)
class PluginSpec:
    """What a plugin registers: one record per (kind, name).

    Parameters
    ----------
    name : str
        Registry name used as ``type:`` in experiment files: lowercase letters, digits,
        ``-`` or ``_``.
    summary : str
        One line for ``hapticframe plugins``.
    config : type of PluginConfig
        The pydantic model validating the component's ``config`` (unknown keys rejected).
    factory : str
        ``"module:Attribute"`` of the implementation, called as ``factory(config, context)``.
        Resolved only when an experiment using the plugin is built.
    capabilities : frozenset of str
        Tags that select conformance checks and describe behaviour (``"trainable"``,
        ``"simulated"``, ``"needs-robot"``, ``"finite"``...).
    install_hint : str
        What to install when the plugin's requirements are missing.
    requires : tuple of str
        Top-level modules the implementation imports (``"torch"``); listing and validation
        check they are findable without importing them.
    inputs : tuple of Kind
        Kinds whose components may appear in this component's ``inputs``; the default is
        set per kind.
    consumes : mapping of str to ChannelSpec (or a shape tuple)
        The channels this plugin reads, its contract with its inputs: the shape of one
        sample (``None`` for an axis of any size), the unit and what it does with them
        (``{"force_n": ChannelSpec((None,), "N", "uses |F|", example=(2,))}``; a tuple is
        a shape of any unit). ``validate`` refuses an input that produces one of these
        channels in another shape or unit. The conformance kit feeds feature extractors and
        classifiers synthetic samples of this layout (``ChannelSpec.kit_shape``). Sensor
        models, maps and planners read their kind's record by default
        (``class_probabilities``, ``observations``, ``occupancy``).
    produces : mapping of str to ChannelSpec
        The channels this plugin delivers, as far as its spec can say before it is built
        (a sensor whose channels come from a file declares none); classifiers, sensor
        models, maps and robots produce their kind's record by default.
    sample_rate_hz : float
        Rate of the samples the kit feeds to ``consumes`` channels.
    check_config : mapping or None
        A small config (as a dict) the conformance kit builds the plugin with; None uses
        the config model's defaults.
    check_inputs : tuple of str
        Plugins the kit builds as this component's inputs, as ``"kind/name"``
        (``("robot/sandbox",)`` for a simulated sensor mounted on the sandbox robot).
    validator : str
        ``"module:function"`` of an import-light function that ``validate`` calls with the
        component's validated config and a :class:`hapticframe.ValidationContext` (its
        inputs' and every component's type and config, the scene, the run settings), for
        checks a config model alone cannot make (across fields, across components, against
        the scene). It yields :class:`hapticframe.Finding` records: errors refuse the file
        (exit 2, located at the finding's field), warnings are reported and the file is
        valid. ``""``: none.
    """

    kind: ClassVar[Kind]
    default_inputs: ClassVar[tuple[Kind, ...]] = ()
    #: What a plugin of this kind reads and delivers unless its spec says otherwise.
    default_consumes: ClassVar[Mapping[str, ChannelSpec]] = {}
    default_produces: ClassVar[Mapping[str, ChannelSpec]] = {}

    name: str
    summary: str
    config: type[PluginConfig]
    factory: str
    capabilities: frozenset[str] = field(default_factory=frozenset)
    install_hint: str = ""
    requires: tuple[str, ...] = ()
    inputs: tuple[Kind, ...] | None = None
    consumes: Mapping[str, ChannelSpec | tuple[int | None, ...]] = field(
        default_factory=dict, hash=False
    )
    produces: Mapping[str, ChannelSpec] = field(default_factory=dict, hash=False)
    sample_rate_hz: float = 100.0
    check_config: dict[str, Any] | None = field(default=None, hash=False)
    check_inputs: tuple[str, ...] = ()
    validator: str = ""
    knobs: tuple[Knob, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise ValueError(
                f"plugin name {self.name!r} must be lowercase letters and digits separated "
                "by '-' or '_'"
            )
        if not isinstance(self.summary, str) or not self.summary.strip() or "\n" in self.summary:
            raise ValueError(f"plugin {self.name!r}: summary must be one non-empty line")
        if not (isinstance(self.config, type) and issubclass(self.config, BaseModel)):
            raise TypeError(f"plugin {self.name!r}: config must be a pydantic model class")
        if self.config.model_config.get("extra") != "forbid":
            raise ValueError(
                f"plugin {self.name!r}: config model {self.config.__name__} must reject "
                "unknown keys (derive from hapticframe.PluginConfig)"
            )
        if not isinstance(self.factory, str) or not _REFERENCE.match(self.factory):
            raise ValueError(
                f"plugin {self.name!r}: factory must be a 'module:attribute' string, "
                f"got {self.factory!r}"
            )
        if self.validator and (
            not isinstance(self.validator, str) or not _REFERENCE.match(self.validator)
        ):
            raise ValueError(
                f"plugin {self.name!r}: validator must be a 'module:attribute' string, "
                f"got {self.validator!r}"
            )
        object.__setattr__(self, "capabilities", frozenset(self.capabilities))
        object.__setattr__(self, "requires", tuple(self.requires))
        object.__setattr__(self, "knobs", tuple(self.knobs))
        if not all(isinstance(k, Knob) for k in self.knobs):
            raise TypeError(f"plugin {self.name!r}: knobs must be hapticframe.Knob records")
        for ref in self.check_inputs:
            kind_name, _, plugin_name = ref.partition("/")
            if kind_name not in {k.value for k in Kind} or not plugin_name:
                raise ValueError(
                    f"plugin {self.name!r}: check_inputs entry {ref!r} must be 'kind/name'"
                )
        object.__setattr__(self, "check_inputs", tuple(self.check_inputs))
        what = f"plugin {self.name!r}"
        consumes = as_channel_specs(self.consumes, f"{what} consumes")
        produces = as_channel_specs(self.produces, f"{what} produces")
        object.__setattr__(self, "consumes", consumes or dict(self.default_consumes))
        object.__setattr__(self, "produces", produces or dict(self.default_produces))
        inputs = self.default_inputs if self.inputs is None else tuple(Kind(k) for k in self.inputs)
        object.__setattr__(self, "inputs", inputs)

    @property
    def reads(self) -> Mapping[str, ChannelSpec]:
        """``consumes`` as it is once the spec is built: every channel a ChannelSpec."""
        return cast(Mapping[str, ChannelSpec], self.consumes)

    @property
    def key(self) -> tuple[Kind, str]:
        return (self.kind, self.name)

    def load_validator(self) -> Any:
        """Import and return the ``validator`` function (None without one); its module must
        be import-light, like the config's: it runs when a file is validated."""
        if not self.validator:
            return None
        return resolve_reference(
            self.validator, what=f"the validator of {self.kind} plugin {self.name!r}",
            install_hint=self.install_hint,
        )

    def load_factory(self) -> Any:
        """Import and return the implementation (heavy imports happen here)."""
        return resolve_reference(
            self.factory, what=f"{self.kind} plugin {self.name!r}", install_hint=self.install_hint
        )


#: The records of the kinds after the classifiers, as channels of their contracts.
_PROBS = ChannelSpec((None,), "1", "one probability per class, classes[0] the background")
_POSE = ChannelSpec((3,), "m, m, rad", "the fingertip's x, y and heading (RobotState)")
_OBSERVATIONS = ChannelSpec(
    (2,), "m", "Observations: points (m, 2) m, targets in [0, 1], weights"
)
_OCCUPANCY = ChannelSpec((), "1", "MapEstimate: occupancy mean and std at (q, 2) points")


@dataclass(frozen=True)
class SensorSpec(PluginSpec):
    kind: ClassVar[Kind] = Kind.SENSOR
    default_inputs: ClassVar[tuple[Kind, ...]] = (Kind.ROBOT,)


@dataclass(frozen=True)
class FeatureExtractorSpec(PluginSpec):
    kind: ClassVar[Kind] = Kind.FEATURE_EXTRACTOR
    default_inputs: ClassVar[tuple[Kind, ...]] = (Kind.SENSOR, Kind.FEATURE_EXTRACTOR)


@dataclass(frozen=True)
class ClassifierSpec(PluginSpec):
    kind: ClassVar[Kind] = Kind.CLASSIFIER
    default_inputs: ClassVar[tuple[Kind, ...]] = (Kind.SENSOR, Kind.FEATURE_EXTRACTOR)
    default_produces: ClassVar[Mapping[str, ChannelSpec]] = {"class_probabilities": _PROBS}


@dataclass(frozen=True)
class SensorModelSpec(PluginSpec):
    kind: ClassVar[Kind] = Kind.SENSOR_MODEL
    default_inputs: ClassVar[tuple[Kind, ...]] = (Kind.CLASSIFIER, Kind.ROBOT, Kind.SENSOR)
    default_consumes: ClassVar[Mapping[str, ChannelSpec]] = {
        "class_probabilities": _PROBS, "pose": _POSE,
    }
    default_produces: ClassVar[Mapping[str, ChannelSpec]] = {"observations": _OBSERVATIONS}


@dataclass(frozen=True)
class MapSpec(PluginSpec):
    kind: ClassVar[Kind] = Kind.MAP
    default_inputs: ClassVar[tuple[Kind, ...]] = (Kind.SENSOR_MODEL,)
    default_consumes: ClassVar[Mapping[str, ChannelSpec]] = {"observations": _OBSERVATIONS}
    default_produces: ClassVar[Mapping[str, ChannelSpec]] = {"occupancy": _OCCUPANCY}


@dataclass(frozen=True)
class PlannerSpec(PluginSpec):
    kind: ClassVar[Kind] = Kind.PLANNER
    default_inputs: ClassVar[tuple[Kind, ...]] = (Kind.MAP,)
    default_consumes: ClassVar[Mapping[str, ChannelSpec]] = {"occupancy": _OCCUPANCY}


@dataclass(frozen=True)
class RobotSpec(PluginSpec):
    kind: ClassVar[Kind] = Kind.ROBOT
    default_inputs: ClassVar[tuple[Kind, ...]] = ()
    default_produces: ClassVar[Mapping[str, ChannelSpec]] = {"pose": _POSE}


SPEC_TYPES: dict[Kind, type[PluginSpec]] = {
    Kind.SENSOR: SensorSpec,
    Kind.FEATURE_EXTRACTOR: FeatureExtractorSpec,
    Kind.CLASSIFIER: ClassifierSpec,
    Kind.SENSOR_MODEL: SensorModelSpec,
    Kind.MAP: MapSpec,
    Kind.PLANNER: PlannerSpec,
    Kind.ROBOT: RobotSpec,
}


@dataclass(frozen=True)
class BenchSpec:
    """A benchmark suite run by ``hapticframe bench NAME``.

    ``factory`` names a function ``run(options: BenchOptions) -> dict`` that writes its
    report into ``options.out_dir`` and returns the headline figures.
    """

    name: str
    summary: str
    factory: str
    install_hint: str = ""

    def __post_init__(self) -> None:
        if not _NAME.match(self.name):
            raise ValueError(f"bench name {self.name!r} is not a valid name")
        if not _REFERENCE.match(self.factory):
            raise ValueError(f"bench {self.name!r}: factory must be a 'module:attribute' string")
