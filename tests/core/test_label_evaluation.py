"""Scoring a classifier against per-sample labels (``run._evaluate.evaluate_labels``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hapticframe.run._evaluate import evaluate_labels, save_label_figure


def _probabilities(decided: np.ndarray) -> np.ndarray:
    p = np.where(decided, 0.8, 0.2)
    return np.column_stack([1.0 - p, p])


def test_balanced_accuracy_and_event_timing():
    frame = np.arange(100)
    t = 0.01 * (frame + 1)
    labels = ((frame >= 30) & (frame < 70)).astype(float)  # 40 contact frames
    decided = (frame >= 26) & (frame < 72)  # 4 frames early, 2 frames late
    out = evaluate_labels(t, _probabilities(decided), t, labels)
    assert out["contact_frames"] == 100
    free_recall = 1 - 6 / 60  # six of the sixty free frames called contact
    assert out["contact_balanced_accuracy"] == pytest.approx((free_recall + 1.0) / 2)
    assert out["first_contact_error_s"] == pytest.approx(-0.04)
    assert out["last_contact_error_s"] == pytest.approx(0.02)
    assert out["_events"]["true"] == pytest.approx((t[30], t[69]))


def test_outputs_take_the_latest_label_and_skip_what_has_none():
    label_t = np.array([0.10, 0.20, 0.30])
    labels = np.array([0.0, np.nan, 1.0])
    t = np.array([0.05, 0.10, 0.25, 0.35])  # before any label, free, NaN label, contact
    out = evaluate_labels(t, _probabilities(np.array([True, False, True, True])), label_t,
                          labels, name="touch")
    assert out["touch_frames"] == 2 and out["touch_balanced_accuracy"] == 1.0
    assert out["first_touch_error_s"] == 0.0 and out["last_touch_error_s"] == 0.0


def test_extremes_give_none_not_nan():
    empty = evaluate_labels(np.empty(0), np.empty((0, 2)), np.empty(0), np.empty(0))
    assert empty["contact_frames"] == 0 and empty["contact_balanced_accuracy"] is None
    assert empty["first_contact_error_s"] is None
    t = 0.01 * np.arange(1, 11)
    free_only = evaluate_labels(t, _probabilities(np.zeros(10, bool)), t, np.zeros(10))
    assert free_only["contact_balanced_accuracy"] == 1.0  # the one class present
    assert free_only["first_contact_error_s"] is None and free_only["last_contact_error_s"] is None
    missed = evaluate_labels(t, _probabilities(np.zeros(10, bool)), t, np.ones(10))
    assert missed["contact_balanced_accuracy"] == 0.0 and missed["first_contact_error_s"] is None
    for value in (*free_only.values(), *missed.values()):
        assert not (isinstance(value, float) and math.isnan(value))
    with pytest.raises(ValueError, match="shape"):
        evaluate_labels(t, np.ones(10), t, np.zeros(10))


def test_label_figure_is_written(tmp_path):
    t = 0.01 * np.arange(1, 101)
    labels = ((t > 0.3) & (t < 0.7)).astype(float)
    out = evaluate_labels(t, _probabilities(labels > 0), t, labels)
    path = tmp_path / "labels.png"
    save_label_figure(path, t, _probabilities(labels > 0), ("free", "contact"), t, labels,
                      out["_events"])
    assert path.stat().st_size > 1000
