"""The conformance kit passes every registered plugin (bundled ones included)."""

from hapticframe import get_registry
from hapticframe.testing import parametrize_with_checks

SPECS = [registered.spec for registered in get_registry()]


def test_the_registry_holds_the_bundled_plugins():
    registry = get_registry()
    assert not registry.broken, registry.broken
    assert not registry.conflicts, registry.conflicts
    names = {(r.spec.kind.value, r.spec.name) for r in registry}
    expected = {
        ("robot", "sandbox"),
        ("map", "bayesian-hilbert-map"),
        ("planner", "two-phase-coverage"),
    }
    assert expected <= names


@parametrize_with_checks(SPECS)
def test_conformance(spec, check):
    check(spec)
