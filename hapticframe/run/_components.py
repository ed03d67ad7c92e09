"""The built components of a run: in build order, and by kind with their precise types."""

from __future__ import annotations

from collections.abc import ItemsView, Iterator, KeysView, Mapping, ValuesView

from hapticframe._errors import RunError
from hapticframe._kind import Kind
from hapticframe.kinds import (
    Classifier,
    Component,
    FeatureExtractor,
    Map,
    Planner,
    Robot,
    RunClock,
    Sensor,
    SensorModel,
)

__all__ = ["INTERFACES", "Components"]

#: The interface a component of each kind implements.
INTERFACES: Mapping[Kind, type[Component]] = {
    Kind.SENSOR: Sensor,
    Kind.FEATURE_EXTRACTOR: FeatureExtractor,
    Kind.CLASSIFIER: Classifier,
    Kind.SENSOR_MODEL: SensorModel,
    Kind.MAP: Map,
    Kind.PLANNER: Planner,
    Kind.ROBOT: Robot,
}


class Components(Mapping[str, Component]):
    """Built components by id, in build order, and by kind with their precise types.

    As a mapping it holds every component (``components[cid]``, ``.values()`` in build
    order); ``sensors``, ``feature_extractors``, ... (named like the experiment file's
    sections) hold those of one kind as their interface, so the run's modules call them
    without casts.
    """

    __slots__ = (
        "_all",
        "classifiers",
        "clock",
        "feature_extractors",
        "maps",
        "planners",
        "robots",
        "sensor_models",
        "sensors",
    )

    def __init__(self, clock: RunClock | None = None) -> None:
        #: The run's clock, handed to every component it built (``BuildContext.clock``).
        self.clock = clock if clock is not None else RunClock()
        self._all: dict[str, Component] = {}
        self.sensors: dict[str, Sensor] = {}
        self.feature_extractors: dict[str, FeatureExtractor] = {}
        self.classifiers: dict[str, Classifier] = {}
        self.sensor_models: dict[str, SensorModel] = {}
        self.maps: dict[str, Map] = {}
        self.planners: dict[str, Planner] = {}
        self.robots: dict[str, Robot] = {}

    def add(self, component_id: str, kind: Kind, component: object, *, plugin: str = "") -> None:
        """Add a built component of ``kind`` under ``component_id``, after those already added.

        Raises
        ------
        RunError
            When ``component`` does not implement the interface of ``kind`` (``plugin``, the
            plugin's name, is then named in the message), or the id is taken.
        """
        if component_id in self._all:
            raise RunError(f"two components are called {component_id!r}")
        # One branch per kind: each narrows `component` to the type its dict holds.
        if kind is Kind.SENSOR and isinstance(component, Sensor):
            self.sensors[component_id] = component
        elif kind is Kind.FEATURE_EXTRACTOR and isinstance(component, FeatureExtractor):
            self.feature_extractors[component_id] = component
        elif kind is Kind.CLASSIFIER and isinstance(component, Classifier):
            self.classifiers[component_id] = component
        elif kind is Kind.SENSOR_MODEL and isinstance(component, SensorModel):
            self.sensor_models[component_id] = component
        elif kind is Kind.MAP and isinstance(component, Map):
            self.maps[component_id] = component
        elif kind is Kind.PLANNER and isinstance(component, Planner):
            self.planners[component_id] = component
        elif kind is Kind.ROBOT and isinstance(component, Robot):
            self.robots[component_id] = component
        else:
            built = f"{kind} plugin {plugin!r} built" if plugin else f"{kind} {component_id!r} is"
            raise RunError(
                f"{built} a {type(component).__name__}, which is not a "
                f"hapticframe.kinds.{INTERFACES[kind].__name__}"
            )
        self._all[component_id] = component

    def __getitem__(self, component_id: str) -> Component:
        return self._all[component_id]

    def __iter__(self) -> Iterator[str]:
        return iter(self._all)

    def __len__(self) -> int:
        return len(self._all)

    def __contains__(self, component_id: object) -> bool:
        return component_id in self._all

    # The dict's own views: the same build order, without Mapping's per-item lookups.
    def keys(self) -> KeysView[str]:
        return self._all.keys()

    def values(self) -> ValuesView[Component]:
        return self._all.values()

    def items(self) -> ItemsView[str, Component]:
        return self._all.items()

    def __repr__(self) -> str:
        return f"<Components {list(self._all)!r}>"
