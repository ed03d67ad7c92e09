"""``import-bag`` on a real bag: a Jackal's IMU (robot_localization's ``test2.bag``, BSD).

The recording's values and times are checked against an independent read of the same bag
with rosbags' ROS 1 reader and its own message definitions (issue 28 §4). The fixture and
its licence are in ``tests/data/imu-robot-localization/``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hapticframe.cli._cli import main
from hapticframe.record._recording import read_recording

pytest.importorskip("rosbags")

BAG = Path(__file__).resolve().parents[1] / "data" / "imu-robot-localization" / "test2.bag"


def _independent_read() -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Header stamps (ns) and the Imu fields, straight from rosbags, in bag order."""
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    stamps, fields, covariance_unset = [], {"gyro": [], "acc": [], "q": []}, {"q": [], "acc": [],
                                                                             "gyro": []}
    with Reader(BAG) as reader:
        connections = [c for c in reader.connections if c.topic == "/imu/data"]
        for connection, _, raw in reader.messages(connections=connections):
            msg = store.deserialize_ros1(raw, connection.msgtype)
            stamps.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
            w = msg.angular_velocity
            a = msg.linear_acceleration
            o = msg.orientation
            fields["gyro"].append([w.x, w.y, w.z])
            fields["acc"].append([a.x, a.y, a.z])
            fields["q"].append([o.w, o.x, o.y, o.z])
            covariance_unset["gyro"].append(msg.angular_velocity_covariance[0] == -1)
            covariance_unset["acc"].append(msg.linear_acceleration_covariance[0] == -1)
            covariance_unset["q"].append(msg.orientation_covariance[0] == -1)
    return (np.array(stamps, dtype=np.int64),
            {k: np.array(v, dtype=float) for k, v in fields.items()},
            {k: np.array(v, dtype=bool) for k, v in covariance_unset.items()})


def test_the_real_jackal_imu_bag_imports_with_its_values_and_times(tmp_path: Path) -> None:
    out = tmp_path / "imported"
    assert main(["import-bag", str(BAG), "--map", "/imu/data=imu", "--out", str(out)]) == 0
    stamps, fields, unset = _independent_read()
    assert stamps.size == 3061
    order = np.argsort(stamps, kind="stable")
    keep = np.ones(stamps.size, dtype=bool)
    keep[1:] = np.diff(stamps[order]) != 0  # a repeated stamp is dropped (and counted)
    rows = order[keep]
    start = int(stamps.min())

    messages = read_recording(out / "run.mcap")["/sensor/imu"]
    t = np.concatenate([np.array(d["timestamps_s"], dtype=float) for _, d in messages])
    np.testing.assert_array_equal(t, (stamps[rows] - start) / 1e9)

    def channel(name: str) -> np.ndarray:
        return np.concatenate([np.array(d["channels"][name], dtype=float) for _, d in messages])

    np.testing.assert_array_equal(channel("angular_velocity_rad_per_s"), fields["gyro"][rows])
    np.testing.assert_array_equal(channel("acceleration_m_per_s2"), fields["acc"][rows])
    np.testing.assert_array_equal(channel("orientation_wxyz"), fields["q"][rows])
    # A field the IMU did not estimate (covariance[0] == -1) is invalid, sample by sample.
    for name, key in (("orientation_wxyz", "q"), ("acceleration_m_per_s2", "acc"),
                      ("angular_velocity_rad_per_s", "gyro")):
        flags = [d.get("valid", {}).get(name) for _, d in messages]
        valid = np.concatenate([np.array(f if f is not None else [True] * len(d["timestamps_s"]),
                                         dtype=bool) for f, (_, d) in zip(flags, messages,
                                                                          strict=True)])
        np.testing.assert_array_equal(valid, ~unset[key][rows])
    # A real 50 Hz stream: its median period, and the recording's start on the bag's clock.
    assert np.median(np.diff(t)) == pytest.approx(0.02, abs=1e-3)
    record = json.loads((out / "import.json").read_text())
    assert record["start_time_ns"] == start
    assert record["sensors"]["imu"]["samples"] == int(keep.sum())
