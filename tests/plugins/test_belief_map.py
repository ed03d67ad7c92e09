"""The ``contact-point`` sensor model and the ``belief-map`` map (hapticframe_belief_map)."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from hapticframe import Circle, RegionConfig, Scene
from hapticframe.kinds import BuildContext, LocatedMeasurement, Observations, Region, RunOutcome
from hapticframe_belief_map import BeliefMap, BeliefMapConfig, ContactPoint, ContactPointConfig
from hapticframe_belief_map import _functional as fn
from hapticframe_belief_map import plugin as bm_plugin

SPECS = [*bm_plugin.hapticframe_sensor_models(), *bm_plugin.hapticframe_maps()]


def build_map(seed: int = 0, scene: Scene | None = None, **config) -> BeliefMap:
    context = BuildContext(id="belief", rng=np.random.default_rng(seed), scene=scene)
    return BeliefMap(BeliefMapConfig(**config), context)


def build_model(**config) -> ContactPoint:
    context = BuildContext(id="cp", rng=np.random.default_rng(0))
    return ContactPoint(ContactPointConfig(**config), context)


def blob_observations(
    n: int, seed: int, *, radius: float = 0.04, noise: float = 0.0
) -> Observations:
    """Uniform points in a 0.2 m square around the origin; contact inside a disc at the origin."""
    rng = np.random.default_rng(seed)
    points = rng.uniform(-0.1, 0.1, (n, 2))
    inside = np.hypot(points[:, 0], points[:, 1]) < radius
    flip = rng.random(n) < noise
    return Observations(points, (inside ^ flip).astype(float))


def sweep(
    n: int = 200, contact: tuple[int, int] = (60, 120), step: float = 0.0004
) -> LocatedMeasurement:
    """A fingertip raked along +x at 100 Hz; the classifier says contact on
    ``[contact[0], contact[1])``."""
    t = 0.01 * np.arange(1, n + 1)
    x = -0.04 + step * np.arange(n)
    p_contact = np.full(n, 0.05)
    p_contact[contact[0]:contact[1]] = 0.9
    probabilities = np.column_stack([1 - p_contact, p_contact])
    return LocatedMeasurement(t, np.column_stack([x, np.full(n, 0.002)]), np.zeros(n),
                              probabilities, ("free", "contact"))


def outcome(tmp_path, figures: bool = True) -> RunOutcome:
    return RunOutcome(out_dir=tmp_path, scene=None, movements=(), components={}, wall_time_s=0.0,
                      figures=figures)


# --- configuration --------------------------------------------------------------------------------


def test_config_defaults_and_gamma() -> None:
    cfg = BeliefMapConfig()
    assert cfg.update_every == 10  # the thesis refits every 10 SF-RNN steps
    assert cfg.gamma_per_m2 == pytest.approx(1 / (2 * 0.02**2))
    assert BeliefMapConfig(length_scale_m=0.1).gamma_per_m2 == pytest.approx(50.0)
    for spec in SPECS:
        schema = spec.config.model_json_schema()
        assert all("description" in p for p in schema["properties"].values()), spec.name


@pytest.mark.parametrize("bad", [
    {"length_scale_m": 0.0}, {"cell_size_m": -1.0}, {"max_points": 3}, {"update_every": 0},
    {"calibration_folds": 1}, {"penalty_c": float("nan")}, {"unknown": 1},
])
def test_bad_map_config_is_rejected(bad) -> None:
    with pytest.raises(ValidationError):
        BeliefMapConfig(**bad)


def test_bad_contact_point_config_is_rejected() -> None:
    with pytest.raises(ValidationError):
        ContactPointConfig(class_targets={"contact": 1.5})
    with pytest.raises(ValidationError):
        ContactPointConfig(class_targets={})


# --- contact-point sensor model -------------------------------------------------------------------


def test_contact_point_observes_the_contact_probability_at_the_fingertip() -> None:
    model = build_model()
    measurement = sweep(50, (10, 20))
    obs = model.observe(measurement)
    np.testing.assert_array_equal(obs.points_m, measurement.positions_m)
    np.testing.assert_allclose(obs.targets, measurement.probabilities[:, 1])
    np.testing.assert_array_equal(obs.weights, np.ones(50))
    assert len(model.observe(measurement.select(slice(0, 0)))) == 0
    timeline = model.timeline
    np.testing.assert_array_equal(timeline["timestamps_s"], measurement.timestamps_s)
    np.testing.assert_allclose(timeline["contact_probability"], obs.targets)


def test_three_classes_map_per_config() -> None:
    probabilities = np.array([[0.2, 0.5, 0.3], [0.1, 0.1, 0.8], [1.0, 0.0, 0.0]])
    classes = ("free", "jamming", "contact")
    np.testing.assert_allclose(
        fn.contact_targets(probabilities, classes, "contact"), [0.3, 0.8, 0.0]
    )
    both = fn.contact_targets(probabilities, classes, "contact", {"contact": 1.0, "jamming": 1.0})
    np.testing.assert_allclose(both, [0.8, 0.9, 0.0])
    half = fn.contact_targets(probabilities, classes, "contact", {"contact": 1.0, "jamming": 0.5})
    np.testing.assert_allclose(half, [0.55, 0.85, 0.0])
    with pytest.raises(ValueError, match="contact_class"):
        fn.contact_targets(probabilities, ("free", "a", "b"), "contact")


def test_contact_point_finalize_writes_the_timeline(tmp_path) -> None:
    model = build_model()
    measurement = sweep(200, (60, 120))
    for i in range(0, 200, 7):  # streamed in uneven parts
        model.observe(measurement.select(slice(i, i + 7)))
    metrics = model.finalize(outcome(tmp_path))
    assert (tmp_path / "timeline.png").stat().st_size > 10_000
    assert metrics["contact_first_s"] == pytest.approx(measurement.timestamps_s[60])
    assert metrics["contact_last_s"] == pytest.approx(measurement.timestamps_s[119])
    assert metrics["contact_fraction"] == pytest.approx(0.3)
    quiet = tmp_path / "quiet"
    build_model().finalize(outcome(quiet, figures=False))
    assert not quiet.exists()


# --- binning --------------------------------------------------------------------------------------


def test_binning_is_exact_under_coarsening_and_order() -> None:
    obs = blob_observations(5000, 1)
    fine = fn.bin_observations(obs.points_m, obs.targets, obs.weights, 0.002)
    direct = fn.bin_observations(obs.points_m, obs.targets, obs.weights, 0.008)
    twice = fn.coarsen_bins(fn.coarsen_bins(fine))
    np.testing.assert_array_equal(twice.keys, direct.keys)
    np.testing.assert_allclose(twice.weights, direct.weights)
    np.testing.assert_allclose(twice.position_sums, direct.position_sums, atol=1e-12)
    # Weighted mean positions lie inside their cells and total weight is kept.
    assert fine.weights.sum() == pytest.approx(5000)
    cells = np.floor(fine.positions / 0.002)
    np.testing.assert_array_equal(cells, fine.keys[:, :2])
    order = np.random.default_rng(2).permutation(5000)
    shuffled = fn.bin_observations(
        obs.points_m[order], obs.targets[order], obs.weights[order], 0.002
    )
    np.testing.assert_array_equal(shuffled.keys, fine.keys)


def test_update_cost_is_bounded() -> None:
    the_map = build_map(max_points=300)
    for part in range(4):
        the_map.update(blob_observations(25_000, 10 + part, noise=0.05))
    assert the_map.observations_seen == 100_000
    assert the_map.representatives <= 300
    assert the_map.cell_size_m > 0.002  # it had to coarsen
    # Streaming reached the same level and bins as binning everything at once.
    everything = Observations.concatenate(
        [blob_observations(25_000, 10 + p, noise=0.05) for p in range(4)]
    )
    batch = build_map(max_points=300, update_every=10**6)
    batch.update(everything)
    assert batch.cell_size_m == the_map.cell_size_m
    assert batch.representatives == the_map.representatives


# --- the map --------------------------------------------------------------------------------------


def test_prior_before_both_classes() -> None:
    the_map = build_map()
    grid = np.array([[0.0, 0.0], [0.3, 0.2], [5.0, -5.0]])
    before = the_map.query(grid)
    np.testing.assert_array_equal(before.mean, 0.5)
    np.testing.assert_array_equal(before.std, 0.5)
    free = Observations(np.column_stack([np.linspace(0, 0.1, 48), np.zeros(48)]), np.zeros(48))
    the_map.update(free)
    only_free = the_map.query(grid)
    # On observed ground the smoothed fraction (0 + 1) / (48 + 2); far away the uniform prior.
    np.testing.assert_allclose(only_free.mean, [1 / 50, 0.5, 0.5], atol=1e-9)
    np.testing.assert_allclose(only_free.std, np.sqrt(only_free.mean * (1 - only_free.mean)))
    assert not the_map.fitted
    # A single contact bin is not enough for cross-validated Platt scaling: still the prior.
    the_map.update(Observations(np.tile([[0.2, 0.0]], (10, 1)), np.ones(10)))
    assert not the_map.fitted
    assert the_map.query(grid).mean == pytest.approx([11 / 60, 0.5, 0.5])
    # Without the unexplored prior the fraction holds everywhere.
    flat = build_map(unexplored_prior=None)
    flat.update(free)
    np.testing.assert_allclose(flat.query(grid).mean, 1 / 50)
    points = np.column_stack([np.linspace(0.21, 0.23, 10), np.zeros(10)])
    the_map.update(Observations(points, np.ones(10)))
    assert the_map.fitted


def test_learns_a_blob_and_stays_in_unit_interval() -> None:
    the_map = build_map()
    the_map.update(blob_observations(1500, 3, noise=0.03))
    assert the_map.fitted
    estimate = the_map.query([[0.0, 0.0], [0.01, -0.01], [0.09, 0.09], [-0.09, 0.08], [0.0, -0.09]])
    assert estimate.mean[:2].min() > 0.8
    assert estimate.mean[2:].max() < 0.2
    np.testing.assert_allclose(estimate.std, np.sqrt(estimate.mean * (1 - estimate.mean)))
    far = the_map.query(np.random.default_rng(4).uniform(-1e3, 1e3, (500, 2)))
    assert np.all((far.mean >= 0) & (far.mean <= 1)) and np.all(np.isfinite(far.std))
    with pytest.raises(ValueError, match="finite"):
        the_map.query([[np.nan, 0.0]])
    assert the_map.query(np.empty((0, 2))).mean.shape == (0,)


def test_unexplored_ground_returns_to_the_prior() -> None:
    obs = blob_observations(800, 12)
    blended, bare = build_map(), build_map(unexplored_prior=None)
    blended.update(obs)
    bare.update(obs)
    inside = np.random.default_rng(13).uniform(-0.09, 0.09, (100, 2))
    np.testing.assert_allclose(blended.query(inside).mean, bare.query(inside).mean, atol=0.05)
    far = np.array([[0.5, 0.5], [-3.0, 2.0]])
    np.testing.assert_allclose(blended.query(far).mean, 0.5, atol=1e-6)
    assert np.all(np.abs(bare.query(far).mean - 0.5) > 0.05)  # the SVC's intercept instead


def test_far_from_the_origin_the_map_is_the_same() -> None:
    """Centring before the fit keeps RBF distances exact 1e5 m from the origin."""
    obs = blob_observations(600, 5)
    near, far = build_map(), build_map()
    near.update(obs)
    far.update(Observations(obs.points_m + 1e5, obs.targets))
    probe = np.random.default_rng(6).uniform(-0.1, 0.1, (200, 2))
    # The SVC is fitted on the same bins and must agree; the calibration folds are a hash of
    # the raw positions, so the Platt fit differs a little.
    svc_near, svc_far = near._current, far._current
    np.testing.assert_allclose(
        svc_far.model.svc.decision_function(probe + 1e5 - svc_far.origin_m),
        svc_near.model.svc.decision_function(probe - svc_near.origin_m), atol=1e-6)
    np.testing.assert_allclose(far.query(probe + 1e5).mean, near.query(probe).mean, atol=0.25)


def test_refits_follow_update_every() -> None:
    the_map = build_map(update_every=10)
    obs = blob_observations(200, 7)
    for i in range(0, 95, 5):
        the_map.update(Observations(obs.points_m[i:i + 5], obs.targets[i:i + 5]))
    assert the_map.observations_seen == 95
    # One refit per 10 observations (9 so far), the first ones possibly without both classes.
    fitted_before = the_map.refits
    the_map.update(Observations(obs.points_m[95:100], obs.targets[95:100]))
    assert the_map.refits == fitted_before + int(the_map.fitted)


def test_region_defaults() -> None:
    assert build_map().region == Region(0.0, 0.75, 0.0, 0.50)
    the_map = build_map(region_margin_m=0.01)
    the_map.update(Observations([[0.1, 0.2], [0.2, 0.25]], [0.0, 1.0]))
    region = the_map.region
    assert (region.x_min_m, region.x_max_m) == pytest.approx((0.09, 0.21))
    assert (region.y_min_m, region.y_max_m) == pytest.approx((0.19, 0.26))
    configured = build_map(region=RegionConfig(x_min_m=-1, x_max_m=1, y_min_m=-1, y_max_m=1))
    assert configured.region == Region(-1, 1, -1, 1)
    scene = Scene(objects=[Circle(center_m=(0.3, 0.2), radius_m=0.05)])
    assert build_map(scene=scene).region == scene.region.to_region()


def test_deterministic_and_order_independent() -> None:
    obs = blob_observations(800, 8, noise=0.05)
    first, second = build_map(seed=3), build_map(seed=3)
    first.update(obs)
    second.update(obs)
    probe = np.random.default_rng(9).uniform(-0.1, 0.1, (300, 2))
    np.testing.assert_array_equal(first.query(probe).mean, second.query(probe).mean)
    order = np.random.default_rng(10).permutation(len(obs))
    shuffled = build_map(seed=3)
    shuffled.update(Observations(obs.points_m[order], obs.targets[order]))
    np.testing.assert_allclose(shuffled.query(probe).mean, first.query(probe).mean, atol=1e-6)


def test_snapshots_at_first_mid_and_last_contact(tmp_path) -> None:
    model, the_map = build_model(), build_map()
    measurement = sweep(200, (63, 127))
    for i in range(200):  # one classifier step at a time, as a run does
        the_map.update(model.observe(measurement.select(slice(i, i + 1))))
    assert the_map.contact_indices == (63, 126)
    snaps = the_map.snapshots()
    assert set(snaps) == {"first_contact", "mid_contact", "last_contact"}
    # Refits happen after observations 10, 20, ...: the first that includes each event.
    assert snaps["first_contact"].observations_seen == 70
    assert snaps["mid_contact"].observations_seen == 100  # (63 + 126) // 2 = 94
    assert snaps["last_contact"].observations_seen == 130
    # At first contact the probability rises towards the fingertip, well above the free
    # start of the rake (with the default C = 1 and l = 2 cm, 7 contact steps do not yet
    # reach 0.5 at the tip: the RBF averages them with the free stretch behind).
    tip = snaps["first_contact"].fingertip_m
    np.testing.assert_allclose(tip, measurement.positions_m[69])
    rising = snaps["first_contact"].probability(measurement.positions_m[[5, 40, 60, 69]])
    assert np.all(np.diff(rising) > 0)
    assert rising[-1] > 10 * rising[0] and rising[-1] > 0.1
    # At last contact the contact chord is high and the free start low; ground not yet
    # visited (index 195) reads about the uniform prior.
    chord = measurement.positions_m[[80, 95, 110]]
    assert snaps["last_contact"].probability(chord).min() > 0.7
    assert snaps["last_contact"].probability(measurement.positions_m[[5]])[0] < 0.3
    ahead = snaps["last_contact"].probability(measurement.positions_m[[195]])[0]
    assert 0.2 < ahead < 0.8
    # At the end both free ends are low and the chord is still high.
    assert the_map.query(measurement.positions_m[[5, 195]]).mean.max() < 0.3
    assert the_map.query(chord).mean.min() > 0.7
    metrics = the_map.finalize(outcome(tmp_path))
    assert metrics["belief_map_snapshots"] == ["first_contact", "last_contact", "mid_contact"]
    for name in ("first_contact", "mid_contact", "last_contact", "final"):
        assert (tmp_path / f"belief_{name}.png").stat().st_size > 5_000
    quiet = tmp_path / "quiet"
    the_map.finalize(outcome(quiet, figures=False))
    assert not quiet.exists()


def test_snapshot_grid_is_the_map_on_a_grid_and_no_grid_queryable() -> None:
    from hapticframe.kinds import GridQueryable

    model, the_map = build_model(), build_map()
    measurement = sweep(200, (63, 127))
    for i in range(200):
        the_map.update(model.observe(measurement.select(slice(i, i + 1))))
    # Its grid takes a snapshot and a cell count, not GridQueryable's spacing: a planner that
    # checks for the protocol must not take the belief map for one and call it wrongly.
    assert not isinstance(the_map, GridQueryable)
    assert not hasattr(the_map, "probability_grid")
    xs, ys, mean = the_map.snapshot_grid(None, 40)
    assert len(xs) == 40 and mean.shape == (len(ys), len(xs))
    gx, gy = np.meshgrid(xs, ys)
    points = np.column_stack([gx.ravel(), gy.ravel()])
    np.testing.assert_array_equal(mean.ravel(), the_map.query(points).mean)
    first = the_map.snapshots()["first_contact"]
    _, _, early = the_map.snapshot_grid(first, 40)
    np.testing.assert_array_equal(early.ravel(), first.probability(points))
    assert np.abs(early - mean).max() > 0.2  # the first-contact map, not the final one


def test_no_contact_gives_no_contact_snapshots(tmp_path) -> None:
    model, the_map = build_model(), build_map()
    the_map.update(model.observe(sweep(100, (0, 0))))
    assert the_map.snapshots() == {}
    assert the_map.contact_indices == (None, None)
    the_map.finalize(outcome(tmp_path))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["belief_final.png"]


def test_reset_forgets_everything() -> None:
    the_map = build_map()
    the_map.update(blob_observations(300, 11))
    assert the_map.fitted
    the_map.reset()
    assert not the_map.fitted and the_map.representatives == 0 and the_map.snapshots() == {}
    np.testing.assert_array_equal(the_map.query([[0.0, 0.0]]).mean, 0.5)


def test_synthetic_biotac_trial_puts_the_object_on_the_contact_chord() -> None:
    synthetic = pytest.importorskip("hapticframe_biotac")
    spec = synthetic.TrialSpec(medium="cottonwood_beads", speed_m_per_s=0.04, orientation_deg=0.0,
                               object_offset_m=0.0, has_object=True)
    trial = synthetic.generate_trial(spec, np.random.default_rng(0))
    model, the_map = build_model(), build_map()
    probabilities = np.column_stack([1.0 - trial.contact, trial.contact]).astype(float)
    measurement = LocatedMeasurement(
        trial.timestamps_s,
        trial.position_m,
        np.zeros(len(trial.contact)),
        probabilities,
        ("free", "contact"),
    )
    for i in range(0, len(measurement), 10):
        the_map.update(model.observe(measurement.select(slice(i, i + 10))))
    contact_x = trial.position_m[trial.contact > 0, 0]
    y = float(np.median(trial.position_m[:, 1]))
    centre = [[0.5 * (contact_x.min() + contact_x.max()), y]]
    assert the_map.query(centre).mean[0] > 0.8
    ends = [[trial.position_m[0, 0], y], [trial.position_m[-1, 0], y]]
    assert the_map.query(ends).mean.max() < 0.3
    region = the_map.region  # extent of the rake plus 5 cm, not the 0.75 x 0.50 m default
    assert region.size_m[0] < 0.35
