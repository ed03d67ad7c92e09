"""The stall check watches each force stream a classifier consumes (issue 26 §6).

Which streams: the force channels nearest upstream of each classifier (a force observer's
output rather than the sensors it reads; a sensor's own when the classifier reads it). How:
each stream on its own, so that one silent stream halts the robot even while another
force stream goes on.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np

from hapticframe._config import RunSettings
from hapticframe.kinds import ChannelInfo, SampleBatch
from hapticframe.run._dataflow import Dataflow
from hapticframe.run._safety import FORCE_STREAM_STALLED, SafetyMonitor

FORCE = ChannelInfo((3,), "N", 100.0)
ACCEL = ChannelInfo((3,), "m/s^2", 100.0)


def _flow(inputs: dict[str, list[str]], sensors: dict[str, Any],
          extractors: dict[str, Any]) -> Any:
    flow: Any = object.__new__(Dataflow)  # only the stream planning is exercised
    flow.entries = {cid: SimpleNamespace(inputs=ins) for cid, ins in inputs.items()}
    flow.sensors = list(sensors)
    flow.extractors = list(extractors)
    flow.classifiers = [c for c in inputs if c.startswith("clf")]
    flow.components = SimpleNamespace(
        sensors={k: SimpleNamespace(channels=v) for k, v in sensors.items()},
        feature_extractors={k: SimpleNamespace(output_channels=v) for k, v in extractors.items()},
    )
    return flow


def test_the_classifiers_force_is_watched_not_the_sensors_behind_an_observer():
    flow = _flow(
        {"observer": ["wrist", "imu"], "clf": ["observer"], "clf-2": ["other"],
         "features": ["other"], "clf-3": ["features"]},
        {"wrist": {"force_n": FORCE}, "imu": {"accel": ACCEL}, "other": {"f": FORCE}},
        {"observer": {"force_n": FORCE}, "features": {"rms": ChannelInfo((), "1", 100.0)}},
    )
    # The observer's output; the other sensor read directly; a feature extractor without a
    # force channel is looked through to the force it is fed (the same stream, once).
    assert flow._classified_force_streams() == [("observer", "force_n"), ("other", "f")]
    no_force = _flow({"clf": ["imu"]}, {"imu": {"accel": ACCEL}}, {})
    assert no_force._classified_force_streams() == []


class _Robot:
    id = "arm"
    control_rate_hz = 100.0

    def __init__(self) -> None:
        self.state = SimpleNamespace(timestamp_s=0.0)
        self.halted: list[str] = []

    def halt(self, reason: str) -> None:
        self.halted.append(reason)


def _batch(t: float, valid: bool) -> SampleBatch:
    return SampleBatch(np.array([t]), {"f": np.ones((1, 3))}, {"f": np.array([valid])})


def test_one_silent_stream_halts_while_the_other_goes_on():
    flow = _flow({"clf": ["a"], "clf-2": ["b"]}, {"a": {"f": FORCE}, "b": {"f": FORCE}}, {})
    flow.force_sensors = ["a", "b"]
    flow.stall_streams = flow._classified_force_streams()
    flow.stall_counts = [0, 0]
    halts: list[dict[str, Any]] = []
    safety = SafetyMonitor(RunSettings(force_stall_s=0.25, force_limit_n=None), flow, halts)
    robot = _Robot()
    safety.begin(robot, 0)
    reason = ""
    for step in range(1, 100):
        t = step / 100
        robot.state.timestamp_s = t
        outputs = {"a": _batch(t, True), "b": _batch(t, t < 0.3)}  # b goes invalid at 0.3 s
        for k, times in enumerate(flow.stall_arrivals(outputs)):
            flow.stall_counts[k] += len(times)
        reason = safety.after_commit()
        if reason:
            break
    assert reason == FORCE_STREAM_STALLED and robot.halted == [FORCE_STREAM_STALLED]
    assert halts[0]["stream"] == "b/f"
    assert halts[0]["robot_time_s"] - 0.29 <= 0.25 + 0.01 + 1e-9  # within one period


def test_a_look_ahead_batch_with_one_silent_stream_is_replayed():
    flow = _flow({"clf": ["a"], "clf-2": ["b"]}, {"a": {"f": FORCE}, "b": {"f": FORCE}}, {})
    flow.force_sensors = ["a", "b"]
    flow.stall_streams = flow._classified_force_streams()
    flow.stall_counts = [0, 0]
    safety = SafetyMonitor(RunSettings(force_stall_s=0.25, force_limit_n=None), flow, [])
    robot = _Robot()
    safety.begin(robot, 0)
    t = np.arange(1, 41) / 100
    states = [SimpleNamespace(timestamp_s=x) for x in t]
    both = {s: SampleBatch(t, {"f": np.ones((40, 3))}) for s in ("a", "b")}
    assert not safety.batch_needs_replay(states, both)
    one = {"a": both["a"], "b": SampleBatch(t, {"f": np.full((40, 3), np.nan)})}
    assert safety.batch_needs_replay(states, one)


def test_only_valid_finite_samples_count_as_arrivals():
    from hapticframe.run._dataflow import _usable_times

    empty = SampleBatch(np.empty(0), {"f": np.empty((0, 3))})
    assert _usable_times(empty, "f").size == 0
    one = SampleBatch(np.array([0.5]), {"f": np.array([[1e300, -1e300, 0.0]])})
    assert _usable_times(one, "f").tolist() == [0.5]  # huge is still finite
    nan = SampleBatch(np.array([0.5]), {"f": np.array([[0.0, np.nan, 0.0]])})
    assert _usable_times(nan, "f").size == 0
    invalid = SampleBatch(np.array([0.5]), {"f": np.ones((1, 3))}, {"f": np.array([False])})
    assert _usable_times(invalid, "f").size == 0
    t = np.arange(4) / 100
    force = np.array([[1.0, 0, 0], [np.inf, 0, 0], [2.0, 0, 0], [3.0, 0, 0]])
    many = SampleBatch(t, {"f": force}, {"f": np.array([True, True, False, True])})
    assert _usable_times(many, "f").tolist() == [0.0, 0.03]
