"""Tare of BioTac recordings: causal reference, streaming = batch, and the sensor option."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

import hapticframe
from hapticframe.testing import make_component
from hapticframe_biotac import BioTacSensorConfig
from hapticframe_biotac._frame import BioTacFrames, layout_for
from hapticframe_biotac._sensor import tare_frames, tare_in_air
from hapticframe_biotac._synthetic import TrialSpec, generate_trial, open_air_frames
from hapticframe_biotac._tare import TareState, tare_reference
from hapticframe_biotac.plugin import SPECS


@pytest.fixture(scope="module")
def registry():
    return hapticframe.make_plugin_manager(modules=["hapticframe_biotac.plugin"]).registry


def test_reference_is_the_running_mean_then_the_mean_of_the_first_frames():
    x = np.arange(12.0).reshape(6, 2)
    ref = tare_reference(x, 3)
    expected = np.array([[0, 1], [1, 2], [2, 3], [2, 3], [2, 3], [2, 3]], dtype=float)
    np.testing.assert_allclose(ref, expected)
    # One frame: every frame is referred to frame 0.
    np.testing.assert_allclose(tare_reference(x, 1), np.broadcast_to(x[0], x.shape))
    # More tare frames than the recording: the running mean throughout.
    np.testing.assert_allclose(tare_reference(x, 100)[-1], x.mean(axis=0))


def test_streaming_in_chunks_equals_batch_and_skips_invalid_frames():
    rng = np.random.default_rng(3)
    x = rng.normal(2000.0, 50.0, (40, 3, 4))
    valid = rng.random(40) > 0.3
    batch = tare_reference(x, 10, valid)
    state = TareState(10)
    parts = [state.reference(x[a:b], valid[a:b]) for a, b in ((0, 1), (1, 7), (7, 25), (25, 40))]
    np.testing.assert_allclose(np.concatenate(parts), batch, rtol=1e-13)
    first_ten = np.flatnonzero(valid[:10])
    np.testing.assert_allclose(batch[-1], x[first_ten].mean(axis=0))


def test_reference_is_zero_until_a_valid_frame_and_never_nan():
    x = np.array([[np.nan], [5.0], [7.0], [9.0]])
    ref = tare_reference(x, 3, np.array([True, False, True, True]))
    np.testing.assert_allclose(ref[:, 0], [0.0, 0.0, 7.0, 7.0])
    with pytest.raises(ValueError, match="at least 1"):
        TareState(0)
    with pytest.raises(ValueError, match="shape"):
        tare_reference(x, 2, np.ones(3, dtype=bool))


def test_tare_removes_the_trial_offsets_of_a_synthetic_trial():
    spec = TrialSpec("cottonwood_beads", 0.04, 0.0, 0.0, True)
    trial = generate_trial(spec, np.random.default_rng(5))
    frames = BioTacFrames(layout_for("biotac"), trial.timestamps_s, trial.pac, trial.pdc, trial.tac,
                          trial.tdc, trial.electrodes)
    tared = tare_frames(frames, 10)
    # Resting electrode counts lie at 2,300-3,400; tared, the first 10 frames average zero
    # and the object still shows (the largest change comes during contact).
    assert np.abs(trial.electrodes[:10].mean(axis=0)).min() > 2000
    np.testing.assert_allclose(tared.electrodes[:10].mean(axis=0), 0.0, atol=np.abs(
        trial.electrodes[:10] - trial.electrodes[:10].mean(axis=0)).max())
    np.testing.assert_allclose(tared.electrodes[10:] + trial.electrodes[:10].mean(axis=0),
                               trial.electrodes[10:])
    contact = trial.contact.astype(bool)
    assert np.abs(tared.electrodes[contact]).max() > 3 * np.abs(tared.electrodes[:10]).max()
    assert tare_frames(frames, 0) is frames


def test_sensor_option_tares_each_trial_and_is_refused_for_spi(registry):
    spec = SPECS[0]
    raw = make_component(spec, registry=registry, seed=4, config={
        "source": "synthetic", "n_trials": 2, "frames_per_read": 1000, "medium": "bbs"})
    tared = make_component(spec, registry=registry, seed=4, config={
        "source": "synthetic", "n_trials": 2, "frames_per_read": 1000, "medium": "bbs",
        "tare_frames": 5})
    raw_trials = list(raw.iter_recordings())
    tared_trials = list(tared.iter_recordings())
    assert len(raw_trials) == len(tared_trials) == 2
    for a, b in zip(raw_trials, tared_trials, strict=True):
        ref = a.channels["electrodes"][:5].mean(axis=0)
        np.testing.assert_allclose(b.channels["electrodes"][5:], a.channels["electrodes"][5:] - ref)
        np.testing.assert_array_equal(b.channels["contact"], a.channels["contact"])
    with pytest.raises(ValidationError, match="tare_frames"):
        BioTacSensorConfig(source="spi", tare_frames=3)


# --- tare in open air before the trial ---------------------------------------------------


def test_open_air_frames_are_the_resting_counts_and_leave_the_trial_unchanged():
    spec = TrialSpec("bbs", 0.02, 20.0, 0.035, True)
    trial = generate_trial(spec, np.random.default_rng(8))
    again = generate_trial(spec, np.random.default_rng(8))
    air = open_air_frames(trial, 400, np.random.default_rng(9))
    assert air["pac"].shape == (400, 22) and air["electrodes"].shape == (400, 19)
    for name in ("pdc", "tac", "tdc"):
        assert air[name].shape == (400,)
    rest = trial.extras["air_rest"]
    # Sensor noise at rest is 1-2 counts, so 400 frames average to within half a count.
    for name in ("pac", "pdc", "tac", "tdc", "electrodes"):
        np.testing.assert_allclose(air[name].mean(axis=0), rest[name], atol=0.5)
        assert np.all(air[name] == np.round(air[name]))  # 12-bit counts
    # The open-air frames come from their own generator; the trial is not touched.
    for name in ("pac", "pdc", "tac", "tdc", "electrodes", "position_m", "contact"):
        np.testing.assert_array_equal(getattr(trial, name), getattr(again, name))
    with pytest.raises(ValueError, match="n_frames"):
        open_air_frames(trial, 0, np.random.default_rng(0))
    stripped = generate_trial(spec, np.random.default_rng(8))
    stripped.extras.pop("air_rest")
    with pytest.raises(ValueError, match="air_rest"):
        open_air_frames(stripped, 3, np.random.default_rng(0))


def test_air_tare_keeps_the_load_of_the_media_that_a_trial_start_tare_removes():
    # Zeroed in air, a rake through the media reads the drag of the media on pdc and the pad;
    # denser BBs press harder than cottonwood. Zeroed on its own first frames, a trial starts
    # at zero whatever the medium.
    def free_pdc(medium: str, source: str) -> float:
        levels = []
        for seed in range(6):
            trial = generate_trial(TrialSpec(medium, 0.04, 0.0, 0.0, False),
                                   np.random.default_rng(seed))
            frames = BioTacFrames(layout_for("biotac"), trial.timestamps_s, trial.pac,
                                  trial.pdc, trial.tac, trial.tdc, trial.electrodes)
            if source == "air":
                tared = tare_in_air(frames, open_air_frames(trial, 10, np.random.default_rng(seed)))
            else:
                tared = tare_frames(frames, 10)
            levels.append(np.median(tared.pdc))
        return float(np.median(levels))

    cotton, bbs = free_pdc("cottonwood_beads", "air"), free_pdc("bbs", "air")
    assert 20.0 < cotton < bbs
    assert abs(free_pdc("bbs", "trial_start")) < 0.5 * cotton


def test_tare_in_air_subtracts_the_reading_and_refuses_a_broken_one():
    trial = generate_trial(TrialSpec("cottonwood_beads", 0.04, 0.0, 0.0, True),
                           np.random.default_rng(3))
    frames = BioTacFrames(layout_for("biotac"), trial.timestamps_s, trial.pac, trial.pdc,
                          trial.tac, trial.tdc, trial.electrodes)
    air = open_air_frames(trial, 10, np.random.default_rng(4))
    tared = tare_in_air(frames, air)
    np.testing.assert_allclose(tared.electrodes, trial.electrodes - air["electrodes"].mean(axis=0))
    np.testing.assert_allclose(tared.pac, trial.pac - air["pac"].mean())
    np.testing.assert_allclose(tared.tdc, trial.tdc - air["tdc"].mean())
    broken = {**air, "pdc": np.array([np.nan, 1.0])}
    with pytest.raises(ValueError, match="pdc"):
        tare_in_air(frames, broken)
    with pytest.raises(ValueError, match="electrodes"):
        tare_in_air(frames, {**air, "electrodes": np.empty((0, 19))})


def test_sensor_tares_in_air_only_for_the_synthetic_source(registry):
    spec = SPECS[0]
    base = {"source": "synthetic", "n_trials": 2, "frames_per_read": 1000, "medium": "pine_beads"}
    raw = list(make_component(spec, registry=registry, seed=6, config=base).iter_recordings())
    air = list(make_component(spec, registry=registry, seed=6, config={
        **base, "tare_frames": 10, "tare_source": "air"}).iter_recordings())
    again = list(make_component(spec, registry=registry, seed=6, config={
        **base, "tare_frames": 10, "tare_source": "air"}).iter_recordings())
    assert len(air) == 2
    for name in ("pdc", "electrodes", "pac"):
        # The first trial is the raw one minus one constant reading (the open-air frames are
        # drawn after it), so the offset is the same in every frame.
        offset = raw[0].channels[name] - air[0].channels[name]
        spread = np.ptp(offset) if name == "pac" else np.ptp(offset, axis=0).max()
        assert spread < 1e-9 and np.abs(offset).max() > 1.0
        for a, b in zip(air, again, strict=True):
            np.testing.assert_array_equal(a.channels[name], b.channels[name])
    # Air-zeroed resting electrodes (2,300-3,400 raw) are small; the drag of the media remains.
    assert np.abs(np.median(air[0].channels["electrodes"], axis=0)).max() < 200
    with pytest.raises(ValidationError, match="synthetic source"):
        BioTacSensorConfig(source="replay", path="x.csv", tare_frames=5, tare_source="air")
    with pytest.raises(ValidationError, match="tare_frames of at least 1"):
        BioTacSensorConfig(source="synthetic", tare_source="air")
