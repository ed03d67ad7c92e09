"""The kit's probe of the range ends a run meets (issue 36 §2): a lab plugin whose ramp may
be near zero, or whose thread count may exceed the machine's CPUs, fails it; the bundled
plugins' bounds pass it."""

from __future__ import annotations

import dataclasses

import pytest
from pydantic import Field

from hapticframe import get_registry
from hapticframe.testing import CheckFailure, check_run_range_ends


def _spec(kind: str, name: str):  # type: ignore[no-untyped-def]
    registry = get_registry()
    spec = next(r.spec for r in registry if (r.spec.kind.value, r.spec.name) == (kind, name))
    return registry, spec


def test_bundled_bounds_pass() -> None:
    for kind, name in (("robot", "sandbox"), ("map", "bayesian-hilbert-map"),
                       ("classifier", "force-rate-jamming"), ("planner", "coverage")):
        registry, spec = _spec(kind, name)
        check_run_range_ends(spec, registry=registry)


def test_a_ramp_open_down_to_zero_fails() -> None:
    registry, spec = _spec("robot", "sandbox")

    class Loose(spec.config):  # type: ignore[name-defined, misc]
        acceleration_m_per_s2: float | None = Field(None, gt=0, le=100)

    with pytest.raises(CheckFailure, match="acceleration_m_per_s2 = 5e-324"):
        check_run_range_ends(dataclasses.replace(spec, config=Loose), registry=registry)


def test_a_thread_count_past_the_machine_fails() -> None:
    registry, spec = _spec("map", "bayesian-hilbert-map")

    class Loose(spec.config):  # type: ignore[name-defined, misc]
        blas_threads: int | None = Field(1, ge=1, le=1024)

    with pytest.raises(CheckFailure, match="blas_threads = 1024 is accepted"):
        check_run_range_ends(dataclasses.replace(spec, config=Loose), registry=registry)


def test_a_planner_depth_that_may_be_zero_fails() -> None:
    registry, spec = _spec("planner", "coverage")

    class Loose(spec.config):  # type: ignore[name-defined, misc]
        depth_m: float | None = Field(None, ge=0, le=0.3)

    with pytest.raises(CheckFailure, match="depth_m = 0"):
        check_run_range_ends(dataclasses.replace(spec, config=Loose), registry=registry)
