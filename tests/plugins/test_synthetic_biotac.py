"""Synthetic granular-media BioTac trials (dissertation chapter 2, §2.6 and §2.8)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hapticframe_biotac._synthetic import (
    CYLINDER_DIAMETER_M,
    CYLINDER_TOP_DEPTH_M,
    FRAME_PERIOD_S,
    PAC_PER_FRAME,
    TrialSpec,
    contact_interval_x_m,
    generate_open_air_trial,
    generate_trial,
    granular_noise_ratios,
    robustness_specs,
    training_specs,
)
from hapticframe_biotac._synthetic_media import MEDIA, colored_noise, contact_pattern, highpass_fft

REFERENCE = TrialSpec("cottonwood_beads", 0.04, 0.0, 0.0, True)
FREE = TrialSpec("cottonwood_beads", 0.04, 0.0, 0.0, False)
ARRAYS = ("timestamps_s", "pac", "pdc", "tac", "tdc", "electrodes", "position_m", "contact")


def _trials(spec: TrialSpec, count: int, seed: int) -> list:
    rng = np.random.default_rng(seed)
    return [generate_trial(spec, rng) for _ in range(count)]


# --- determinism, shapes, units ---------------------------------------------------------------


def test_same_seed_gives_identical_trials_and_other_seeds_differ() -> None:
    first = generate_trial(REFERENCE, np.random.default_rng(7))
    again = generate_trial(REFERENCE, np.random.default_rng(7))
    other = generate_trial(REFERENCE, np.random.default_rng(8))
    for name in ARRAYS:
        np.testing.assert_array_equal(getattr(first, name), getattr(again, name))
    assert not np.array_equal(first.electrodes, other.electrodes)
    assert not np.array_equal(first.pac, other.pac)


@pytest.mark.parametrize("medium", sorted(MEDIA))
@pytest.mark.parametrize("speed", [0.02, 0.04])
def test_shapes_dtypes_and_units(medium: str, speed: float) -> None:
    spec = TrialSpec(medium, speed, 20.0, 0.035, True)
    trial = generate_trial(spec, np.random.default_rng(1))
    n = trial.n_frames
    assert n == int(0.125 / (speed * FRAME_PERIOD_S)) + 1
    assert trial.pac.shape == (n, PAC_PER_FRAME)
    assert trial.electrodes.shape == (n, 19)
    assert trial.position_m.shape == (n, 2)
    for name in ("pdc", "tac", "tdc", "timestamps_s"):
        assert getattr(trial, name).shape == (n,)
    for name in ARRAYS[:-1]:
        assert getattr(trial, name).dtype == np.float64
        assert np.all(np.isfinite(getattr(trial, name)))
    assert trial.contact.dtype == np.int8
    np.testing.assert_allclose(np.diff(trial.timestamps_s), FRAME_PERIOD_S)
    # Metres: the fingertip covers about speed × duration along x and stays on its lane in y.
    travelled = trial.position_m[-1, 0] - trial.position_m[0, 0]
    assert travelled == pytest.approx(speed * trial.timestamps_s[-1], rel=0.08)
    assert np.all(np.abs(trial.position_m[:, 1]) < 0.01)
    for name in ("pac", "pdc", "tac", "tdc", "electrodes"):
        values = getattr(trial, name)
        assert np.all((values >= 0.0) & (values <= 4095.0))
        np.testing.assert_array_equal(values, np.round(values))  # 12-bit counts


def test_resting_counts_look_like_a_biotac() -> None:
    trial = generate_open_air_trial(FREE, np.random.default_rng(3))
    assert 1700 < np.median(trial.pdc) < 2300
    assert 1950 < np.median(trial.pac) < 2150
    resting = np.median(trial.electrodes, axis=0)
    assert np.all((resting > 2000) & (resting < 3700))


# --- labels from the geometry -----------------------------------------------------------------


@pytest.mark.parametrize("medium", sorted(MEDIA))
def test_no_object_means_no_contact(medium: str) -> None:
    for speed in (0.02, 0.04):
        spec = TrialSpec(medium, speed, 0.0, 0.0, False)
        assert not generate_trial(spec, np.random.default_rng(11)).contact.any()


@pytest.mark.parametrize("offset", [0.0, 0.035])
def test_contact_interval_matches_the_cylinder(offset: float) -> None:
    spec = TrialSpec("cottonwood_beads", 0.04, 0.0, offset, True)
    for trial in _trials(spec, 8, seed=int(offset * 1000)):
        on = np.flatnonzero(trial.contact)
        assert on.size and np.all(np.diff(on) == 1)  # one block: first to last contact
        first, last = on[0], on[-1]
        assert trial.contact[: first].sum() == 0 and trial.contact[last + 1 :].sum() == 0
        depth = float(np.mean(trial.extras["depth_m"][first : last + 1]))
        start, end = contact_interval_x_m(spec, depth)
        step = spec.speed_m_per_s * FRAME_PERIOD_S
        assert trial.position_m[first, 0] == pytest.approx(start, abs=step + 0.0015)
        assert trial.position_m[last, 0] == pytest.approx(end, abs=step + 0.0015)
        # The chord is centred on the cylinder's axis, no longer than 1 cm interference allows.
        centre = 0.5 * (trial.position_m[first, 0] + trial.position_m[last, 0])
        assert centre == pytest.approx(offset, abs=0.003)
        radius = CYLINDER_DIAMETER_M / 2
        longest = 2 * np.sqrt(radius**2 - (radius - (0.05 + 0.001 - CYLINDER_TOP_DEPTH_M)) ** 2)
        assert 0.03 < trial.position_m[last, 0] - trial.position_m[first, 0] < longest + 2 * step


def test_shallow_rake_passes_over_the_object() -> None:
    spec = TrialSpec("bbs", 0.04, 0.0, 0.0, True, fingertip_depth_m=0.035)
    assert contact_interval_x_m(spec) is None
    assert not generate_trial(spec, np.random.default_rng(0)).contact.any()


# --- effects reported in §2.8 -----------------------------------------------------------------


def test_noise_ratios_follow_the_thesis_within_a_factor_of_two() -> None:
    ratios = granular_noise_ratios(FREE, np.random.default_rng(21), n_trials=16)
    assert 2.5 <= ratios["pac"] <= 10.0  # thesis ×5
    assert 7.5 <= ratios["pdc"] <= 30.0  # thesis ×15
    assert 2.5 <= ratios["electrodes"] <= 10.0  # thesis ×5
    assert 2.5 <= ratios["electrode_1"] <= 10.0  # thesis ×5
    assert 1.5 <= ratios["electrode_7"] <= 6.0  # thesis ×3
    assert 3.0 <= ratios["electrode_11"] <= 12.0  # thesis ×6
    assert ratios["electrode_7"] < ratios["electrode_11"]
    assert ratios["pdc"] > ratios["pac"]


def test_sustained_tip_deformation_on_contact() -> None:
    up, down = [], []
    for trial in _trials(REFERENCE, 20, seed=4):
        on = np.flatnonzero(trial.contact)
        during = trial.electrodes[on].mean(axis=0)
        before = trial.electrodes[: max(on[0] - 10, 1)].mean(axis=0)
        up.append(during[6] - before[6])
        down.append(0.5 * (during[0] + during[10]) - 0.5 * (before[0] + before[10]))
    assert np.median(up) > 40.0  # electrode #7 compressed
    assert np.median(down) < -20.0  # #1 and #11 bulge
    pattern = contact_pattern(0.0)
    assert np.argmax(pattern) == 6 and pattern[0] < 0 and pattern[10] < 0


def test_pac_and_pdc_transient_after_last_contact() -> None:
    burst, sustained, pdc_bump = [], [], []
    for trial in _trials(REFERENCE, 20, seed=5):
        last = int(np.flatnonzero(trial.contact)[-1])
        pac = trial.pac - np.median(trial.pac)
        burst.append(np.sqrt(np.mean(pac[last + 1 : last + 12] ** 2)))
        sustained.append(np.sqrt(np.mean(pac[last - 40 : last - 5] ** 2)))
        later = trial.pdc[last + 25 : last + 30].mean()
        pdc_bump.append(trial.pdc[last + 3 : last + 10].mean() - later)
    assert np.median(burst) > 1.8 * np.median(sustained)
    assert np.median(pdc_bump) > 5.0


def test_jamming_raises_the_load_just_before_first_contact() -> None:
    rise = []
    for trial in _trials(REFERENCE, 30, seed=6):
        first = int(np.flatnonzero(trial.contact)[0])
        tip = trial.electrodes[:, 6]
        rise.append(tip[first - 4 : first].mean() - tip[first - 30 : first - 15].mean())
    # Four frames (40 ms at 4 cm/s) before contact the tip already feels the object.
    assert np.median(rise) > 15.0


def test_particle_size_and_speed_shape_the_vibration() -> None:
    def centroid_and_rms(medium: str, speed: float) -> tuple[float, float]:
        spec = TrialSpec(medium, speed, 0.0, 0.0, False)
        cents, rms = [], []
        for trial in _trials(spec, 6, seed=9):
            pac = trial.pac.ravel() - trial.pac.mean()
            power = np.abs(np.fft.rfft(pac)) ** 2
            freqs = np.fft.rfftfreq(pac.size, 1 / 2200)
            cents.append(np.sum(freqs * power) / np.sum(power))
            rms.append(np.std(pac))
        return float(np.median(cents)), float(np.median(rms))

    fine_centroid, _ = centroid_and_rms("poppy_seed", 0.04)
    coarse_centroid, fast_rms = centroid_and_rms("cottonwood_beads", 0.04)
    _, slow_rms = centroid_and_rms("cottonwood_beads", 0.02)
    assert fine_centroid > 1.5 * coarse_centroid  # shorter impacts: wider vibration band
    assert fast_rms > 1.3 * slow_rms


def test_open_air_trial_has_only_sensor_noise_but_keeps_contact() -> None:
    trial = generate_open_air_trial(REFERENCE, np.random.default_rng(2))
    free = trial.contact == 0
    assert trial.contact.any()
    assert np.percentile(trial.pdc[free][:20], 75) - np.percentile(trial.pdc[free][:20], 25) <= 4


# --- datasets -----------------------------------------------------------------------------------


def test_training_set_matches_the_thesis() -> None:
    specs = training_specs(np.random.default_rng(0))
    assert len(specs) == 750
    assert sum(s.has_object for s in specs) == 250
    assert {(s.medium, s.speed_m_per_s, s.orientation_deg, s.object_offset_m) for s in specs} == {
        ("cottonwood_beads", 0.04, 0.0, 0.0)
    }
    assert specs == training_specs(np.random.default_rng(0))
    assert specs != training_specs(np.random.default_rng(1))  # shuffled by the seed


def test_robustness_set_matches_the_thesis() -> None:
    specs = robustness_specs(np.random.default_rng(0))
    assert len(specs) == 5 * 75
    for medium in MEDIA:
        mine = [s for s in specs if s.medium == medium]
        with_object = [s for s in mine if s.has_object]
        assert len(with_object) == 50 and len(mine) == 75
        assert all(s.speed_m_per_s == 0.02 for s in mine)
        assert sum(s.orientation_deg == 20.0 for s in with_object) == 25
        assert sum(s.object_offset_m == 0.035 for s in with_object) == 25
    assert specs == robustness_specs(np.random.default_rng(0))


# --- extremes -------------------------------------------------------------------------------------


@pytest.mark.parametrize("speed", [0.005, 0.2])
def test_slowest_and_fastest_speeds(speed: float) -> None:
    spec = TrialSpec("poppy_seed", speed, 45.0, 0.0, True)
    trial = generate_trial(spec, np.random.default_rng(0))
    assert trial.n_frames >= 60  # never a single-frame trial
    assert trial.contact.any() and np.all(np.isfinite(trial.pac))
    assert np.all((trial.electrodes >= 0) & (trial.electrodes <= 4095))


@pytest.mark.parametrize(
    "changes",
    [
        {"speed_m_per_s": 0.0},
        {"speed_m_per_s": 0.5},
        {"speed_m_per_s": float("nan")},
        {"orientation_deg": 90.0},
        {"object_offset_m": float("inf")},
        {"fingertip_depth_m": -0.01},
        {"medium": "sand"},
    ],
)
def test_out_of_range_specs_are_refused(changes: dict) -> None:
    values = {**REFERENCE.__dict__, **changes}
    with pytest.raises(ValueError):
        generate_trial(TrialSpec(**values), np.random.default_rng(0))


def test_noise_primitives() -> None:
    rng = np.random.default_rng(0)
    noise = colored_noise(rng, 4, 20000, 10.0)
    assert noise.shape == (4, 20000)
    assert np.std(noise) == pytest.approx(1.0, rel=0.1)
    lag1 = np.mean(noise[:, 1:] * noise[:, :-1])
    assert lag1 == pytest.approx(np.exp(-0.1), abs=0.05)
    assert colored_noise(rng, 3, 0, 5.0).shape == (3, 0)
    constant = np.full(4000, 7.0)
    assert np.abs(highpass_fft(constant, 10.0, 2200.0)[-1000:]).max() < 0.1  # DC is removed


# --- imports ------------------------------------------------------------------


def test_module_import_does_not_load_scikit_learn() -> None:
    plugins = Path(__file__).resolve().parents[2] / "plugins"
    code = (
        f"import sys; sys.path.insert(0, {str(plugins)!r}); import hapticframe_biotac._synthetic; "
        "assert 'sklearn' not in sys.modules, 'sklearn loaded'"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
