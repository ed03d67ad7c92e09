"""The ``occupancy-grid`` map (hapticframe_grid) and its registration."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError
from scipy.special import expit, logit

from hapticframe import Circle, MapSpec, RegionConfig, Scene
from hapticframe.kinds import (
    BuildContext,
    ExploratoryMovement,
    Map,
    MovementResult,
    Observations,
    Region,
    RunOutcome,
)
from hapticframe_grid import OccupancyGrid, OccupancyGridConfig
from hapticframe_grid import _functional as fn
from hapticframe_grid import plugin as grid_plugin


def build(scene: Scene | None = None, **config) -> OccupancyGrid:
    context = BuildContext(id="grid", rng=np.random.default_rng(0), scene=scene)
    return OccupancyGrid(OccupancyGridConfig(**config), context)


def random_observations(rng: np.random.Generator, count: int, box=(0.0, 0.05)) -> Observations:
    """Points crowded into a few cells (so clamping is reached), soft targets and weights."""
    points = rng.uniform(box[0], box[1], size=(count, 2))
    targets = rng.choice([0.0, 1.0, 0.3, 0.8], size=count)
    weights = rng.uniform(0.0, 3.0, size=count)
    return Observations(points, targets, weights)


def reference_fuse(grid: OccupancyGrid, observations: Observations) -> np.ndarray:
    """One observation at a time with plain Python arithmetic: OctoMap's updateNodeLogOdds."""
    cfg = grid.config
    log_odds = grid.log_odds.copy()
    low, high = logit(cfg.clamping_min), logit(cfg.clamping_max)
    rows = zip(observations.points_m, observations.targets, observations.weights, strict=True)
    for (x, y), target, weight in rows:
        if not (0 <= x <= 0.75 and 0 <= y <= 0.5):
            continue
        i = min(int(np.floor(x / cfg.cell_size_m)), log_odds.shape[0] - 1)
        j = min(int(np.floor(y / cfg.cell_size_m)), log_odds.shape[1] - 1)
        hit, miss = logit(cfg.probability_hit), logit(cfg.probability_miss)
        step = weight * ((2 * target - 1) * hit if target >= 0.5 else (1 - 2 * target) * miss)
        log_odds[i, j] = min(max(log_odds[i, j] + step, low), high)
    return log_odds


def test_octomap_constants_are_the_defaults() -> None:
    cfg = OccupancyGridConfig()
    assert (cfg.probability_hit, cfg.probability_miss) == (0.7, 0.4)
    assert (cfg.clamping_min, cfg.clamping_max) == (0.1192, 0.971)
    assert cfg.cell_size_m == 0.01
    # The log-odds values OctoMap documents.
    assert logit(cfg.probability_hit) == pytest.approx(0.8473, abs=1e-4)
    assert logit(cfg.probability_miss) == pytest.approx(-0.4055, abs=1e-4)
    assert logit(cfg.clamping_min) == pytest.approx(-2.0, abs=1e-3)
    assert logit(cfg.clamping_max) == pytest.approx(3.5, abs=0.02)
    grid = build()
    assert grid.shape == (75, 50)
    grid.update(Observations([[0.105, 0.205]], [1.0]))
    assert grid.query([[0.105, 0.205]]).mean[0] == pytest.approx(0.7, abs=1e-12)
    grid.reset()
    grid.update(Observations([[0.105, 0.205]], [0.0]))
    assert grid.query([[0.105, 0.205]]).mean[0] == pytest.approx(0.4, abs=1e-12)


def test_config_validation() -> None:
    for bad in (
        {"cell_size_m": 0.0},
        {"cell_size_m": float("inf")},
        {"probability_hit": 0.4},
        {"probability_miss": 0.6},
        {"clamping_min": 0.6},
        {"clamping_max": 1.0},
        {"extra": 1},
    ):
        with pytest.raises(ValidationError):
            OccupancyGridConfig(**bad)
    fields = OccupancyGridConfig.model_json_schema()["properties"]
    assert all(spec.get("description") for spec in fields.values())


def test_soft_target_and_weight_scale_the_increment() -> None:
    grid = build()
    grid.update(Observations([[0.3, 0.3]], [0.25], [2.0]))
    expected = 2.0 * (0.5 * logit(0.4))  # a quarter-way to "free": half a miss, twice weighted
    assert grid.log_odds[30, 30] == pytest.approx(expected, abs=1e-14)
    grid.update(Observations([[0.3, 0.3]], [0.5], [3.0]))  # "unknown" changes nothing
    assert grid.log_odds[30, 30] == pytest.approx(expected, abs=1e-14)
    np.testing.assert_array_equal(np.delete(grid.log_odds.ravel(), 30 * 50 + 30), 0.0)


def test_update_matches_the_one_at_a_time_reference() -> None:
    rng = np.random.default_rng(1)
    grid = build()
    observations = random_observations(rng, 2000)
    expected = reference_fuse(grid, observations)
    grid.update(observations)
    np.testing.assert_array_equal(grid.log_odds, expected)
    assert grid.log_odds.max() == pytest.approx(logit(0.971))  # clamping was reached


def test_two_updates_equal_one_concatenated_update() -> None:
    rng = np.random.default_rng(2)
    first, second = random_observations(rng, 700), random_observations(rng, 900)
    split, joined = build(), build()
    split.update(first)
    split.update(second)
    joined.update(Observations.concatenate([first, second]))
    np.testing.assert_array_equal(split.log_odds, joined.log_odds)
    # Order matters under clamping, so the reverse order generally differs.
    reverse = build()
    reverse.update(second)
    reverse.update(first)
    assert not np.array_equal(reverse.log_odds, joined.log_odds)


def test_clamping_bounds_confidence_and_keeps_the_cell_revisable() -> None:
    grid = build()
    cell = [[0.401, 0.201]]
    grid.update(Observations(np.repeat(cell, 50, axis=0), np.ones(50)))
    assert grid.query(cell).mean[0] == pytest.approx(0.971, abs=1e-12)
    grid.update(Observations(np.repeat(cell, 3, axis=0), np.zeros(3)))
    assert grid.log_odds[40, 20] == pytest.approx(logit(0.971) + 3 * logit(0.4), abs=1e-12)
    grid.update(Observations(np.repeat(cell, 100, axis=0), np.zeros(100)))
    assert grid.query(cell).mean[0] == pytest.approx(0.1192, abs=1e-12)


def test_queries_nearest_cell_unknown_outside_empty_float32() -> None:
    grid = build()
    corners_and_outside = [[0.0, 0.0], [0.75, 0.5], [-0.1, 0.2], [0.3, 0.9]]
    grid.update(Observations(corners_and_outside, np.ones(4)))
    lo = grid.log_odds
    assert lo[0, 0] > 0 and lo[74, 49] > 0  # far edges belong to the last cell
    assert np.count_nonzero(lo) == 2  # points outside the region are ignored
    queries = np.array([[0.009, 0.001], [0.5, 0.25], [2.0, 2.0], [0.745, 0.499]], np.float32)
    estimate = grid.query(queries)
    np.testing.assert_allclose(estimate.mean, [0.7, 0.5, 0.5, 0.7], atol=1e-7)
    np.testing.assert_allclose(estimate.std, np.sqrt(estimate.mean * (1 - estimate.mean)))
    assert grid.query(np.empty((0, 2))).mean.shape == (0,)
    assert grid.query([]).std.shape == (0,)
    assert grid.query(np.array([0.005, 0.005])).mean.shape == (1,)
    with pytest.raises(ValueError):
        grid.query([[np.nan, 0.0]])
    with pytest.raises(ValueError):
        grid.query(np.zeros((2, 3)))
    with pytest.raises(TypeError):
        grid.update([[0.1, 0.1]])  # type: ignore[arg-type]


def test_region_from_config_scene_or_default() -> None:
    assert build().region == Region(0.0, 0.75, 0.0, 0.5)
    scene = Scene(region=RegionConfig(x_min_m=1.0, x_max_m=1.2, y_min_m=-0.1, y_max_m=0.0))
    grid = build(scene=scene, cell_size_m=0.03)
    assert grid.region == Region(1.0, 1.2, -0.1, 0.0)
    assert grid.shape == (7, 4)  # partial last cells are kept
    xs, ys = grid.cell_centers
    assert xs[0] == pytest.approx(1.015) and ys[-1] == pytest.approx(-0.1 + 3.5 * 0.03)
    own = build(scene=scene, region=RegionConfig(x_min_m=0, x_max_m=0.1, y_min_m=0, y_max_m=0.1))
    assert own.region == Region(0.0, 0.1, 0.0, 0.1)


def test_fuse_clamped_handles_a_long_run_in_one_cell() -> None:
    log_odds = np.zeros(3)
    steps = np.tile([1.0, -0.3], 500)
    fn.fuse_clamped(log_odds, np.zeros(1000, dtype=np.intp), steps, -2.0, 3.5)
    value = 0.0
    for step in steps:
        value = min(max(value + step, -2.0), 3.5)
    assert log_odds[0] == pytest.approx(value, abs=1e-12) and log_odds[1] == 0.0


def _movement(index: int, phase: str) -> MovementResult:
    move = ExploratoryMovement(np.zeros(2), np.array([0.1, 0.0]), phase=phase)
    return MovementResult(
        index=index, movement=move, halted=False, halt_reason="", final_state=None
    )


def test_phase_snapshots_and_figures(tmp_path: Path) -> None:
    scene = Scene(objects=[Circle(center_m=(0.3, 0.2), radius_m=0.04)])
    grid = build(scene=scene)
    grid.update(Observations([[0.1, 0.1]], [1.0]))
    grid.on_movement_end(_movement(0, "phase1"))
    grid.update(Observations([[0.2, 0.1]], [1.0]))
    grid.on_movement_end(_movement(1, "phase1"))
    end_of_phase1 = grid.log_odds
    grid.update(Observations([[0.3, 0.1]], [0.0]))
    grid.on_movement_end(_movement(2, "phase 2/b"))
    snapshots = grid.phase_snapshots
    assert list(snapshots) == ["phase1"]
    np.testing.assert_array_equal(snapshots["phase1"], end_of_phase1)
    outcome = RunOutcome(tmp_path, scene, (), {"grid": grid}, 0.0)
    assert dict(grid.finalize(outcome)) == {}
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["logodds_phase-2-b.png", "logodds_phase1.png"]
    for path in tmp_path.iterdir():
        assert path.read_bytes().startswith(b"\x89PNG")
    grid.reset()
    assert grid.phase_snapshots == {} and not grid.log_odds.any()


def test_without_movements_one_figure_is_written(tmp_path: Path) -> None:
    grid = build()
    grid.update(Observations([[0.1, 0.1]], [1.0]))
    grid.finalize(RunOutcome(tmp_path, None, (), {}, 0.0))
    assert [p.name for p in tmp_path.iterdir()] == ["logodds.png"]


def test_registration_is_import_light_and_resolves() -> None:
    specs = list(grid_plugin.hapticframe_maps())
    assert len(specs) == 1 and isinstance(specs[0], MapSpec)
    assert specs[0].name == "occupancy-grid"
    assert specs[0].load_factory() is OccupancyGrid
    assert issubclass(OccupancyGrid, Map)
    code = (
        "import sys, hapticframe_grid.plugin; "
        "print(sorted(m for m in ('scipy', 'matplotlib', 'hapticframe_grid._grid') "
        "if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_probabilities_stay_in_bounds_for_any_input() -> None:
    rng = np.random.default_rng(7)
    grid = build()
    for _ in range(5):
        grid.update(random_observations(rng, 500, box=(-0.1, 0.8)))
    estimate = grid.query(rng.uniform(-0.2, 0.9, size=(1000, 2)))
    assert np.all((estimate.mean >= 0.1192 - 1e-12) & (estimate.mean <= 0.971 + 1e-12))
    assert np.all(estimate.std <= 0.5)
    assert expit(grid.log_odds).max() <= 0.971 + 1e-12


def test_the_dark_squares_along_a_path_are_cells_with_more_observed_points(tmp_path: Path) -> None:
    # What the log-odds figures' note says (hapticframe_grid._plots._NOTE), measured on the
    # README's main job: along the phase-1 line every other cell holds about 2.5 times the
    # observed points of its neighbours and so ends darker (more negative log odds).
    from hapticframe.cli._cli import main

    root = Path(__file__).resolve().parents[2]
    out = tmp_path / "run"
    assert main(["run", str(root / "examples" / "search-ellipse.yaml"), "--out", str(out),
                 "--quiet", "--set", "run.figures=false"]) == 0
    with np.load(out / "trace.npz", allow_pickle=False) as trace:
        points = trace["sensor_model/failure-zone/points_m"]
        targets = trace["sensor_model/failure-zone/targets"]
        weights = trace["sensor_model/failure-zone/weights"]
        movement = trace["robot/arm/movement_index"]
        position = trace["robot/arm/position_m"]
    grid = build()
    grid.update(Observations(points, targets, weights))
    line = position[movement == 0]
    assert np.ptp(line[:, 1]) < 1e-9  # phase 1 rakes along x
    cell = grid.config.cell_size_m
    row = int(np.floor(line[0, 1] / cell))
    # The first straight stretch, away from the object and the region's edge.
    columns = np.arange(6, int(np.floor(0.30 / cell)))
    in_row = np.floor(points[:, 1] / cell).astype(int) == row
    counts = np.bincount(np.floor(points[in_row, 0] / cell).astype(int),
                         minlength=grid.shape[0])[columns]
    log_odds = grid.log_odds[columns, row]
    even, odd = counts[::2], counts[1::2]
    dense, sparse = (even, odd) if even.mean() > odd.mean() else (odd, even)
    assert 2.0 <= dense.mean() / sparse.mean() <= 3.0
    assert np.all(dense > sparse[:dense.size]) or np.all(dense[:sparse.size] > sparse)
    dark = log_odds[::2] if even.mean() > odd.mean() else log_odds[1::2]
    light = log_odds[1::2] if even.mean() > odd.mean() else log_odds[::2]
    assert dark.max() < light.min() < 0  # both free, the dense cells darker
