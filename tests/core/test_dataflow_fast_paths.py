"""The closed loop's fast paths give exactly what the general code gives.

Each per-step shortcut of the dataflow (pose lookup at the latest pose, trace rows kept as
Python values, one-sample force tracking, the last label, trusted located measurements,
one-row probability checks) is compared with the array computation it replaces, bit for
bit, on random data and on the edge cases.
"""

from __future__ import annotations

import math
import zipfile

import numpy as np
import pytest

from hapticframe.kinds import ChannelInfo, ClassProbabilities, LocatedMeasurement, SampleBatch
from hapticframe.run._dataflow import Dataflow, _last_label
from hapticframe.run._streams import PoseHistory, TraceRecorder


class ReferencePoses:
    """The pose history as it was before the fast path: every query through ``np.interp``."""

    def __init__(self) -> None:
        self.t: list[float] = []
        self.pose: list[tuple[float, float, float, float]] = []

    def add(self, t: float, xy, heading: float, depth: float) -> None:
        if self.t and t <= self.t[-1]:
            return
        heading = np.float64(heading)
        if self.t:
            previous = np.float64(self.pose[-1][2])
            heading = previous + (heading - previous + np.pi) % (2 * np.pi) - np.pi
        x, y = np.asarray(xy, dtype=np.float64)
        self.t.append(t)
        self.pose.append((x, y, heading, depth))

    def at(self, times):
        t = np.array(self.t)
        pose = np.array(self.pose, dtype=np.float64)
        x, y, heading = (np.interp(times, t, pose[:, k]) for k in range(3))
        if np.all(np.isfinite(pose[:, 3])):
            depth = np.interp(times, t, pose[:, 3])
        else:
            depth = np.full(len(times), np.nan)
        return np.column_stack([x, y]), heading, depth


def assert_same(ours, reference) -> None:
    for a, b in zip(ours, reference, strict=True):
        assert a.dtype == b.dtype and a.shape == b.shape
        np.testing.assert_array_equal(a, b)  # NaN equals NaN here, bit-exact otherwise


def random_walk(rng: np.random.Generator, n: int, nan_depth_at: int | None = None):
    t = np.cumsum(rng.uniform(0.005, 0.02, n))
    t[rng.choice(n, size=n // 10, replace=False)] -= 0.03  # stale and repeated times
    xy = rng.normal(0.0, 0.3, (n, 2))
    heading = rng.uniform(-3 * np.pi, 3 * np.pi, n)  # wraps many times
    heading[::7] = np.pi  # exactly on the cut
    heading[3::7] = -np.pi
    depth = rng.uniform(0.0, 0.05, n)
    if nan_depth_at is not None:
        depth[nan_depth_at] = np.nan
    return t, xy, heading, depth


@pytest.mark.parametrize("seed", range(2))
@pytest.mark.parametrize("nan_depth", [False, True])
def test_pose_lookup_equals_interpolation(seed: int, nan_depth: bool) -> None:
    rng = np.random.default_rng(seed)
    n = 400  # grows the storage past its first 256 rows
    t, xy, heading, depth = random_walk(rng, n, nan_depth_at=n // 2 if nan_depth else None)
    ours, reference = PoseHistory(), ReferencePoses()
    for i in range(n):
        ours.add(t[i], xy[i], heading[i], depth[i])
        reference.add(t[i], xy[i], heading[i], depth[i])
        latest = reference.t[-1]
        queries = [
            np.array([latest]),  # the closed loop's query: the latest pose
            np.array([latest + 0.5]),  # after it
            np.array([reference.t[0] - 1.0]),  # before the first pose
            np.array([rng.uniform(reference.t[0], latest)]),  # between poses
            np.sort(rng.uniform(reference.t[0] - 0.1, latest + 0.1, 5)),
            np.array([reference.t[0], reference.t[0]]),  # a repeated time
            np.empty(0),
        ]
        for times in queries if i % 5 == 0 else queries[:2]:
            assert_same(ours.at(times), reference.at(times))
    assert len(ours) == len(reference.t)


def test_pose_lookup_of_a_single_pose_and_of_none() -> None:
    poses = PoseHistory()
    with pytest.raises(Exception, match="none were recorded"):
        poses.at(np.array([0.0]))
    poses.add(1.0, (0.2, 0.3), 3.0, 0.01)
    poses.add(1.0, (9.0, 9.0), 0.0, 0.0)  # repeated time: ignored
    reference = ReferencePoses()
    reference.add(1.0, (0.2, 0.3), 3.0, 0.01)
    for times in (np.array([0.5]), np.array([1.0]), np.array([2.0]), np.array([0.5, 1.0, 2.0])):
        assert_same(poses.at(times), reference.at(times))


def test_pose_batches_follow_the_same_rules() -> None:
    rng = np.random.default_rng(7)
    t, xy, _, _ = random_walk(rng, 50)
    t = np.sort(np.unique(t))
    xy = xy[: t.size]
    ours, reference = PoseHistory(), ReferencePoses()
    ours.add_batch(SampleBatch(t, {"position_m": xy}))
    steps = np.diff(np.vstack([xy[:1], xy]), axis=0)
    for i, angle in enumerate(np.arctan2(steps[:, 1], steps[:, 0])):
        reference.add(t[i], xy[i], angle, np.nan)
    queries = np.concatenate([t, t + 0.001, [t[0] - 1, t[-1] + 1]])
    assert_same(ours.at(np.sort(queries)), reference.at(np.sort(queries)))
    assert_same(ours.at(t[-1:]), reference.at(t[-1:]))


def test_trace_rows_equal_one_array_per_row(tmp_path) -> None:
    rng = np.random.default_rng(3)
    rows, arrays = TraceRecorder(), TraceRecorder()
    for step in range(40):
        position = rng.normal(size=2)
        for recorder, as_row in ((rows, True), (arrays, False)):
            if as_row:
                recorder.add_row("t", float(step) / 100)
                recorder.add_row("position", position.tolist())
                recorder.add_row("index", step // 7)
            else:
                recorder.add("t", np.array([float(step) / 100]))
                recorder.add("position", position[None, :])
                recorder.add("index", np.array([step // 7]))
            # Arrays under the same key between rows keep their order.
            if step % 9 == 0:
                recorder.add("t", np.array([-1.0, -2.0]))
            recorder.add("force", rng.normal(size=(1, 2)) if as_row else np.zeros((1, 2)))
    rows.set("unit", np.array("N"))
    arrays.set("unit", np.array("N"))
    ours, reference = rows.arrays(), arrays.arrays()
    assert list(ours) == list(reference)
    for key in ("t", "position", "index", "unit"):
        assert ours[key].dtype == reference[key].dtype
        np.testing.assert_array_equal(ours[key], reference[key])
    # Reading again gives the same arrays, and rows added after a read join them in order.
    again = rows.arrays()
    assert all(np.array_equal(again[k], ours[k]) for k in ours)
    rows.add_row("t", 9.0)
    rows.add("t", np.array([10.0]))
    grown = rows.arrays()["t"]
    assert grown.dtype == ours["t"].dtype
    np.testing.assert_array_equal(grown, np.concatenate([ours["t"], [9.0, 10.0]]))
    rows, ours["t"] = TraceRecorder(), grown
    for key, value in ours.items():
        rows.set(key, value) if key == "unit" else rows.add(key, value)
    # Saved at another compression level, the file still loads as the same arrays.
    rows.save(str(tmp_path / "trace"))
    with np.load(tmp_path / "trace.npz") as loaded:
        assert list(loaded.files) == list(ours)
        for key in ours:
            np.testing.assert_array_equal(loaded[key], ours[key])
    with zipfile.ZipFile(tmp_path / "trace.npz") as archive:
        assert all(i.compress_type == zipfile.ZIP_DEFLATED for i in archive.infolist())


class _ForceSensor:
    def __init__(self, shape: tuple[int, ...]) -> None:
        self.channels = {"f": ChannelInfo(shape, "N", 100.0), "p": ChannelInfo((), "Pa", 100.0)}


def _tracker() -> Dataflow:
    flow = object.__new__(Dataflow)  # only the force bookkeeping is exercised
    flow.force_max_n = float("nan")
    return flow


@pytest.mark.parametrize("shape", [(), (1,), (2,)])
def test_one_sample_force_tracking_equals_the_norm(shape) -> None:
    rng = np.random.default_rng(11)
    width = int(np.prod(shape))
    values = rng.normal(0.0, 10.0, (300, width)) * 10.0 ** rng.integers(-200, 200, (300, 1))
    values[5] = np.nan
    values[6] = np.inf
    values[7] = -0.0
    values[8] = 1e300  # the square overflows: an infinite norm is not counted
    flow, sensor = _tracker(), _ForceSensor(shape)
    expected = float("nan")
    for k, row in enumerate(values):
        sample = row.reshape((1, *shape))
        flow._track_force(sensor, SampleBatch(np.array([k / 100]), {"f": sample, "p": row[:1]}))
        with np.errstate(over="ignore"):
            norms = np.linalg.norm(sample.reshape(1, -1), axis=1)
        finite = norms[np.isfinite(norms)]
        if finite.size:
            expected = float(np.fmax(expected, finite.max()))
        both_nan = math.isnan(expected) and math.isnan(flow.force_max_n)
        assert flow.force_max_n == expected or both_nan
    assert math.isfinite(flow.force_max_n)


def test_last_label_is_the_argmax_of_the_last_row() -> None:
    classes = ("free", "jamming", "contact")
    rows = np.array([
        [0.2, 0.3, 0.5], [0.4, 0.4, 0.2], [0.3, 0.35, 0.35], [1 / 3, 1 / 3, 1 / 3],
        [1.0, 0.0, 0.0], [0.0, 0.0, 1.0],
    ])
    for k in range(len(rows)):
        probs = ClassProbabilities(np.arange(k + 1, dtype=float), rows[: k + 1], classes)
        assert _last_label(probs) == int(probs.labels[-1])


def test_trusted_located_measurement_equals_the_checked_one() -> None:
    rng = np.random.default_rng(5)
    p = rng.dirichlet(np.ones(3), 4)
    probs = ClassProbabilities(np.arange(4.0), p, ("free", "jamming", "contact"))
    positions, headings, depth = rng.normal(size=(4, 2)), rng.normal(size=4), rng.normal(size=4)
    checked = LocatedMeasurement(probs.timestamps_s, positions, headings, p, probs.classes, depth)
    trusted = LocatedMeasurement._from_checked(
        probs, positions.copy(), headings.copy(), depth.copy()
    )
    for name in ("timestamps_s", "positions_m", "headings_rad", "depth_m", "probabilities"):
        ours, theirs = getattr(trusted, name), getattr(checked, name)
        assert ours.dtype == theirs.dtype and ours.shape == theirs.shape
        np.testing.assert_array_equal(ours, theirs)
        assert not ours.flags.writeable
    assert trusted.classes == checked.classes and len(trusted) == 4


ROWS = [
    [0.2, 0.3, 0.5],
    [1.0, 0.0, 0.0],
    [0.5, 0.5 + 4e-7, -4e-7],  # slightly negative
    [0.3, 0.3, 0.4 + 9e-7],  # within the sum tolerance
    [0.3, 0.3, 0.4 + 1.1e-6],  # outside it
    [0.3, 0.3, 0.4 + 1e-6],  # on it
    [np.nan, 0.5, 0.5],
    [np.inf, 0.0, 0.0],
    [1.5, -0.5, 0.0],
    [1e308, 1e308, -1e308],
    [-0.0, 1.0, 0.0],
]


@pytest.mark.parametrize("row", ROWS)
def test_one_row_probability_checks_decide_as_the_array_checks(row) -> None:
    classes = ("a", "b", "c")

    def outcome(p: np.ndarray) -> str:
        try:
            ClassProbabilities(np.arange(float(len(p))), p, classes)
        except ValueError as exc:
            return str(exc)
        return "ok"

    # Two copies of the row take the array checks; one row takes the fast path.
    assert outcome(np.array([row])) == outcome(np.array([row, row]))


def test_one_sample_batches_keep_their_checks() -> None:
    with pytest.raises(ValueError, match="finite"):
        SampleBatch(np.array([np.nan]), {"f": np.zeros((1, 2))})
    with pytest.raises(ValueError, match="finite"):
        SampleBatch(np.array([np.inf]), {})
    with pytest.raises(ValueError, match="has 2 rows, expected 1"):
        SampleBatch(np.array([0.0]), {"f": np.zeros((2, 2))})
    with pytest.raises(ValueError, match="sample axis"):
        SampleBatch(np.array([0.0]), {"f": np.float64(1.0)})
    batch = SampleBatch(np.array([0.0]), {"f": [[1, 2]]})
    assert batch.channels["f"].dtype == np.float64 and not batch.channels["f"].flags.writeable
