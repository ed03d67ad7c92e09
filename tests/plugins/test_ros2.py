"""The ROS 2 plugins: CDR against rosbags, the search over DDS on loopback, bad input."""

from __future__ import annotations

import itertools
import math
import os
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("cyclonedds", reason="the 'ros2' extra (cyclonedds) is not installed")
rosbags_typesys = pytest.importorskip("rosbags.typesys", reason="rosbags is not installed")

from hapticframe_ros2 import _messages as M  # noqa: E402
from hapticframe_ros2._config import QosConfig  # noqa: E402
from hapticframe_ros2._dds import Endpoint, stamp_of  # noqa: E402

from hapticframe import run_experiment, validate_file  # noqa: E402
from hapticframe.devices import DeviceError  # noqa: E402
from hapticframe.kinds import BuildContext  # noqa: E402

EXAMPLE = Path(__file__).parents[2] / "examples" / "search-ros2.yaml"
_DOMAINS = itertools.count()


def fresh_domain() -> int:
    """A DDS domain no other test worker uses at the same time (pid-spread)."""
    return 1 + (os.getpid() * 17 + next(_DOMAINS)) % 200


def _header(sec: int = 12, nsec: int = 345, frame: str = "plate") -> M.Header:
    return M.Header(M.Time(sec, nsec), frame)


SAMPLES = [
    M.Time(7, 999_999_999),
    _header(),
    M.Vector3(1.5, -2.25, 1e300),
    M.Point(0.1, 0.2, -0.3),
    M.Quaternion(0.0, 0.0, 0.5, math.sqrt(0.75)),
    M.Wrench(M.Vector3(1, 2, 3), M.Vector3(-4, 5, -6)),
    M.WrenchStamped(_header(frame="ft_sensor_link"), M.Wrench(M.Vector3(1e-9, 2, 3))),
    M.Pose(M.Point(0.4, 0.2, -0.044), M.Quaternion(0, 0, 0.3, 0.95)),
    M.PoseStamped(_header(frame="world"), M.Pose(M.Point(1, 2, 3))),
    M.Imu(_header(frame=""), M.Quaternion(0.1, 0.2, 0.3, 0.9),
          [float(i) for i in range(9)], M.Vector3(0.01, -0.02, 0.03),
          [-1.0] * 9, M.Vector3(0, 0, 9.81), [float(i) / 7 for i in range(9)]),
    M.Path(_header(frame="world"), [M.PoseStamped(_header(1, 2, "a")),
                                    M.PoseStamped(_header(3, 4, "bb"))]),
    M.Path(_header(frame="world"), []),
]


def test_every_message_type_is_checked():
    assert {type(m) for m in SAMPLES} == set(M.ROS_TYPES)


@pytest.mark.parametrize("message", SAMPLES, ids=lambda m: type(m).__name__)
def test_cdr_equals_rosbags_both_ways(message):
    store = rosbags_typesys.get_typestore(rosbags_typesys.Stores.ROS2_HUMBLE)
    name = M.ROS_TYPES[type(message)]
    ours = message.serialize()
    # rosbags reads our bytes into the same message, and writes the same bytes back.
    theirs = store.deserialize_cdr(ours, name)
    assert store.serialize_cdr(theirs, name) == ours
    # And our side reads what rosbags writes from a message built on its side.
    assert type(message).deserialize(store.serialize_cdr(theirs, name)) == message
    # A message built on rosbags' side from scratch serializes to our bytes.
    if isinstance(message, M.WrenchStamped):
        msg_types = store.types
        built = msg_types[name](
            msg_types["std_msgs/msg/Header"](
                msg_types["builtin_interfaces/msg/Time"](12, 345), "ft_sensor_link"),
            msg_types["geometry_msgs/msg/Wrench"](
                msg_types["geometry_msgs/msg/Vector3"](1e-9, 2.0, 3.0),
                msg_types["geometry_msgs/msg/Vector3"](0.0, 0.0, 0.0)))
        assert store.serialize_cdr(built, name) == ours


def test_a_changed_field_changes_the_bytes():
    a = M.WrenchStamped(_header(), M.Wrench(M.Vector3(1, 2, 3)))
    b = M.WrenchStamped(_header(), M.Wrench(M.Vector3(1, 2, 3.0000001)))
    assert a.serialize() != b.serialize()


def _experiment(tmp_path: Path, domain: int, **robot: object) -> Path:
    data = yaml.safe_load(EXAMPLE.read_text())
    data["robots"][0]["config"] = {"domain_id": domain, **robot}
    data["sensors"][0]["config"]["domain_id"] = domain
    path = tmp_path / "search-ros2.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _in_process(tmp_path: Path) -> Path:
    data = yaml.safe_load(EXAMPLE.read_text())
    data["robots"][0] = {"id": "arm", "type": "sandbox"}
    data["sensors"][0] = {"id": "wrist", "type": "sandbox-force", "inputs": ["arm"]}
    path = tmp_path / "search-inproc.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.slow
def test_search_over_dds_makes_the_in_process_movements(tmp_path):
    from hapticframe_ros2 import rig_for_experiment

    domain = fresh_domain()
    path = _experiment(tmp_path, domain)
    rig = rig_for_experiment(str(path)).start()  # its own DDS participant, in a thread
    try:
        over_dds = run_experiment(validate_file(path), tmp_path / "dds", progress=False)
    finally:
        rig.stop()
    assert rig.error is None
    in_process = run_experiment(validate_file(_in_process(tmp_path)), tmp_path / "inproc",
                                progress=False)
    # The same movements: the first ones bit-identical, later ones within micrometres (the
    # goal's speed travels as a duration in nanoseconds, the heading as a quaternion; their
    # rounding reaches the map and through it the planner's next line).
    dds, local = (np.load(run / "trace.npz") for run in (tmp_path / "dds", tmp_path / "inproc"))
    index = dds["robot/arm/movement_index"]
    np.testing.assert_array_equal(index, local["robot/arm/movement_index"])
    assert index.max() >= 2
    np.testing.assert_allclose(dds["robot/arm/position_m"], local["robot/arm/position_m"],
                               atol=1e-4)
    first = index == 0
    np.testing.assert_array_equal(dds["robot/arm/position_m"][first],
                                  local["robot/arm/position_m"][first])
    np.testing.assert_array_equal(dds["sensor/wrist/force_n"][first][:, :2],
                                  local["sensor/wrist/force_n"][first])
    assert over_dds["object_found"] and in_process["object_found"]
    assert over_dds["movements"] == in_process["movements"] == rig.counts["movements"]
