"""The conformance kit passes every registered plugin (bundled ones included)."""

from hapticframe import get_registry
from hapticframe.testing import parametrize_with_checks

SPECS = [registered.spec for registered in get_registry()]

BUNDLED = {
    ("sensor", "biotac"),
    ("sensor", "sandbox-force"),
    ("sensor", "robotiq-ft300"),
    ("sensor", "bno055"),
    ("sensor", "trace-recording"),
    ("sensor", "recording"),
    ("feature_extractor", "force-observer"),
    ("feature_extractor", "emd-features"),
    ("feature_extractor", "sparse-coding"),
    ("classifier", "force-rate-jamming"),
    ("classifier", "drag-ratio-jamming"),
    ("classifier", "fusion-rnn"),
    ("classifier", "linear-svm"),
    ("classifier", "sf-rnn"),
    ("classifier", "raking-estimator"),
    ("sensor_model", "distance-estimate"),
    ("sensor_model", "contact-point"),
    ("sensor_model", "failure-zone-kernel"),
    ("sensor_model", "learned-zone"),
    ("map", "bayesian-hilbert-map"),
    ("map", "gp-occupancy"),
    ("map", "belief-map"),
    ("map", "occupancy-grid"),
    ("planner", "coverage"),
    ("planner", "two-phase-coverage"),
    ("robot", "sandbox"),
    ("robot", "mpm-sand"),
    ("robot", "dynamixel"),
    ("robot", "barrett-wam"),
    ("robot", "barrett-hand"),
    ("robot", "ros2"),
    ("sensor", "ros2-topic"),
}


def test_the_registry_holds_the_bundled_plugins():
    registry = get_registry()
    assert not registry.broken, registry.broken
    assert not registry.conflicts, registry.conflicts
    names = {(r.spec.kind.value, r.spec.name) for r in registry}
    # Every bundled plugin: the kit runs on each here (and nowhere else in the tests).
    assert BUNDLED <= names, sorted(BUNDLED - names)


@parametrize_with_checks(SPECS)
def test_conformance(spec, check):
    check(spec)
