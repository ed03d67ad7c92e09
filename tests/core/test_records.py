"""Records reject malformed data where it is produced."""

import numpy as np
import pytest

from hapticframe.kinds import (
    ClassProbabilities,
    ExploratoryMovement,
    LocatedMeasurement,
    MapEstimate,
    Observations,
    Region,
    SampleBatch,
    concatenate_batches,
)


def test_sample_batch_requires_increasing_time_and_matching_rows():
    SampleBatch([0.0, 0.01], {"f": np.zeros((2, 3))})
    with pytest.raises(ValueError, match="strictly increasing"):
        SampleBatch([0.0, 0.0], {"f": np.zeros((2, 3))})
    with pytest.raises(ValueError, match="rows"):
        SampleBatch([0.0, 0.01], {"f": np.zeros((3, 3))})
    with pytest.raises(ValueError, match="finite"):
        SampleBatch([0.0, np.inf], {})


def test_sample_batch_is_read_only_float64():
    batch = SampleBatch([0.0, 1.0], {"f": np.array([[1], [2]], dtype=np.int32)})
    assert batch.channels["f"].dtype == np.float64
    with pytest.raises(ValueError):
        batch.channels["f"][0, 0] = 5.0


def test_concatenate_keeps_validity():
    a = SampleBatch([0.0], {"f": [[1.0]]}, {"f": [False]})
    b = SampleBatch([1.0], {"f": [[2.0]]})
    joined = concatenate_batches([a, b])
    assert joined.valid["f"].tolist() == [False, True]
    with pytest.raises(ValueError, match="channel sets differ"):
        concatenate_batches([a, SampleBatch([2.0], {"g": [[1.0]]})])


@pytest.mark.parametrize(
    "probs, message",
    [
        ([[0.5, np.nan]], "NaN"),
        ([[1.2, -0.2]], r"\[0, 1\]"),
        ([[0.5, 0.6]], "sum to 1"),
        ([[1.0]], "columns"),
    ],
)
def test_class_probabilities_rejects_invalid(probs, message):
    with pytest.raises(ValueError, match=message):
        ClassProbabilities([0.0], probs, ("free", "contact"))


def test_located_measurement_shapes():
    m = LocatedMeasurement([0.0, 1.0], [[0, 0], [1, 1]], [0, 0], [[1, 0], [0, 1]], ("a", "b"))
    assert np.all(np.isnan(m.depth_m)) and len(m.select(slice(1, 2))) == 1
    with pytest.raises(ValueError, match="positions_m"):
        LocatedMeasurement([0.0], [[0, 0, 0]], [0], [[1, 0]], ("a", "b"))


def test_observations_and_estimates_reject_nan_and_ranges():
    with pytest.raises(ValueError, match="NaN"):
        Observations([[np.nan, 0.0]], [0.5])
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        Observations([[0.0, 0.0]], [1.5])
    with pytest.raises(ValueError, match="NaN"):
        MapEstimate([np.nan], [0.1])
    with pytest.raises(ValueError, match="std"):
        MapEstimate([0.5], [-0.1])
    assert len(Observations.concatenate([])) == 0


def test_region_and_movement():
    region = Region(0, 2, 0, 1)
    assert region.contains([[1, 0.5], [3, 0.5]]).tolist() == [True, False]
    xs, ys = region.grid(0.5)
    assert len(xs) == 4 and len(ys) == 2
    with pytest.raises(ValueError):
        Region(0, 0, 0, 1)
    move = ExploratoryMovement((0, 0), (3, 4))
    assert move.length_m == pytest.approx(5.0)
    with pytest.raises(ValueError):
        ExploratoryMovement((0, 0), (np.nan, 1))


def test_records_own_their_arrays_a_callers_later_change_cannot_reach_them():
    t = np.array([0.0, 1.0])
    p = np.array([[0.9, 0.1], [0.2, 0.8]])
    probs = ClassProbabilities(t, p, ("free", "contact"))
    p[0] = [5.0, -4.0]  # the caller reuses its buffer
    t[1] = -1.0
    assert probs.probabilities[0].tolist() == [0.9, 0.1] and probs.timestamps_s[1] == 1.0
    force = np.ones((2, 2))
    valid = np.array([True, True])
    batch = SampleBatch(np.array([0.0, 1.0]), {"force_n": force}, {"force_n": valid})
    force[:] = np.nan
    valid[0] = False
    assert np.isfinite(batch.channels["force_n"]).all() and batch.valid["force_n"].all()
    points = np.zeros((1, 2))
    obs = Observations(points, np.array([1.0]))
    points[0] = [np.nan, 3.0]
    assert obs.points_m.tolist() == [[0.0, 0.0]]
    with pytest.raises(ValueError):
        probs.probabilities[0, 0] = 0.5  # and they stay read-only


def test_records_hand_read_only_arrays_on_without_copying():
    batch = SampleBatch(np.array([0.0, 1.0]), {"force_n": np.ones((2, 2))})
    again = SampleBatch(batch.timestamps_s, dict(batch.channels))
    assert again.channels["force_n"] is batch.channels["force_n"]
    assert again.timestamps_s is batch.timestamps_s
