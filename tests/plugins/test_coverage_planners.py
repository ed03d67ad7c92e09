"""Tests of the two-phase coverage planner and the boustrophedon baseline.

The maps here are small fakes whose query returns a blob we control, so the planners are
tested without any real map plugin.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scipy.special import expit

from hapticframe import Circle, RegionConfig, Scene
from hapticframe.kinds import (
    BuildContext,
    ExploratoryMovement,
    Map,
    MapEstimate,
    MovementResult,
    Observations,
    Region,
    RobotState,
    RunOutcome,
)
from hapticframe_coverage import (
    BoustrophedonCoverage,
    CoverageConfig,
    TwoPhaseCoverage,
    TwoPhaseCoverageConfig,
)
from hapticframe_coverage import plugin as coverage_plugin
from hapticframe_coverage._functional import (
    angle_gap_deg,
    binary_search_order,
    largest_angular_gap_deg,
    outer_last_order,
)

BOX = (0.0, 0.75, 0.0, 0.50)
#: The dissertation's strategy as first implemented: 3.5 cm binary-search lines, the whole
#: region shrinking by 25 %, random sweep angles, the λ stopping rule.
THESIS = {
    "line_spacing_m": 0.035,
    "phase1_order": "binary",
    "phase2_region_size_m": None,
    "min_region_size_m": 0.10,
    "sweep_rule": "random",
    "stop_rule": "uncertain-area",
    "met_from": "heading",
}


class BlobMap(Map):
    """A map whose occupancy is a disc of radius ``radius_m`` at ``centre_m``."""

    def __init__(self, centre_m=(0.3, 0.2), radius_m=0.04, std=0.3, bounds=BOX) -> None:
        super().__init__(None, BuildContext("blob", np.random.default_rng(0)))
        self._region = Region(*bounds)
        self.centre_m = np.asarray(centre_m, dtype=float)
        self.radius_m = radius_m
        self.std = std
        self.queries = 0

    @property
    def region(self) -> Region:
        return self._region

    def update(self, observations: Observations) -> None:  # the fake ignores data
        pass

    def query(self, points_m) -> MapEstimate:
        self.queries += 1
        p = np.asarray(points_m, dtype=float).reshape(-1, 2)
        d = np.linalg.norm(p - self.centre_m, axis=1)
        mean = 0.02 + 0.96 * expit((self.radius_m - d) / 0.004)
        return MapEstimate(mean, np.full(len(p), float(self.std)))


class FlatMap(BlobMap):
    """Nothing reaches the 0.6 level."""

    def query(self, points_m) -> MapEstimate:
        p = np.asarray(points_m, dtype=float).reshape(-1, 2)
        return MapEstimate(np.full(len(p), 0.5), np.full(len(p), float(self.std)))


class GridBlobMap(BlobMap):
    """A blob map that also offers the BHM's ``probability_grid``."""

    grid_calls = 0

    def probability_grid(self, spacing_m: float):
        self.grid_calls += 1
        xs = np.arange(self.region.x_min_m + spacing_m / 2, self.region.x_max_m, spacing_m)
        ys = np.arange(self.region.y_min_m + spacing_m / 2, self.region.y_max_m, spacing_m)
        gx, gy = np.meshgrid(xs, ys)
        est = self.query(np.column_stack([gx.ravel(), gy.ravel()]))
        return xs, ys, est.mean.reshape(gy.shape), est.std.reshape(gy.shape)


def two_phase(map_: Map | None = None, seed: int = 0, scene: Scene | None = None,
              **config: object) -> TwoPhaseCoverage:
    inputs = {"bhm": map_} if map_ is not None else {}
    if map_ is None and scene is None and "region" not in config:
        config["region"] = RegionConfig()
    return TwoPhaseCoverage(
        TwoPhaseCoverageConfig(**config),
        BuildContext("plan", np.random.default_rng(seed), inputs, scene),
    )


def finish(index: int, movement: ExploratoryMovement, stop: np.ndarray | None) -> MovementResult:
    hit = stop is not None
    where = stop if hit else movement.end_m
    state = RobotState(float(index), where, movement.heading_rad)
    return MovementResult(index, movement, hit, "interaction" if hit else "", state,
                          "jamming" if hit else "free")


def circle_hit(centre, radius, reach=0.02) -> Callable[[ExploratoryMovement], np.ndarray | None]:
    """Stop where the fingertip first comes within ``reach`` of a circle's outline."""
    c = np.asarray(centre, dtype=float)

    def hit(m: ExploratoryMovement) -> np.ndarray | None:
        n = max(2, int(np.ceil(m.length_m / 0.005)) + 1)
        path = m.start_m + np.linspace(0, 1, n)[:, None] * (m.end_m - m.start_m)
        close = np.flatnonzero(np.linalg.norm(path - c, axis=1) <= radius + reach)
        return path[close[0]] if close.size else None

    return hit


def run(planner, hit, limit: int = 100) -> list[MovementResult]:
    results = []
    for i in range(limit):
        movement = planner.propose()
        if movement is None:
            return results
        r = finish(i, movement, hit(movement) if callable(hit) else hit.get(i))
        planner.on_movement_end(r)
        results.append(r)
    raise AssertionError("the planner kept proposing")


def never(_: ExploratoryMovement) -> None:
    return None


# --- phase 1 ------------------------------------------------------------------------------------


def test_phase1_visits_lines_in_binary_search_order() -> None:
    planner = two_phase(BlobMap(), **THESIS)
    assert planner.phase == "phase1"
    results = run(planner, never)
    starts, _ = planner.phase1_lines
    assert len(results) == len(starts) == 15
    visited = [int(np.argmin(np.linalg.norm(starts - r.movement.start_m, axis=1))) for r in results]
    assert visited == binary_search_order(15)
    assert all(r.movement.phase == "phase1" for r in results)
    assert planner.phase == "done" and planner.propose() is None
    assert planner.phase_metrics() == {"ems_phase1": 15, "ems_phase2": 0}


def test_reverse_pass_after_first_interaction() -> None:
    planner = two_phase(BlobMap(), **THESIS)
    stop = np.array([0.31, 0.2])
    results = run(planner, {2: stop, 3: np.array([0.36, 0.2])}, limit=40)
    third, fourth, fifth = (r.movement for r in results[2:5])
    np.testing.assert_allclose(fourth.start_m, third.end_m)
    np.testing.assert_allclose(fourth.end_m, third.start_m)
    assert third.phase == fourth.phase == "phase1"
    assert fifth.phase == "phase2"
    assert [r.movement.phase for r in results[:4]] == ["phase1"] * 4
    np.testing.assert_allclose(planner.interaction_points[0], stop)


# --- phase 2 ------------------------------------------------------------------------------------


def phase2_run(map_: Map, **config: object) -> tuple[TwoPhaseCoverage, list[MovementResult]]:
    planner = two_phase(map_, **{**THESIS, **config})
    hit = circle_hit(getattr(map_, "centre_m", (0.3, 0.2)), 0.04)
    return planner, run(planner, hit)


def test_phase2_sweep_angles_are_30_degrees_apart() -> None:
    planner, results = phase2_run(BlobMap(std=0.3))
    angles = planner.used_angles_deg
    assert len(angles) == 1 + planner.phase_metrics()["ems_phase2"] == 13
    for i, a in enumerate(angles):
        window = angles[max(0, i - 4) : i]  # five directions always fit 30 degrees apart
        assert all(angle_gap_deg(a, b) >= 30 - 1e-9 for b in window)
    phase2 = [r for r in results if r.movement.phase == "phase2"]
    for r, a in zip(phase2, angles[1:], strict=True):
        assert angle_gap_deg(np.degrees(r.movement.heading_rad), a) == pytest.approx(0, abs=1e-6)


def test_phase2_stops_at_the_cap_when_never_certain() -> None:
    planner, results = phase2_run(BlobMap(std=0.3), max_phase2_movements=5)
    assert planner.phase_metrics()["ems_phase2"] == 5
    assert planner.phase == "done"
    assert sum(r.movement.phase == "phase2" for r in results) == 5


def test_phase2_movements_lie_in_the_shrinking_region() -> None:
    planner, results = phase2_run(BlobMap(std=0.3), max_phase2_movements=8)
    phase2 = [r.movement for r in results if r.movement.phase == "phase2"]
    regions = planner._regions
    assert len(regions) == len(phase2) == 8
    sizes = np.array([(b[1] - b[0], b[3] - b[2]) for b in regions])
    # Each side shrinks by 25 % per phase-2 movement, down to min_region_size_m = 0.1 m.
    expected = np.maximum(np.array([0.75, 0.5]) * 0.75 ** np.arange(1, 9)[:, None], 0.1)
    np.testing.assert_allclose(sizes, expected)
    for m, b in zip(phase2, regions, strict=True):
        for p in (m.start_m, m.end_m):
            assert b[0] - 1e-12 <= p[0] <= b[1] + 1e-12 and b[2] - 1e-12 <= p[1] <= b[3] + 1e-12
    # The centroid estimate is the blob's centre.
    np.testing.assert_allclose(planner.centroid_m, [0.3, 0.2], atol=0.005)


def test_phase2_picks_the_line_through_the_blob() -> None:
    centre = np.array([0.45, 0.3])
    _, results = phase2_run(BlobMap(centre_m=centre, std=0.2), max_phase2_movements=6)
    for r in results:
        if r.movement.phase != "phase2":
            continue
        a, b = r.movement.start_m, r.movement.end_m
        t = np.clip(np.dot(centre - a, b - a) / np.dot(b - a, b - a), 0, 1)
        assert np.linalg.norm(a + t * (b - a) - centre) <= 0.012  # half a candidate spacing
        # It starts in granular material, not inside the object.
        assert np.linalg.norm(a - centre) > 0.04


def test_stops_when_uncertainty_is_low() -> None:
    map_ = BlobMap(std=0.3)
    planner = two_phase(map_, **THESIS)
    hit = circle_hit(map_.centre_m, 0.04)
    results = []
    for i in range(50):
        if planner.phase_metrics()["ems_phase2"] == 2:
            map_.std = 0.01  # the map became confident
        movement = planner.propose()
        if movement is None:
            break
        results.append(finish(i, movement, hit(movement)))
        planner.on_movement_end(results[-1])
    assert planner.phase == "done"
    assert planner.phase_metrics()["ems_phase2"] == 2
    assert planner.last_uncertainty == 0.0


@pytest.mark.parametrize("rule", ["uncertain-area", "mean-std"])
def test_confident_map_stops_after_min_phase2_movements(rule: str) -> None:
    planner, _ = phase2_run(BlobMap(std=0.01), stop_rule=rule, min_phase2_movements=1)
    assert planner.phase_metrics()["ems_phase2"] == 1
    planner, _ = phase2_run(BlobMap(std=0.01), stop_rule=rule, min_phase2_movements=3)
    assert planner.phase_metrics()["ems_phase2"] == 3
    # Just above the threshold it carries on to the cap.
    std = 0.16 if rule == "uncertain-area" else 0.06
    planner, _ = phase2_run(BlobMap(std=std), stop_rule=rule, max_phase2_movements=4)
    assert planner.phase_metrics()["ems_phase2"] == 4


class LowMap(BlobMap):
    """Nothing reaches even the lowest fallback level (0.3)."""

    def query(self, points_m) -> MapEstimate:
        p = np.asarray(points_m, dtype=float).reshape(-1, 2)
        return MapEstimate(np.full(len(p), 0.2), np.full(len(p), float(self.std)))


def test_centroid_falls_back_to_interaction_points() -> None:
    planner = two_phase(LowMap(), max_phase2_movements=1, **THESIS)
    run(planner, {5: np.array([0.2, 0.3]), 6: np.array([0.3, 0.31])})
    np.testing.assert_allclose(planner.centroid_m, [0.25, 0.305])


def test_centroid_falls_back_to_a_weaker_blob_before_the_interaction_points() -> None:
    class WeakBlob(BlobMap):  # peaks at 0.45: below the outline level, above 0.4
        def query(self, points_m) -> MapEstimate:
            estimate = super().query(points_m)
            return MapEstimate(0.45 * estimate.mean, estimate.std)

    planner = two_phase(WeakBlob(centre_m=(0.5, 0.2)), max_phase2_movements=1, **THESIS)
    run(planner, {5: np.array([0.42, 0.2]), 6: np.array([0.47, 0.2])})
    np.testing.assert_allclose(planner.centroid_m, [0.5, 0.2], atol=0.005)


def test_uses_probability_grid_when_the_map_has_one() -> None:
    map_ = GridBlobMap(centre_m=(0.5, 0.15))
    planner, _ = phase2_run(map_, max_phase2_movements=3)
    assert map_.grid_calls == 3
    np.testing.assert_allclose(planner.centroid_m, [0.5, 0.15], atol=0.005)


def test_without_a_map_phase2_runs_to_the_cap() -> None:
    planner = two_phase(None, max_phase2_movements=3, **THESIS)
    results = run(planner, circle_hit((0.3, 0.2), 0.04))
    assert planner.phase_metrics()["ems_phase2"] == 3
    assert results[-1].movement.phase == "phase2"


def test_deterministic_given_the_seed() -> None:
    def movements(seed: int) -> list[tuple[float, ...]]:
        _, results = phase2_run(BlobMap(), seed=seed, max_phase2_movements=5)
        return [(*r.movement.start_m, *r.movement.end_m) for r in results]

    assert movements(4) == movements(4)
    assert movements(4) != movements(5)


def test_total_cap_on_movements() -> None:
    planner = two_phase(BlobMap(), max_movements=4, **THESIS)
    assert len(run(planner, never)) == 4
    assert planner.max_movements == 4


def test_region_sources() -> None:
    small = BlobMap(bounds=(0.1, 0.3, 0.0, 0.2))
    assert two_phase(small).search_bounds == (0.1, 0.3, 0.0, 0.2)
    scene = Scene(region=RegionConfig(x_max_m=0.4, y_max_m=0.9))
    assert two_phase(None, scene=scene).search_bounds == (0.0, 0.4, 0.0, 0.9)
    assert two_phase(None, scene=scene).phase1_angle_deg == 90.0
    with pytest.raises(ValueError, match="search region"):
        BoustrophedonCoverage(CoverageConfig(), BuildContext("c", np.random.default_rng(0)))
    with pytest.raises(ValueError, match="map_id"):
        two_phase(BlobMap(), map_id="grid")


def test_simulated_searches_find_the_object() -> None:
    rng = np.random.default_rng(11)
    phase1 = []
    for trial in range(10):
        centre = rng.uniform([0.06, 0.06], [0.69, 0.44])
        map_ = BlobMap(centre_m=centre, std=0.3)
        planner = two_phase(map_, seed=trial, max_phase2_movements=4, **THESIS)
        results = run(planner, circle_hit(centre, 0.04))
        metrics = planner.phase_metrics()
        assert metrics["ems_phase2"] == 4
        assert len(planner.interaction_points) >= 2
        phase1.append(metrics["ems_phase1"])
        # Most phase-2 lines, aimed through the estimate, reach the object.
        assert sum(r.halted for r in results if r.movement.phase == "phase2") >= 3
    assert np.mean(phase1) <= 7  # binary search finds it fast (15 lines in all)


def test_finalize_writes_paths_and_metrics(tmp_path: Path) -> None:
    scene = Scene(objects=[Circle(center_m=(0.3, 0.2), radius_m=0.04)])
    planner, results = phase2_run(BlobMap(), max_phase2_movements=3)
    outcome = RunOutcome(tmp_path, scene, tuple(results), {"plan": planner}, 1.0)
    metrics = planner.finalize(outcome)
    assert metrics == {"ems_phase1": len(results) - 3, "ems_phase2": 3}
    png = tmp_path / "paths.png"
    assert png.stat().st_size > 1000 and png.read_bytes()[:4] == b"\x89PNG"


# --- baseline -----------------------------------------------------------------------------------


def test_baseline_rakes_every_line_in_boustrophedon_order(tmp_path: Path) -> None:
    planner = BoustrophedonCoverage(
        CoverageConfig(), BuildContext("c", np.random.default_rng(0), {"m": BlobMap()})
    )
    assert planner.phase == "coverage"
    results = run(planner, circle_hit((0.3, 0.2), 0.04))  # interactions do not stop it
    starts, ends = planner.lines
    assert len(results) == len(starts) == 15
    for i, r in enumerate(results):
        a, b = (starts[i], ends[i]) if i % 2 == 0 else (ends[i], starts[i])
        np.testing.assert_allclose(r.movement.start_m, a)
        np.testing.assert_allclose(r.movement.end_m, b)
        assert r.movement.phase == "coverage"
    assert any(r.halted for r in results)
    assert planner.phase == "done" and planner.propose() is None
    outcome = RunOutcome(tmp_path, None, tuple(results), {}, 1.0)
    assert planner.finalize(outcome) == {"ems_phase1": 15, "ems_phase2": 0}
    assert (tmp_path / "paths.png").exists()


def test_baseline_cap_and_angle() -> None:
    planner = BoustrophedonCoverage(
        CoverageConfig(region=RegionConfig(), max_movements=3, sweep_angle_deg=90.0),
        BuildContext("c", np.random.default_rng(0)),
    )
    results = run(planner, never)
    assert len(results) == 3
    assert all(abs(np.cos(r.movement.heading_rad)) < 1e-9 for r in results)


def test_registration() -> None:
    specs = {s.name: s for s in coverage_plugin.hapticframe_planners()}
    assert set(specs) == {"two-phase-coverage", "coverage"}
    assert specs["two-phase-coverage"].load_factory() is TwoPhaseCoverage
    assert specs["coverage"].load_factory() is BoustrophedonCoverage
    for spec in specs.values():
        schema = spec.config.model_json_schema()
        assert all("description" in p for p in schema["properties"].values())
    with pytest.raises(ValueError):
        TwoPhaseCoverageConfig(min_phase2_movements=5, max_phase2_movements=2)


# --- the calibrated defaults ----------------------------------------------------------------------


def test_default_phase1_rakes_10_cm_lines_outer_ones_last() -> None:
    planner = two_phase(BlobMap())
    results = run(planner, never)
    starts, _ = planner.phase1_lines
    np.testing.assert_allclose(starts[:, 1], [0.05, 0.15, 0.25, 0.35, 0.45])
    visited = [int(np.argmin(np.linalg.norm(starts - r.movement.start_m, axis=1))) for r in results]
    assert visited == outer_last_order(5) == [2, 3, 1, 0, 4]


def met_from_spread(planner: TwoPhaseCoverage) -> float:
    return largest_angular_gap_deg(planner._met_from())


@pytest.mark.parametrize("centre", [(0.3, 0.2), (0.55, 0.32), (0.2, 0.3)])
def test_default_phase2_meets_the_object_from_every_side(centre) -> None:
    map_ = BlobMap(centre_m=centre)
    planner = two_phase(map_)
    results = run(planner, circle_hit(centre, 0.04))
    phase2 = [r for r in results if r.movement.phase == "phase2"]
    assert planner.phase == "done"
    assert 1 <= len(phase2) <= 4
    # Stopped because no approach direction is left more than 55 degrees from a met side.
    assert met_from_spread(planner) <= planner.config.max_gap_deg + 1e-9
    assert planner.last_uncertainty * 360 <= planner.config.max_gap_deg + 1e-9
    for r in phase2:
        a, b = r.movement.start_m, r.movement.end_m
        t = np.clip(np.dot(np.subtract(centre, a), b - a) / np.dot(b - a, b - a), 0, 1)
        assert np.linalg.norm(a + t * (b - a) - centre) <= 0.012  # aimed at the estimate
        assert np.linalg.norm(a - centre) >= planner.config.min_start_distance_m - 1e-9
        assert r.halted  # every aimed line reaches the object
    # The first phase-2 region is the configured square around the estimate.
    first = planner._regions[0]
    assert first[1] - first[0] == pytest.approx(0.32)
    assert first[3] - first[2] == pytest.approx(0.32)


def test_widest_gap_approaches_from_the_side_not_met_yet() -> None:
    centre = np.array([0.4, 0.25])
    planner = two_phase(BlobMap(centre_m=centre))
    hits = circle_hit(centre, 0.04)
    results = []
    while not any(r.movement.phase == "phase2" for r in results):
        movement = planner.propose()
        results.append(finish(len(results), movement, hits(movement)))
        planner.on_movement_end(results[-1])
    # Phase 1 met the object from the left and the right (lines along x) ...
    phase1 = [r for r in results if r.movement.phase == "phase1" and r.halted]
    assert len(phase1) == 2
    first_phase2 = next(r for r in results if r.movement.phase == "phase2")
    # ... so the first aimed line comes from above or below.
    heading = np.degrees(first_phase2.movement.heading_rad) % 180
    assert abs(heading - 90) <= 30


def test_edges_of_the_region_do_not_count_as_open_sides() -> None:
    centre = (0.4, 0.045)  # 4.5 cm from the bottom edge: nothing can come from below
    planner = two_phase(BlobMap(centre_m=centre))
    results = run(planner, circle_hit(centre, 0.04))
    assert planner.phase == "done"
    assert planner.phase_metrics()["ems_phase2"] <= 4
    for r in results:
        if r.movement.phase == "phase2":
            assert r.movement.start_m[1] >= centre[1] - 1e-9  # never started below it


def test_heading_and_stop_point_met_from_agree_for_aimed_lines() -> None:
    centre = (0.35, 0.2)
    planners = [two_phase(BlobMap(centre_m=centre), met_from=rule)
                for rule in ("heading", "stop-point")]
    for planner in planners:
        run(planner, circle_hit(centre, 0.04))
    for planner in planners:
        assert planner.phase == "done"
    # Aimed phase-2 lines stop on the line through the centre: both readings agree there.
    stop_point = planners[1]
    headings = stop_point.met_from_deg
    bearings = stop_point._met_from()
    for h, b, point in zip(headings, bearings, stop_point.interaction_points, strict=True):
        if abs(point[1] - 0.25) > 1e-9 and abs(point[1] - 0.15) > 1e-9:  # not a phase-1 line
            assert min(abs(h - b), 360 - abs(h - b)) <= 15
