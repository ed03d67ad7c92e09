"""Fewer object interactions (issue 19 §6): no reverse pass, movements that stop short."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError
from scipy.special import expit

from hapticframe import RegionConfig
from hapticframe.kinds import (
    BuildContext,
    ExploratoryMovement,
    Map,
    MapEstimate,
    MovementResult,
    Observations,
    Region,
    RobotState,
)
from hapticframe_coverage import TwoPhaseCoverage, TwoPhaseCoverageConfig

BOX = (0.0, 0.75, 0.0, 0.50)
CENTRE = np.array([0.30, 0.20])
RADIUS = 0.04


class DiscMap(Map):
    """Occupancy of a disc of radius ``RADIUS`` at ``CENTRE`` (the fake ignores data)."""

    def __init__(self) -> None:
        super().__init__(None, BuildContext("disc", np.random.default_rng(0)))

    @property
    def region(self) -> Region:
        return Region(*BOX)

    def update(self, observations: Observations) -> None:
        pass

    def query(self, points_m) -> MapEstimate:
        p = np.asarray(points_m, dtype=float).reshape(-1, 2)
        d = np.linalg.norm(p - CENTRE, axis=1)
        return MapEstimate(0.02 + 0.96 * expit((RADIUS - d) / 0.004), np.full(len(p), 0.3))


def planner(**config: object) -> TwoPhaseCoverage:
    return TwoPhaseCoverage(
        TwoPhaseCoverageConfig.model_validate({"region": RegionConfig(), **config}),
        BuildContext("plan", np.random.default_rng(3), {"bhm": DiscMap()}),
    )


def first_touch(m: ExploratoryMovement, reach: float) -> np.ndarray | None:
    """Where the fingertip first comes within ``reach`` of the disc (None: never)."""
    n = max(2, int(np.ceil(m.length_m / 0.002)) + 1)
    path = m.start_m + np.linspace(0, 1, n)[:, None] * (m.end_m - m.start_m)
    close = np.flatnonzero(np.linalg.norm(path - CENTRE, axis=1) <= RADIUS + reach)
    return path[close[0]] if close.size else None


def search(p: TwoPhaseCoverage, reach: float = 0.03) -> list[MovementResult]:
    results: list[MovementResult] = []
    for i in range(60):
        movement = p.propose()
        if movement is None:
            return results
        stop = first_touch(movement, reach)
        where = movement.end_m if stop is None else stop
        result = MovementResult(i, movement, stop is not None,
                                "interaction" if stop is not None else "",
                                RobotState(float(i), where, movement.heading_rad),
                                "free" if stop is None else "jamming")
        p.on_movement_end(result)
        results.append(result)
    raise AssertionError("the planner kept proposing")


def touches(results: list[MovementResult]) -> int:
    return sum(r.halted for r in results)


def test_defaults_keep_the_reverse_pass_and_rake_through() -> None:
    results = search(planner())
    phases = [r.movement.phase for r in results]
    first = next(i for i, r in enumerate(results) if r.halted)
    assert phases[first + 1] == "phase1"  # the reverse pass
    np.testing.assert_allclose(results[first + 1].movement.start_m, results[first].movement.end_m)
    assert not any("stopping short" in r.movement.label for r in results)


def test_without_the_reverse_pass_phase2_follows_the_first_touch() -> None:
    p = planner(phase1_reverse=False)
    results = search(p)
    first = next(i for i, r in enumerate(results) if r.halted)
    assert all(r.movement.phase == "phase1" for r in results[: first + 1])
    assert all(r.movement.phase == "phase2" for r in results[first + 1:])
    q = planner()
    search(q)
    assert p.phase_metrics()["ems_phase1"] == q.phase_metrics()["ems_phase1"] - 1


def test_stopping_short_keeps_off_the_object_and_still_stops() -> None:
    p = planner(stop_short_m=0.04, stop_short_after=2)
    results = search(p, reach=0.03)
    short = [r for r in results if "stopping short" in r.movement.label]
    assert short, "no movement stopped short"
    for r in short:
        # Ends stop_short_m outside the 0.6 outline (about RADIUS from the centre), so a
        # failure zone reaching 3 cm never touches the disc.
        gap = np.linalg.norm(r.movement.end_m - CENTRE) - RADIUS
        assert 0.035 <= gap <= 0.05
        assert not r.halted
        assert r.movement.length_m >= p.config.min_segment_m - 1e-9
    assert touches(results) == 2  # the phase-1 pair only
    assert len(p.probe_from_deg) == len(short)
    # The probes close the angular gap: the search ends well before the phase-2 cap.
    assert p.phase == "done"
    assert p.phase_metrics()["ems_phase2"] < p.config.max_phase2_movements
    raked = search(planner(), reach=0.03)
    assert touches(raked) > touches(results)


def test_stop_short_after_counts_interactions() -> None:
    p = planner(stop_short_m=0.04, stop_short_after=3)
    results = search(p, reach=0.03)
    phase2 = [r for r in results if r.movement.phase == "phase2"]
    assert not phase2[0].movement.label.endswith("stopping short")
    assert phase2[0].halted  # the third touch, aimed
    assert all("stopping short" in r.movement.label for r in phase2[1:])
    assert touches(results) == 3


@pytest.mark.parametrize("field, value", [("stop_short_m", 0.0), ("stop_short_m", -0.1),
                                          ("stop_short_after", -1)])
def test_stop_short_fields_are_validated(field: str, value: float) -> None:
    with pytest.raises(ValidationError, match=field):
        TwoPhaseCoverageConfig.model_validate({field: value})


def test_a_probe_from_a_small_region_starts_farther_back() -> None:
    # The 26 cm phase-2 square leaves 13 - 4 - 8 = 1 cm before an 8 cm margin: the probe
    # starts back along its line so that it still rakes min_segment_m.
    p = planner(stop_short_m=0.08, stop_short_after=2, phase2_region_size_m=0.26)
    results = search(p, reach=0.03)
    short = [r for r in results if "stopping short" in r.movement.label]
    assert short
    for r in short:
        assert r.movement.length_m >= p.config.min_segment_m - 1e-9
        assert np.linalg.norm(r.movement.end_m - CENTRE) - RADIUS >= 0.075
        assert np.linalg.norm(r.movement.start_m - CENTRE) > np.linalg.norm(
            r.movement.end_m - CENTRE)
