"""Tests of the two-phase planner's search for every object (issue 19 §3), on fake maps."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import expit

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
from hapticframe_coverage._functional import free_runs, inside_or_near

SQUARE = np.array([[0.0, 0.0], [0.1, 0.0], [0.1, 0.1], [0.0, 0.1]])


class TwoBlobMap(Map):
    """Occupancy discs at two centres (the truth a perfect map would show)."""

    def __init__(self, centres, radius_m=0.04) -> None:
        super().__init__(None, BuildContext("blobs", np.random.default_rng(0)))
        self.centres = np.asarray(centres, dtype=float)
        self.radius_m = radius_m

    @property
    def region(self) -> Region:
        return Region(0.0, 0.75, 0.0, 0.50)

    def update(self, observations: Observations) -> None:  # the fake ignores data
        pass

    def query(self, points_m) -> MapEstimate:
        p = np.asarray(points_m, dtype=float).reshape(-1, 2)
        d = np.min(np.linalg.norm(p[:, None, :] - self.centres[None], axis=2), axis=1)
        mean = 0.02 + 0.96 * expit((self.radius_m - d) / 0.004)
        return MapEstimate(mean, np.full(len(p), 0.3))


def two_phase(map_: Map, **config: object) -> TwoPhaseCoverage:
    return TwoPhaseCoverage(TwoPhaseCoverageConfig(**config),
                            BuildContext("plan", np.random.default_rng(0), {"bhm": map_}))


def finish(index: int, movement: ExploratoryMovement, stop: np.ndarray | None) -> MovementResult:
    hit = stop is not None
    state = RobotState(float(index), stop if hit else movement.end_m, movement.heading_rad)
    return MovementResult(index, movement, hit, "interaction" if hit else "", state,
                          "jamming" if hit else "free")


def circle_hit(centre, radius, reach=0.02):
    """Stop where the fingertip first comes within ``reach`` of a circle's outline."""
    c = np.asarray(centre, dtype=float)

    def hit(m: ExploratoryMovement) -> np.ndarray | None:
        n = max(2, int(np.ceil(m.length_m / 0.005)) + 1)
        path = m.start_m + np.linspace(0, 1, n)[:, None] * (m.end_m - m.start_m)
        close = np.flatnonzero(np.linalg.norm(path - c, axis=1) <= radius + reach)
        return path[close[0]] if close.size else None

    return hit


def test_inside_or_near_marks_inside_and_the_margin_only():
    points = [[0.05, 0.05], [0.12, 0.05], [0.14, 0.05], [-0.01, -0.01], [0.3, 0.3]]
    assert inside_or_near(points, [SQUARE], 0.03).tolist() == [True, True, False, True, False]
    assert inside_or_near(points, [], 0.03).tolist() == [False] * 5


def test_free_runs_split_a_line_around_a_blocked_stretch():
    flags = np.zeros(11, dtype=bool)
    flags[4:7] = True
    parts = free_runs([0.0, 0.0], [1.0, 0.0], flags, 0.2)
    assert [(round(a[0], 3), round(b[0], 3)) for a, b in parts] == [(0.0, 0.3), (0.7, 1.0)]
    # Too short a free run is dropped; an all-free line is itself.
    assert len(free_runs([0.0, 0.0], [1.0, 0.0], flags, 0.35)) == 0
    whole = free_runs([0.0, 0.0], [1.0, 0.0], np.zeros(5, dtype=bool), 0.1)
    assert len(whole) == 1 and np.allclose(whole[0][1], [1.0, 0.0])


def _run_two(planner, centres, limit=60):
    hits = [circle_hit(c, 0.04) for c in centres]
    results = []
    for i in range(limit):
        movement = planner.propose()
        if movement is None:
            break
        stops = [s for s in (h(movement) for h in hits) if s is not None]
        # The fingertip stops at the first object along its path.
        stop = min(stops, key=lambda s: float(np.linalg.norm(s - movement.start_m))) \
            if stops else None
        result = finish(i, movement, stop)
        planner.on_movement_end(result)
        results.append(result)
    return results


CENTRES = [(0.2, 0.3), (0.55, 0.15)]


def test_every_object_is_localised_and_later_lines_keep_off_found_ones():
    planner = two_phase(TwoBlobMap(CENTRES), max_objects=None)
    results = _run_two(planner, CENTRES)
    assert planner.phase == "done"
    assert len(planner.found_centroids) == 2
    found = sorted(planner.found_centroids, key=lambda c: c[0])
    for estimate, truth in zip(found, CENTRES, strict=True):
        assert np.linalg.norm(estimate - truth) < 0.01
    # After the first object was kept, no movement enters its dilated outline.
    first = planner.found_outlines[0]
    index = next(i for i, r in enumerate(results) if r.movement.phase == "phase2")
    later = [r for r in results[index:] if r.movement.phase == "phase1"]
    assert later, "phase 1 resumed"
    for r in later:
        path = r.movement.start_m + np.linspace(0, 1, 50)[:, None] * (
            r.movement.end_m - r.movement.start_m)
        assert not inside_or_near(path, [first], 0.045).any()
    assert planner.phase_metrics()["objects_localised"] == 2


def test_max_objects_one_stops_after_the_first_object_as_before():
    single = two_phase(TwoBlobMap(CENTRES))
    results = _run_two(single, CENTRES)
    assert single.phase == "done" and len(single.found_centroids) == 1
    assert "objects_localised" not in single.phase_metrics()
    # The same decisions as a planner that never heard of several objects.
    again = _run_two(two_phase(TwoBlobMap(CENTRES), max_objects=1), CENTRES)
    assert [r.movement.label for r in results] == [r.movement.label for r in again]


def test_an_empty_region_is_exhausted_without_objects():
    planner = two_phase(TwoBlobMap(CENTRES), max_objects=None)
    moves = 0
    while (movement := planner.propose()) is not None:
        planner.on_movement_end(finish(moves, movement, None))
        moves += 1
    assert planner.phase == "done" and planner.found_centroids == []
    assert moves == len(planner.phase1_lines[0])


def test_max_objects_is_validated():
    with pytest.raises(ValueError):
        two_phase(TwoBlobMap(CENTRES), max_objects=0)
