"""Tests of the failure-zone kernel sensor model (dissertation Eqs. 3.2-3.4, Table 3.1)."""

from __future__ import annotations

import math
import warnings
from itertools import pairwise

import numpy as np
import pytest

from hapticframe import Material, Scene
from hapticframe.kinds import (
    BuildContext,
    ExploratoryMovement,
    LocatedMeasurement,
    MovementResult,
    Observations,
)
from hapticframe_failure_zone import FailureZoneAngleWarning, FailureZoneConfig, FailureZoneKernel
from hapticframe_failure_zone import _functional as fz

CLASSES = ("free", "jamming", "contact")
#: The dissertation's sensor model exactly (Eqs. 3.2-3.4, Table 3.1); the defaults are calibrated.
THESIS = {
    "schedule": "empirical",
    "free_range_scale": 1.0,
    "free_gamma_scale": 1.0,
    "jamming_shape": "sector",
    "jamming_inner_scale": 0.0,
    "jamming_range_scale": 1.0,
    "jamming_angle_scale": 1.0,
    "interaction_weight": 1.0,
    "first_pair_weight": 1.0,
}
ONE_HOT = {"free": [1.0, 0.0, 0.0], "jamming": [0.0, 1.0, 0.0], "contact": [0.0, 0.0, 1.0]}


def make_model(scene: Scene | None = None, **config: object) -> FailureZoneKernel:
    return FailureZoneKernel(
        FailureZoneConfig(**config), BuildContext("soil", np.random.default_rng(0), scene=scene)
    )


def measurement(
    positions: np.ndarray,
    states: list[str] | None = None,
    headings: np.ndarray | float = 0.0,
    depth: np.ndarray | float | None = None,
    classes: tuple[str, ...] = CLASSES,
    probabilities: np.ndarray | None = None,
    t0: float = 0.0,
) -> LocatedMeasurement:
    positions = np.atleast_2d(np.asarray(positions, dtype=float))
    n = len(positions)
    if probabilities is None:
        states = states or ["free"] * n
        probabilities = np.array([[ONE_HOT[s][CLASSES.index(c)] for c in classes] for s in states])
    return LocatedMeasurement(
        t0 + 0.01 * np.arange(n),
        positions,
        np.broadcast_to(np.asarray(headings, dtype=float), (n,)).copy(),
        probabilities,
        classes,
        None if depth is None else np.broadcast_to(np.asarray(depth, dtype=float), (n,)).copy(),
    )


def result(index: int, halt_reason: str = "", final_class: str = "free") -> MovementResult:
    movement = ExploratoryMovement(np.zeros(2), np.array([0.1, 0.0]))
    return MovementResult(index, movement, bool(halt_reason), halt_reason, None, final_class)


# --- formulas -------------------------------------------------------------------------------


def test_empirical_gamma_at_zero_pairs() -> None:
    gamma = fz.empirical_gamma(0)
    assert gamma == pytest.approx(1 / 72 * 1e4)  # 1/72 cm^-2 in m^-2
    assert gamma == pytest.approx(math.log(2) / 0.071**2, rel=0.02)
    assert fz.empirical_gamma(2) == pytest.approx(1e4 / (72 * 0.82**2))
    assert fz.range_from_gamma(gamma) == pytest.approx(math.sqrt(math.log(2) * 72) / 100)


def test_analytic_side_angle_warns_once_per_instance() -> None:
    model = make_model(schedule="analytic")

    def observe_three_times_then_fit() -> None:
        for i in range(3):
            model.observe(measurement([[0.01 * i, 0.0]], ["free"], t0=i))
        model.parameters()

    with pytest.warns(FailureZoneAngleWarning) as caught:
        observe_three_times_then_fit()
    assert len([w for w in caught if w.category is FailureZoneAngleWarning]) == 1
    reach, gamma, eta = model.parameters()
    assert np.isfinite([reach, gamma, eta]).all()
    assert eta == pytest.approx(math.pi / 2)
    other = make_model(schedule="analytic")
    with pytest.warns(FailureZoneAngleWarning):
        other.parameters()


def test_depth_schedule() -> None:
    depths = [fz.depth_schedule(k) for k in range(5)]
    np.testing.assert_allclose(depths, [0.044, 0.034, 0.029, 0.0265, 0.02525])
    assert fz.depth_schedule(200) == pytest.approx(0.024)
    assert fz.depth_schedule(3, 0.01, 0.01, 1.0, 0.002) == 0.002


# --- kernels --------------------------------------------------------------------------------


def test_free_kernel_rises_from_zero_to_half_at_range() -> None:
    r = 0.07
    gamma = float(fz.rupture_gamma(r))
    d = np.linspace(0, r, 50)
    t = fz.kernel_targets(d, gamma, 0)
    assert t[0] == pytest.approx(0.0)
    assert t[-1] == pytest.approx(0.5)
    assert np.all(np.diff(t) > 0)


def test_jamming_kernel_rises_from_half_to_one() -> None:
    r = 0.05
    t = fz.kernel_targets([0.0, r], float(fz.rupture_gamma(r)), 1)
    np.testing.assert_allclose(t, [0.5, 1.0])


def test_targets_stay_in_unit_interval() -> None:
    d = np.concatenate([np.linspace(0, 1, 200), [1e6]])
    for state in range(3):
        for gamma in (0.0, 1.0, 138.9, 1e9):
            t = fz.kernel_targets(d, gamma, state)
            assert np.all((t >= 0) & (t <= 1))
    assert fz.kernel_targets([0.0], 100.0, 2)[0] == pytest.approx(1.0)


def test_soft_mixture_renormalises_over_covering_states() -> None:
    r = 0.05
    gamma = float(fz.rupture_gamma(r))
    d = np.array([0.0, r / 2, r])
    targets, weights = fz.mixture_targets(d, gamma, [0.3, 0.3, 0.4], [r, r, 0.0])
    free = fz.kernel_targets(d, gamma, 0)
    jam = fz.kernel_targets(d, gamma, 1)
    # At the fingertip all three states speak; beyond it only free and jamming do.
    assert targets[0] == pytest.approx(0.3 * 0 + 0.3 * 0.5 + 0.4 * 1.0)
    np.testing.assert_allclose(targets[1:], (free[1:] + jam[1:]) / 2)
    np.testing.assert_allclose(weights, [1.0, 0.6, 0.6])


# --- the sensor model ------------------------------------------------------------------------


def test_contact_gives_range_zero() -> None:
    model = make_model()
    obs = model.observe(measurement([[0.2, 0.3]], ["contact"], headings=1.0))
    assert len(obs) == 1
    np.testing.assert_allclose(obs.points_m, [[0.2, 0.3]])
    assert obs.targets[0] == 1.0


def test_free_sector_targets_and_extent() -> None:
    model = make_model(**THESIS)
    reach, _, _ = model.parameters()
    obs = model.observe(measurement([[0.1, 0.1]], ["free"]))
    dist = np.linalg.norm(obs.points_m - [0.1, 0.1], axis=1)
    assert dist.max() == pytest.approx(reach)
    assert obs.targets[np.argmin(dist)] == pytest.approx(0.0)
    assert obs.targets[dist > reach - 1e-9] == pytest.approx(0.5)
    assert np.all(obs.weights == 1.0)
    jam = model.observe(measurement([[0.1, 0.1]], ["jamming"], t0=1.0))
    assert jam.targets.min() == pytest.approx(0.5) and jam.targets.max() == pytest.approx(1.0)
    assert np.linalg.norm(jam.points_m - [0.1, 0.1], axis=1).max() == pytest.approx(reach)


@pytest.mark.parametrize("heading", [0.0, 0.7, math.pi / 2, -2.5, math.pi])
def test_sector_respects_heading_and_half_angle(heading: float) -> None:
    model = make_model()
    reach, _, eta = model.parameters()
    origin = np.array([0.3, 0.2])
    obs = model.observe(measurement(origin, ["free"], headings=heading))
    offsets = obs.points_m - origin
    dist = np.linalg.norm(offsets, axis=1)
    away = dist > 1e-12
    bearing = np.arctan2(offsets[away, 1], offsets[away, 0]) - heading
    bearing = (bearing + math.pi) % (2 * math.pi) - math.pi
    assert np.all(dist <= reach + 1e-12)
    assert np.all(np.abs(bearing) <= eta + 1e-9)
    assert bearing.max() == pytest.approx(eta) and bearing.min() == pytest.approx(-eta)
    # Everything lies ahead: the projection on the direction of motion is never negative
    # beyond the sector's half-angle allowance (η < 90° here).
    ahead = offsets @ np.array([math.cos(heading), math.sin(heading)])
    assert np.all(ahead >= -1e-12)


def test_sector_spacing_controls_density() -> None:
    coarse = fz.sector_offsets(0.07, math.radians(50), 0.02)
    fine = fz.sector_offsets(0.07, math.radians(50), 0.005)
    assert len(fine) > 8 * len(coarse)
    assert len(fz.sector_offsets(0.0, 1.0, 0.01)) == 1
    ray = fz.sector_offsets(0.05, 0.0, 0.01)
    np.testing.assert_allclose(ray[:, 1], 0.0)
    disc = fz.sector_offsets(0.05, math.pi, 0.01)
    assert len(np.unique(np.round(disc, 12), axis=0)) == len(disc)


def random_path(rng: np.random.Generator, n: int) -> LocatedMeasurement:
    steps = rng.uniform(0.0, 0.008, n)
    positions = np.column_stack([np.cumsum(steps), 0.01 * np.sin(np.arange(n))])
    states = ["free"] * n
    for i in rng.choice(n, size=n // 6, replace=False):
        states[i] = str(rng.choice(["jamming", "contact"]))
    return measurement(positions, states, headings=rng.uniform(-0.3, 0.3, n),
                       depth=rng.uniform(0.02, 0.05, n))


@pytest.mark.parametrize("schedule", ["hybrid", "empirical", "analytic"])
@pytest.mark.parametrize("mixture", ["one-hot", "soft"])
def test_streaming_equals_batch(schedule: str, mixture: str) -> None:
    rng = np.random.default_rng(3)
    m = random_path(rng, 60)
    if mixture == "soft":
        p = rng.dirichlet([2, 1, 1], size=len(m))
        m = LocatedMeasurement(m.timestamps_s, m.positions_m, m.headings_rad, p, CLASSES, m.depth_m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FailureZoneAngleWarning)
        batch = make_model(schedule=schedule, mixture=mixture).observe(m)
        model = make_model(schedule=schedule, mixture=mixture)
        one_by_one = Observations.concatenate([model.observe(m.select(slice(i, i + 1)))
                                               for i in range(len(m))])
        model = make_model(schedule=schedule, mixture=mixture)
        cuts = [0, 7, 8, 30, 31, 60]
        chunks = Observations.concatenate(
            [model.observe(m.select(slice(a, b))) for a, b in pairwise(cuts)]
        )
    assert len(batch) > 0
    for other in (one_by_one, chunks):
        np.testing.assert_array_equal(other.points_m, batch.points_m)
        np.testing.assert_array_equal(other.targets, batch.targets)
        np.testing.assert_array_equal(other.weights, batch.weights)


def test_reset_clears_streaming_state() -> None:
    rng = np.random.default_rng(5)
    m = random_path(rng, 40)
    model = make_model()
    first = model.observe(m)
    model.on_movement_end(result(0, "interaction", "jamming"))
    model.on_movement_end(result(1, "interaction", "jamming"))
    assert model.pair_count == 1
    model.reset()
    assert model.pair_count == 0
    again = model.observe(m)
    np.testing.assert_array_equal(again.points_m, first.points_m)
    np.testing.assert_array_equal(again.targets, first.targets)


def fingertip_rows(obs: Observations, positions: np.ndarray) -> int:
    """How many sectors were emitted: each starts with its fingertip point."""
    return sum(bool(np.any(np.all(obs.points_m == p, axis=1))) for p in positions)


def test_observation_spacing_thins_free_movement() -> None:
    positions = np.column_stack([0.004 * np.arange(50), np.zeros(50)])  # 0.196 m of travel
    model = make_model(observation_spacing_m=0.01)
    obs = model.observe(measurement(positions))
    assert fingertip_rows(obs, positions) == 1 + 19
    every = make_model(observation_spacing_m=0.0).observe(measurement(positions))
    assert fingertip_rows(every, positions) == 50


def test_first_non_free_sample_is_always_emitted() -> None:
    positions = np.column_stack([0.001 * np.arange(6), np.zeros(6)])  # 5 mm of travel
    states = ["free", "free", "free", "jamming", "jamming", "jamming"]
    model = make_model(observation_spacing_m=0.01, **THESIS)  # sectors start at the fingertip
    obs = model.observe(measurement(positions, states))
    emitted = [bool(np.any(np.all(obs.points_m == p, axis=1))) for p in positions]
    assert emitted == [True, False, False, True, False, False]
    # A new movement starts a new count: its first sample is emitted however close.
    model.on_movement_end(result(0, "interaction", "jamming"))
    nxt = model.observe(measurement(positions[:1] + 1e-6, t0=5.0))
    assert len(nxt) > 0


def test_two_class_classifier() -> None:
    model = make_model()
    m = measurement([[0.0, 0.0], [0.05, 0.0]], classes=("free", "contact"),
                    probabilities=np.array([[1.0, 0.0], [0.0, 1.0]]))
    obs = model.observe(m)
    contact_points = obs.points_m[obs.targets == 1.0]
    np.testing.assert_allclose(contact_points, [[0.05, 0.0]])
    with pytest.raises(ValueError, match="no kernel state"):
        model.observe(measurement([[0, 0]], classes=("free", "touch"),
                                  probabilities=np.array([[0.0, 1.0]])))
    renamed = make_model(class_states={"none": "free", "touch": "contact"})
    obs = renamed.observe(measurement([[0, 0]], classes=("none", "touch"),
                                      probabilities=np.array([[0.0, 1.0]])))
    assert len(obs) == 1 and obs.targets[0] == 1.0


# --- interaction count and schedules -----------------------------------------------------------


def test_empirical_schedule_counts_pairs() -> None:
    model = make_model(**THESIS)
    assert model.parameters()[1] == pytest.approx(1e4 / 72)
    model.on_movement_end(result(0, "interaction", "jamming"))
    assert model.pair_count == 0
    model.on_movement_end(result(1, "force_limit", "free"))  # not an interaction
    assert model.interacting_movements == 1
    model.on_movement_end(result(2, "force_limit", "jamming"))  # halted by force, but jamming
    assert model.pair_count == 1
    _, gamma, eta = model.parameters()
    assert gamma == pytest.approx(1e4 / (72 * 0.82))
    assert math.degrees(eta) == pytest.approx(57.0)


def test_analytic_schedule_shrinks_depth_after_each_interaction() -> None:
    model = make_model(schedule="analytic")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FailureZoneAngleWarning)
        ranges = []
        for i in range(4):
            ranges.append(model.parameters()[0])
            model.on_movement_end(result(i, "interaction", "jamming"))
        # The measured depth wins over the schedule when it is finite.
        measured = model.parameters(depth_m=0.044)[0]
    np.testing.assert_allclose(np.array(ranges) * 100, [7.18, 5.55, 4.73, 4.32], atol=0.01)
    assert measured == pytest.approx(0.0718, abs=1e-4)


def test_shear_band_angle_sources() -> None:
    scene = Scene(material=Material(friction_angle_deg=30.0, dilation_angle_deg=2.0))
    from_scene = make_model(scene=scene, schedule="analytic")
    from_config = make_model(scene=scene, schedule="analytic", shear_band_angle_deg=31.5)
    assert math.degrees(from_scene.shear_band_angle_rad) == pytest.approx(37.0)
    assert math.degrees(from_config.shear_band_angle_rad) == pytest.approx(31.5)
    assert math.degrees(make_model().shear_band_angle_rad) == pytest.approx(31.5)


# --- calibrated defaults -------------------------------------------------------------------------


def test_hybrid_schedule_takes_the_range_from_depth_and_the_angle_from_table_3_1() -> None:
    model = make_model()
    reach, gamma, eta = model.parameters(depth_m=0.034)
    assert reach == pytest.approx(0.034 / math.tan(math.radians(31.5)))
    assert gamma == pytest.approx(math.log(2) / reach**2)
    assert math.degrees(eta) == pytest.approx(50.0)
    model.on_movement_end(result(0, "interaction", "jamming"))
    model.on_movement_end(result(1, "interaction", "jamming"))
    assert math.degrees(model.parameters(depth_m=0.034)[2]) == pytest.approx(57.0)
    # Unknown depth: the depth schedule, 4.4 cm less 1 and 0.5 cm after two interactions.
    assert model.parameters()[0] == pytest.approx(0.029 / math.tan(math.radians(31.5)))


def test_default_free_sector_is_short_and_nearly_free() -> None:
    model = make_model()
    reach = model.parameters(depth_m=0.044)[0]
    obs = model.observe(measurement([[0.2, 0.2]], ["free"], depth=0.044))
    dist = np.linalg.norm(obs.points_m - [0.2, 0.2], axis=1)
    assert dist.max() == pytest.approx(0.85 * reach)
    # The free kernel with 0.04 γ_r: 1 − 2^(−0.04 · 0.85²) ≈ 0.02 at the sector's end.
    assert obs.targets.max() == pytest.approx(1 - 2 ** (-0.04 * 0.85**2))
    assert np.all(obs.weights == 1.0)


@pytest.mark.parametrize("heading", [0.0, 2.0, -math.pi / 2])
def test_jamming_disc_lies_ahead_of_the_fingertip(heading: float) -> None:
    model = make_model()
    reach, gamma, _ = model.parameters(depth_m=0.044)
    origin = np.array([0.3, 0.25])
    obs = model.observe(measurement(origin, ["jamming"], headings=heading, depth=0.044))
    radius = model.config.jamming_disc_radius_m
    ahead = np.array([math.cos(heading), math.sin(heading)])
    centre = origin + (0.45 * reach + radius) * ahead
    offsets = np.linalg.norm(obs.points_m - centre, axis=1)
    assert offsets.max() == pytest.approx(radius) and offsets.min() == pytest.approx(0.0)
    dist = np.linalg.norm(obs.points_m - origin, axis=1)
    assert dist.min() == pytest.approx(0.45 * reach)
    np.testing.assert_allclose(obs.targets, fz.kernel_targets(dist, gamma, 1))
    assert np.all(obs.targets >= 0.5)


def test_first_pair_of_interactions_counts_half() -> None:
    model = make_model()
    jam = model.observe(measurement([[0.3, 0.2]], ["jamming"], depth=0.03))
    np.testing.assert_allclose(jam.weights, 0.5)
    free = model.observe(measurement([[0.35, 0.2]], ["free"], depth=0.03, t0=1.0))
    np.testing.assert_allclose(free.weights, 1.0)
    model.on_movement_end(result(0, "interaction", "jamming"))
    model.on_movement_end(result(1, "interaction", "jamming"))
    again = model.observe(measurement([[0.3, 0.2]], ["jamming"], depth=0.03, t0=2.0))
    np.testing.assert_allclose(again.weights, 1.0)
    contact = model.observe(measurement([[0.3, 0.2]], ["contact"], depth=0.03, t0=3.0))
    assert len(contact) == 1 and contact.targets[0] == 1.0


def test_soft_mixture_with_the_disc_weights_each_region_by_its_probability() -> None:
    model = make_model(mixture="soft", first_pair_weight=1.0)
    theta = np.array([[0.25, 0.75, 0.0]])
    obs = model.observe(measurement([[0.3, 0.2]], probabilities=theta, depth=0.044))
    free = make_model().observe(measurement([[0.3, 0.2]], ["free"], depth=0.044))
    jam = make_model(first_pair_weight=1.0).observe(
        measurement([[0.3, 0.2]], ["jamming"], depth=0.044))
    assert len(obs) == len(free) + len(jam)
    np.testing.assert_allclose(np.sort(obs.weights), np.sort(np.r_[0.25 * free.weights,
                                                                     0.75 * jam.weights]))


def test_disc_offsets() -> None:
    disc = fz.disc_offsets(0.1, 0.03, 0.01)
    np.testing.assert_allclose(disc[0], [0.1, 0.0])
    assert np.linalg.norm(disc - [0.1, 0.0], axis=1).max() == pytest.approx(0.03)
    assert len(np.unique(np.round(disc, 12), axis=0)) == len(disc)
    assert len(fz.disc_offsets(0.1, 0.0, 0.01)) == 1
    with pytest.raises(ValueError):
        fz.disc_offsets(0.1, -0.01, 0.01)
    with pytest.raises(ValueError):
        fz.disc_offsets(0.1, 0.03, 0.0)


def test_calibration_fields_are_validated() -> None:
    with pytest.raises(ValueError):
        FailureZoneConfig(jamming_inner_scale=1.2, jamming_range_scale=1.0)
    with pytest.raises(ValueError):
        FailureZoneConfig(first_pair_weight=0.0)
    with pytest.raises(ValueError):
        FailureZoneConfig(jamming_shape="ring")


# --- extremes -----------------------------------------------------------------------------------


def test_empty_measurement() -> None:
    model = make_model()
    empty = LocatedMeasurement(
        np.empty(0), np.empty((0, 2)), np.empty(0), np.empty((0, 3)), CLASSES
    )
    obs = model.observe(empty)
    assert len(obs) == 0 and obs.points_m.shape == (0, 2)


@pytest.mark.parametrize(
    ("depth", "expected_range"),
    [
        (np.nan, 0.0718),  # unknown: the depth schedule (4.4 cm)
        (np.inf, 0.0718),
        (1e6, 0.25),  # huge: capped at max_range_m
        (1e-12, 0.002),  # tiny: floored at min_range_m
        (-0.01, 0.002),  # above the surface: depth 0, floored
        (0.0, 0.002),
    ],
)
def test_extreme_depths_give_finite_observations(depth: float, expected_range: float) -> None:
    model = make_model(**{**THESIS, "schedule": "analytic"})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FailureZoneAngleWarning)
        obs = model.observe(measurement([[0.1, 0.1]], ["jamming"], depth=depth))
    dist = np.linalg.norm(obs.points_m - [0.1, 0.1], axis=1)
    assert dist.max() == pytest.approx(expected_range, abs=1e-4)
    assert np.all(np.isfinite(obs.points_m)) and np.all(np.isfinite(obs.targets))
    assert np.all((obs.targets >= 0.5) & (obs.targets <= 1.0))


def test_non_finite_position_is_an_error() -> None:
    model = make_model()
    with pytest.raises(ValueError, match="finite"):
        model.observe(measurement([[np.nan, 0.0]]))
    with pytest.raises(ValueError, match="finite"):
        model.observe(measurement([[0.0, 0.0]], headings=np.inf))


def test_config_rejects_unknown_keys_and_bad_ranges() -> None:
    with pytest.raises(ValueError):
        FailureZoneConfig(radius=3)
    with pytest.raises(ValueError):
        FailureZoneConfig(min_range_m=0.5, max_range_m=0.1)
    with pytest.raises(ValueError):
        FailureZoneConfig(class_states={"contact": "contact"})


def test_registration() -> None:
    from hapticframe_failure_zone import plugin

    (spec,) = list(plugin.hapticframe_sensor_models())
    assert spec.name == "failure-zone-kernel"
    assert spec.load_factory() is FailureZoneKernel
    schema = spec.config.model_json_schema()
    assert all("description" in p for p in schema["properties"].values())
