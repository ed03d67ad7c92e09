"""The built components of a run: by id in build order, and by kind with their types."""

import numpy as np
import pytest

from hapticframe import Kind, RunError
from hapticframe.kinds import BuildContext, Observations
from hapticframe.run._components import INTERFACES, Components
from hapticframe.testing import KitMap, make_component
from tests.support.lab import lab_main


class _Echo:
    """Not a component at all."""


def _kit_map(name: str) -> KitMap:
    the_map = KitMap()
    the_map.context = BuildContext(id=name, rng=np.random.default_rng(0))
    return the_map


def test_components_keep_build_order_and_file_each_under_its_kind():
    components = Components()
    first, second = _kit_map("b"), _kit_map("a")
    components.add("b", Kind.MAP, first)
    components.add("a", Kind.MAP, second)
    assert list(components) == ["b", "a"]
    assert list(components.values()) == [first, second]
    assert list(components.items()) == [("b", first), ("a", second)]
    assert components["a"] is second and "a" in components and len(components) == 2
    assert components.maps == {"b": first, "a": second}
    assert components.sensors == {} and components.robots == {}
    assert dict(components) == {"b": first, "a": second}


def test_a_component_of_another_kind_is_refused_with_the_plugin_named():
    components = Components()
    with pytest.raises(RunError, match=r"sensor plugin 'grid' built a KitMap, which is not a "
                                       r"hapticframe\.kinds\.Sensor"):
        components.add("s", Kind.SENSOR, KitMap(), plugin="grid")
    wrong = r"map 'm' is a _Echo, which is not a hapticframe\.kinds\.Map"
    with pytest.raises(RunError, match=wrong):
        components.add("m", Kind.MAP, _Echo())
    assert len(components) == 0 and components.sensors == {}


def test_an_id_is_added_once():
    components = Components()
    components.add("m", Kind.MAP, KitMap())
    with pytest.raises(RunError, match="two components are called 'm'"):
        components.add("m", Kind.MAP, KitMap())


def test_every_kind_has_its_interface():
    assert set(INTERFACES) == set(Kind)
    assert all(interface.kind is kind for kind, interface in INTERFACES.items())


def test_observations_weights_are_an_array_even_when_not_given():
    obs = Observations([[0.0, 0.0], [1.0, 1.0]], [0.0, 1.0])
    assert obs.weights.dtype == np.float64 and obs.weights.tolist() == [1.0, 1.0]
    assert not obs.weights.flags.writeable
    given = Observations([[0.0, 0.0]], [1.0], weights=[0.25])
    assert given.weights.tolist() == [0.25]
    assert Observations.concatenate([obs, given]).weights.tolist() == [1.0, 1.0, 0.25]


def test_make_component_checks_the_interface_it_is_asked_for():
    from hapticframe import get_registry
    from hapticframe.kinds import Map, Sensor
    from hapticframe.testing import CheckFailure

    registry = get_registry()
    name = registry.names(Kind.MAP)[0]
    spec = registry.plugins[Kind.MAP][name].spec
    built = make_component(spec, registry=registry, interface=Map)
    try:
        assert isinstance(built, Map)
    finally:
        built.close()
    with pytest.raises(CheckFailure, match=r"not a hapticframe\.kinds\.Sensor"):
        make_component(spec, registry=registry, interface=Sensor)


@pytest.mark.parametrize(("chosen", "said"), [("sweep", "a sensor"), ("nothing", "no component")])
def test_run_evaluation_map_must_name_a_map(lab_dir, capsys, chosen, said):
    path = lab_dir / "lab-open-loop.yaml"
    setting = f"seed: 3\nrun: {{evaluation_map: {chosen}}}"
    path.write_text(path.read_text().replace("seed: 3", setting))
    # Refused at validate (exit 2), before anything is built or written.
    assert lab_main(["run", str(path), "--out", str(lab_dir / "run"), "--quiet"]) == 2
    assert f"run.evaluation_map {chosen!r} names {said}, not a map" in capsys.readouterr().err
    assert not (lab_dir / "run").exists()


def test_build_context_finds_an_input_channel_of_a_sensor_or_an_extractor():
    from collections.abc import Mapping

    from hapticframe.kinds import (
        BuildContext,
        ChannelInfo,
        FeatureExtractor,
        SampleBatch,
        Sensor,
    )

    class Source(Sensor):
        channels: Mapping[str, ChannelInfo] = {"force_n": ChannelInfo((3,), "N", 125.0)}

        def read(self) -> SampleBatch:
            return SampleBatch.empty(self.channels)

    class Features(FeatureExtractor):
        output_channels: Mapping[str, ChannelInfo] = {"f": ChannelInfo((2,), "1", 40.0)}

        def update(self, batch: SampleBatch) -> SampleBatch:
            return batch

    rng = np.random.default_rng(0)
    source = Source(None, BuildContext("s", rng))
    features = Features(None, BuildContext("e", rng))
    context = BuildContext("c", rng, inputs={"s": source, "e": features})
    assert context.input_channel("force_n") == ChannelInfo((3,), "N", 125.0)
    assert context.input_channel("f").rate_hz == 40.0
    assert context.input_channel("missing") is None
