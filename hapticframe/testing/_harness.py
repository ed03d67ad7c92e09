"""Building components for checks, synthetic inputs, and the kit's stand-in map."""

from __future__ import annotations

import traceback
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar, overload

import numpy as np
from numpy.typing import NDArray

from hapticframe._kind import Kind
from hapticframe._manager import get_registry
from hapticframe._registry import Registry
from hapticframe._scene import Circle, Scene
from hapticframe._specs import PluginSpec
from hapticframe.kinds import (
    BuildContext,
    Component,
    Device,
    ExploratoryMovement,
    Map,
    MapEstimate,
    Observations,
    Region,
    Robot,
    RunClock,
    SampleBatch,
)

__all__ = [
    "CheckFailure",
    "DEFAULT_SCENE",
    "KitMap",
    "crossing_movement",
    "make_component",
    "raised_by_record_validation",
    "release_component",
    "synthetic_batch",
]

#: The scene components are built in: the thesis's region with one 8 cm circle.
DEFAULT_SCENE = Scene(objects=[Circle(center_m=(0.40, 0.25), radius_m=0.04)])


class CheckFailure(AssertionError):
    """A plugin broke the contract a check verifies; the message says which and how."""


def raised_by_record_validation(exc: BaseException) -> bool:
    """True when ``exc`` came from a hapticframe record rejecting a plugin's output."""
    frames = traceback.extract_tb(exc.__traceback__)
    return bool(frames) and Path(frames[-1].filename).name == "_records.py"


class KitMap(Map):
    """A map the kit hands to planners: a fixed occupancy blob, optionally learned from data.

    Before ``update`` it reports a uniform 0.5; after an update it reports a Gaussian blob
    at the mean of the observations whose target exceeds 0.5.
    """

    def __init__(self, region: Region | None = None) -> None:
        super().__init__(None, BuildContext(id="kit-map", rng=np.random.default_rng(0)))
        self._region = region or DEFAULT_SCENE.region.to_region()
        self.center: np.ndarray | None = None

    @property
    def region(self) -> Region:
        return self._region

    def reset(self) -> None:
        self.center = None

    def update(self, observations: Observations) -> None:
        hits = observations.points_m[observations.targets > 0.5]
        if len(hits):
            self.center = hits.mean(axis=0)

    def _query(self, p: NDArray[np.float64]) -> MapEstimate:
        if self.center is None:
            return MapEstimate(np.full(len(p), 0.5), np.full(len(p), 0.5))
        d2 = np.sum((p - self.center) ** 2, axis=1)
        mean = 0.05 + 0.9 * np.exp(-d2 / (2 * 0.03**2))
        return MapEstimate(mean, 0.5 * (1 - mean) + 0.01)


C = TypeVar("C", bound=Component)


@overload
def make_component(
    spec: PluginSpec,
    *,
    registry: Registry | None = None,
    seed: int = 0,
    scene: Scene | None = DEFAULT_SCENE,
    config: Mapping[str, Any] | None = None,
    planner_map: Map | None = None,
    interface: type[C],
    _depth: int = 0,
) -> C: ...


@overload
def make_component(
    spec: PluginSpec,
    *,
    registry: Registry | None = None,
    seed: int = 0,
    scene: Scene | None = DEFAULT_SCENE,
    config: Mapping[str, Any] | None = None,
    planner_map: Map | None = None,
    interface: None = None,
    _depth: int = 0,
) -> Component: ...


def make_component(
    spec: PluginSpec,
    *,
    registry: Registry | None = None,
    seed: int = 0,
    scene: Scene | None = DEFAULT_SCENE,
    config: Mapping[str, Any] | None = None,
    planner_map: Map | None = None,
    interface: type[Component] | None = None,
    _depth: int = 0,
) -> Component:
    """Build ``spec`` the way the conformance kit does.

    The config is ``spec.check_config`` (or the model's defaults), the scene is
    :data:`DEFAULT_SCENE`, and the inputs are built from ``spec.check_inputs``; a planner
    without ``check_inputs`` gets a :class:`KitMap` as input ``"map"``. ``planner_map``, for
    a planner, replaces that stand-in and every map named in ``check_inputs``.
    ``interface`` (``Sensor``, ``Map``, ...) is the class the component must be an instance
    of; it is also the type a type checker sees returned (default:
    :class:`~hapticframe.kinds.Component`).

    A :class:`~hapticframe.kinds.Device` (and every device among the inputs) is configured
    and activated, as a run does before its loop; :func:`release_component` (or the
    device's ``close()``) takes it down again.

    Raises
    ------
    CheckFailure
        When the factory builds something that is not an instance of ``interface``, or a
        device fails to configure or activate.
    """
    if _depth > 5:
        raise CheckFailure(f"check_inputs of {spec.name!r} nest too deeply (a cycle?)")
    registry = registry or get_registry()
    given = config if config is not None else (spec.check_config or {})
    cfg = spec.config.model_validate(dict(given))
    inputs: dict[str, Component] = {}
    for ref in spec.check_inputs:
        kind_name, _, name = ref.partition("/")
        kind = Kind(kind_name)
        if name not in registry.plugins[kind]:
            raise CheckFailure(
                f"check_inputs names {ref!r}, which is not installed: "
                + registry.unknown_message(kind, name)
            )
        inputs[f"{kind_name}-{name}"] = make_component(
            registry.plugins[kind][name].spec, registry=registry, seed=seed + 1, scene=scene,
            _depth=_depth + 1,
        )
    if spec.kind is Kind.PLANNER:
        if not spec.check_inputs:
            inputs["map"] = planner_map or KitMap(scene.region.to_region() if scene else None)
        elif planner_map is not None:
            for key, component in inputs.items():
                if isinstance(component, Map):
                    component.close()
                    inputs[key] = planner_map
    factory = spec.load_factory()
    context = BuildContext(
        id=f"kit-{spec.name}", rng=np.random.default_rng(seed), inputs=inputs, scene=scene,
        clock=_kit_clock(inputs),
    )
    own_inputs = [c for c in inputs.values() if c is not planner_map]
    try:
        built: object = factory(cfg, context)
    except BaseException:
        _release_all(own_inputs)
        raise
    if isinstance(built, Component):
        _KIT_INPUTS[id(built)] = own_inputs  # released with it (release_component)
    wanted = interface or Component
    if not isinstance(built, wanted):
        if isinstance(built, Component):
            release_component(built)
        raise CheckFailure(
            f"{spec.factory!r} built {type(built).__name__}, not a "
            f"hapticframe.kinds.{wanted.__name__}"
        )
    if isinstance(built, Device):
        try:
            built.configure()
            built.activate()
        except Exception as exc:
            release_component(built)
            raise CheckFailure(
                f"device {spec.name!r} failed to come up (configure, activate): "
                f"{type(exc).__name__}: {exc}"
            ) from exc
    return built


def _kit_clock(inputs: Mapping[str, Component]) -> RunClock:
    """The clock the kit hands a component, as a run does: its first robot input's time and
    control period, else a clock at 100 Hz that the kit advances one period per read."""
    clock = RunClock()
    robots = [c for c in inputs.values() if isinstance(c, Robot)]
    if robots:
        robot = robots[0]
        clock.follow(lambda: float(robot.state.timestamp_s), 1.0 / float(robot.control_rate_hz))
    return clock


#: The inputs the kit built for a component (by ``id``), released with it.
_KIT_INPUTS: dict[int, list[Component]] = {}


def release_component(component: Component) -> None:
    """Close a component the kit built: a device is deactivated and cleaned up first (as a
    run does after its loop), then ``close()`` runs whatever happened before; then the
    inputs the kit built for it (``check_inputs``: an emulated carrier arm) the same way."""
    try:
        if isinstance(component, Device):
            try:
                component.deactivate()
            finally:
                component.cleanup()
    finally:
        try:
            component.close()
        finally:
            _release_all(_KIT_INPUTS.pop(id(component), []))


def _release_all(components: list[Component]) -> None:
    """Release each of ``components``, every one even when another fails."""
    errors: list[BaseException] = []
    for component in components:
        try:
            release_component(component)
        except Exception as exc:  # release the rest, then report the first failure
            errors.append(exc)
    if errors:
        raise errors[0]


def synthetic_batch(
    spec: PluginSpec,
    n: int,
    *,
    rng: np.random.Generator,
    t0: float = 0.0,
    fill: str = "noise",
) -> SampleBatch:
    """Samples in the layout of ``spec.consumes``.

    ``fill`` is ``"noise"`` (a smooth random walk plus noise), ``"zero"``, ``"constant"``
    (3.0), ``"huge"`` (1e9), ``"tiny"`` (1e-12) or ``"nan"`` (noise with every fifth sample
    NaN).
    """
    if not spec.consumes:
        raise CheckFailure(
            f"{spec.kind} plugin {spec.name!r} declares no 'consumes' channels, so the kit "
            "cannot feed it; set consumes={'channel': shape} in its spec"
        )
    dt = 1.0 / spec.sample_rate_hz
    t = np.asarray(t0 + dt * (1 + np.arange(n)), dtype=np.float64)
    channels = {}
    for name, channel in spec.reads.items():
        size = (n, *channel.kit_shape)
        if fill == "zero":
            values = np.zeros(size)
        elif fill == "constant":
            values = np.full(size, 3.0)
        elif fill in ("huge", "tiny"):
            scale = 1e9 if fill == "huge" else 1e-12
            values = scale * (1 + 0.1 * rng.standard_normal(size))
        else:
            walk = np.cumsum(rng.standard_normal(size), axis=0) * 0.3
            values = 5.0 + walk + rng.standard_normal(size)
            if fill == "nan":
                values[::5] = np.nan
        channels[name] = values
    return SampleBatch(t, channels)


def crossing_movement(scene: Scene | None, robot: Robot | None = None) -> ExploratoryMovement:
    """A straight movement across the scene's region through its first object's row."""
    region = (scene or DEFAULT_SCENE).region.to_region()
    y = float(region.center_m[1])
    if scene is not None and scene.objects:
        y = float(scene.objects[0].centroid_m[1])
    margin = 0.02 * region.size_m[0]
    return ExploratoryMovement(
        start_m=np.array([region.x_min_m + margin, y]),
        end_m=np.array([region.x_max_m - margin, y]),
        speed_m_per_s=0.05, phase="kit", label="kit crossing",
    )

