"""The numpy functions of hapticframe_sfrnn: input assembly, windows, splits, guarded numerics."""

from __future__ import annotations

import numpy as np
import pytest

from hapticframe.kinds import SampleBatch
from hapticframe_sfrnn._functional import (
    FillReport,
    assemble_inputs,
    balanced_accuracy,
    check_labels,
    contact_figures,
    rms_scale,
    sigmoid_pair,
    softmax_rows,
    split_trials,
    window_starts,
)

GROUPS = {"a_code": 3, "b_code": 2}


def _batch(n: int = 4, **valid: np.ndarray) -> SampleBatch:
    a = np.arange(n * 3, dtype=float).reshape(n, 3) + 1.0
    b = -np.arange(n * 2, dtype=float).reshape(n, 2) - 1.0
    return SampleBatch(0.01 * (1 + np.arange(n)), {"a_code": a, "b_code": b}, valid)


def test_assemble_inputs_places_channels_side_by_side() -> None:
    batch = _batch()
    x, present = assemble_inputs(batch, GROUPS)
    assert x.shape == (4, 5) and present.all()
    assert np.array_equal(x[:, :3], batch.channels["a_code"])
    assert np.array_equal(x[:, 3:], batch.channels["b_code"])


def test_absent_channel_is_zero_filled_and_reported() -> None:
    batch = _batch()
    report = FillReport()
    x, present = assemble_inputs(batch, {**GROUPS, "c_code": 4}, report)
    assert x.shape == (4, 9)
    assert np.all(x[:, 5:] == 0.0) and not present[:, 2].any()
    assert report.absent_frames == {"a_code": 0, "b_code": 0, "c_code": 4}


def test_flagged_and_non_finite_frames_are_zero_filled() -> None:
    flags = np.array([True, False, True, True])
    batch = _batch(a_code=flags)
    channels = dict(batch.channels)
    b = np.array(channels["b_code"])
    b[2, 1] = np.nan
    batch = SampleBatch(
        batch.timestamps_s, {"a_code": channels["a_code"], "b_code": b}, {"a_code": flags}
    )
    report = FillReport()
    x, present = assemble_inputs(batch, GROUPS, report)
    assert np.all(x[1, :3] == 0.0) and np.all(x[2, 3:] == 0.0)
    assert np.array_equal(x[0, :3], channels["a_code"][0])
    assert np.isfinite(x).all()
    assert present[:, 0].tolist() == [True, False, True, True]
    assert present[:, 1].tolist() == [True, True, False, True]
    assert report.invalid_frames == {"a_code": 1, "b_code": 1}


def test_wrong_channel_size_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="values per frame"):
        assemble_inputs(_batch(), {"a_code": 4})


def test_empty_batch_gives_empty_inputs() -> None:
    batch = SampleBatch(np.empty(0), {"a_code": np.empty((0, 3)), "b_code": np.empty((0, 2))})
    x, present = assemble_inputs(batch, GROUPS)
    assert x.shape == (0, 5) and present.shape == (0, 2)


def test_window_starts_cover_the_trial_and_end_at_its_end() -> None:
    starts = window_starts(123, 50, 10)
    assert starts[0] == 0 and starts[-1] == 73
    assert np.all(np.diff(starts)[:-1] == 10)
    covered = np.zeros(123, dtype=bool)
    for s in starts:
        covered[s : s + 50] = True
    assert covered.all()
    assert window_starts(100, 50, 5).size == 11  # 0, 5, ..., 50
    assert window_starts(30, 50, 5).tolist() == [0]
    assert window_starts(0, 50, 5).size == 0
    with pytest.raises(ValueError):
        window_starts(10, 0, 1)


def test_split_trials_is_stratified_disjoint_and_seeded() -> None:
    flags = [True] * 6 + [False] * 14
    train, val = split_trials(flags, 0.2, np.random.default_rng(0))
    assert set(train).isdisjoint(val) and len(train) + len(val) == 20
    assert sum(flags[i] for i in val) >= 1 and sum(not flags[i] for i in val) >= 1
    assert sum(flags[i] for i in train) >= 1
    again = split_trials(flags, 0.2, np.random.default_rng(0))
    assert np.array_equal(again[0], train) and np.array_equal(again[1], val)
    train0, val0 = split_trials(flags, 0.0, np.random.default_rng(0))
    assert val0.size == 0 and train0.size == 20
    single_train, single_val = split_trials([True], 0.5, np.random.default_rng(0))
    assert single_train.tolist() == [0] and single_val.size == 0


def test_softmax_rows_is_finite_for_extreme_logits() -> None:
    logits = np.array([[1e30, -1e30], [0.0, 0.0], [np.nan, 1.0], [-800.0, -801.0]])
    p = softmax_rows(logits)
    assert np.isfinite(p).all() and np.allclose(p.sum(axis=1), 1.0)
    assert p[0].tolist() == [1.0, 0.0] and np.allclose(p[1], 0.5)
    assert np.isclose(p[3, 0], 1 / (1 + np.exp(-1.0)))
    assert softmax_rows(np.empty((0, 2))).shape == (0, 2)


def test_sigmoid_pair_is_finite_and_sums_to_one() -> None:
    p = sigmoid_pair(np.array([-1e308, 0.0, 1e308, np.nan, 2.0]))
    assert np.isfinite(p).all() and np.allclose(p.sum(axis=1), 1.0)
    assert p[0].tolist() == [1.0, 0.0] and p[2].tolist() == [0.0, 1.0]
    assert np.allclose(p[1], 0.5) and np.allclose(p[3], 0.5)
    assert np.isclose(p[4, 1], 1 / (1 + np.exp(-2.0)))


def test_rms_scale_keeps_zero_columns_at_unit_scale() -> None:
    x = np.array([[0.0, 3.0, 1e-300], [0.0, -4.0, 0.0]])
    scale = rms_scale(x)
    assert scale[0] == 1.0 and np.isclose(scale[1], np.sqrt(12.5)) and scale[2] == 1.0
    assert rms_scale(np.empty((0, 3))).tolist() == [1.0, 1.0, 1.0]
    grouped = rms_scale(x, [2, 1])
    assert np.allclose(grouped[:2], np.sqrt(25.0 / 4)) and grouped[2] == 1.0
    with pytest.raises(ValueError, match="add up"):
        rms_scale(x, [2, 2])


def test_check_labels_rejects_bad_labels() -> None:
    assert check_labels([0, 1, 1], 3, 2).dtype == np.int64
    with pytest.raises(ValueError, match="shape"):
        check_labels([0, 1], 3, 2)
    with pytest.raises(ValueError, match="integers"):
        check_labels([0, 2, 1], 3, 2)
    with pytest.raises(ValueError, match="integers"):
        check_labels([0, 0.5, 1], 3, 2)
    with pytest.raises(ValueError, match="NaN"):
        check_labels([0, np.nan, 1], 3, 2)


def test_balanced_accuracy_averages_recalls() -> None:
    truth = np.array([0, 0, 0, 0, 1, 1])
    assert balanced_accuracy(truth, np.zeros(6)) == 0.5
    assert balanced_accuracy(truth, truth) == 1.0
    assert np.isclose(balanced_accuracy(truth, [0, 0, 1, 1, 1, 0]), 0.5 * (0.5 + 0.5))
    assert balanced_accuracy([0, 0], [0, 1]) == 0.5
    with pytest.raises(ValueError):
        balanced_accuracy([], [])


def test_contact_figures_reads_misses_false_alarms_and_late_onsets() -> None:
    # Trial 1: contact on frames 3-6, read from frame 5 (2 frames late) to 7 (one false
    # alarm after it). Trial 2: contact on frames 1-2, never read. Trial 3: free, one false
    # alarm. Trial 4: read one frame before contact and through it (onset 0).
    truth = [[0, 0, 0, 1, 1, 1, 1, 0], [0, 1, 1, 0], [0, 0, 0], [0, 1, 1]]
    predicted = [[0, 0, 0, 0, 0, 1, 1, 1], [0, 0, 0, 0], [0, 1, 0], [1, 1, 1]]
    f = contact_figures(truth, predicted)
    assert f["contact_recall"] == pytest.approx(4 / 8)  # frames 5, 6 and both of trial 4
    assert f["free_specificity"] == pytest.approx(7 / 10)  # trial 4 read frame 0 too early
    assert f["balanced_accuracy"] == pytest.approx(0.5 * (0.5 + 0.7))
    assert f["onset_delay_frames"] == 1.0  # median of 2 and 0
    assert f["missed_contacts"] == 1 and f["contact_trials"] == 3
    assert f["trials"] == 4 and f["frames"] == 18


def test_contact_figures_at_the_extremes() -> None:
    # Only free frames: no contact recall and no onset, not a NaN.
    free = contact_figures([np.zeros(5)], [np.zeros(5)])
    assert free["contact_recall"] is None and free["onset_delay_frames"] is None
    assert free["free_specificity"] == 1.0 and free["missed_contacts"] == 0
    # A single contact frame, read at once.
    single = contact_figures([[1]], [[1]])
    assert single["onset_delay_frames"] == 0.0 and single["free_specificity"] is None
    for bad in (([], []), ([[0, 1]], [[0]]), ([[0]], [])):
        with pytest.raises(ValueError):
            contact_figures(*bad)
    with pytest.raises(ValueError):
        contact_figures([np.zeros(0)], [np.zeros(0)])  # no frames to score
