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

from hapticframe import run_experiment, validate_file  # noqa: E402
from hapticframe.devices import DeviceError  # noqa: E402
from hapticframe.kinds import BuildContext  # noqa: E402
from hapticframe_ros2 import _messages as M  # noqa: E402
from hapticframe_ros2._config import QosConfig  # noqa: E402
from hapticframe_ros2._dds import Endpoint, stamp_of  # noqa: E402

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


def _sensor(domain: int, **config: object):
    from hapticframe_ros2 import Ros2TopicSensor, Ros2TopicSensorConfig

    cfg = Ros2TopicSensorConfig.model_validate(
        {"topic": "/ft/wrench", "domain_id": domain, "connect_timeout_s": 2.0, **config})
    return Ros2TopicSensor(cfg, BuildContext("wrist", np.random.default_rng(0)))


def _wrench(t: float, fx: float = 1.0) -> M.WrenchStamped:
    return M.WrenchStamped(M.Header(M.Time(*stamp_of(t)), "ft"),
                           M.Wrench(M.Vector3(fx, 2.0, 3.0)))


def _read_until(sensor, n: int, timeout_s: float = 2.0):
    batches, got, deadline = [], 0, time.monotonic() + timeout_s
    while got < n and time.monotonic() < deadline:
        batch = sensor.read()
        batches.append(batch)
        got += len(batch)
        time.sleep(0.005)
    return batches


def test_sensor_checks_every_sample():
    domain = fresh_domain()
    peer = Endpoint(domain)
    writer = peer.writer("/ft/wrench", M.WrenchStamped, QosConfig())
    sensor = _sensor(domain, rate_hz=100.0)
    try:
        sensor.configure()
        sensor.activate()
        # In order, a gap of 3 lost samples, one out of order, one non-finite.
        for t, fx in [(1.00, 1.0), (1.01, 1.0), (1.05, 1.0), (1.02, 9.0), (1.06, math.nan)]:
            writer.write(_wrench(t, fx))
        batches = _read_until(sensor, 4)
        times = np.concatenate([b.timestamps_s for b in batches])
        force = np.concatenate([b.channels["force_n"] for b in batches])
        valid = np.concatenate([b.valid["force_n"] for b in batches])
        np.testing.assert_allclose(times, [1.00, 1.01, 1.05, 1.06])
        assert 9.0 not in force[:, 0]  # the out-of-order sample is never delivered
        assert valid.tolist() == [True, True, True, False]
        health = sensor.health
        assert health.out_of_order == 1
        assert health.dropped_samples == 3
        assert health.invalid_samples == 1
        # A clock that jumps ahead stops the run with a message, delivering nothing.
        writer.write(_wrench(5000.0))
        with pytest.raises(DeviceError, match="jumped forward"):
            _read_until(sensor, 1)
    finally:
        sensor.close()
        peer.close()


def test_sensor_counts_a_topic_that_disappears_as_a_stall():
    domain = fresh_domain()
    peer = Endpoint(domain)
    writer = peer.writer("/ft/wrench", M.WrenchStamped, QosConfig())
    sensor = _sensor(domain, stall_s=0.05)
    try:
        sensor.configure()
        sensor.activate()
        writer.write(_wrench(1.0))
        assert len(np.concatenate([b.timestamps_s for b in _read_until(sensor, 1)])) == 1
        del writer
        peer.close()  # the publisher leaves the domain
        time.sleep(0.2)
        assert len(sensor.read()) == 0
        assert sensor.health.stalls == 1
    finally:
        sensor.close()


def test_sensor_refuses_a_topic_of_another_type():
    domain = fresh_domain()
    peer = Endpoint(domain)
    _imu_writer = peer.writer("/ft/wrench", M.Imu, QosConfig())  # Imu where a wrench is meant
    sensor = _sensor(domain, connect_timeout_s=0.5)
    try:
        sensor.configure()
        with pytest.raises(DeviceError, match="another type"):
            sensor.activate()
    finally:
        sensor.close()
        peer.close()


def test_robot_refuses_to_move_on_a_stale_pose_stream(tmp_path):
    from hapticframe.kinds import ExploratoryMovement
    from hapticframe_ros2 import Ros2Robot, Ros2RobotConfig

    domain = fresh_domain()
    peer = Endpoint(domain)
    poses = peer.writer("/hapticframe/plate_pose", M.PoseStamped, QosConfig())
    cfg = Ros2RobotConfig.model_validate({"domain_id": domain, "pose_timeout_s": 0.1,
                                          "connect_timeout_s": 2.0})
    robot = Ros2Robot(cfg, BuildContext("arm", np.random.default_rng(0)))
    try:
        robot.configure()
        poses.write(M.PoseStamped(M.Header(M.Time(0, 0), "world"),
                                  M.Pose(M.Point(0.1, 0.1, -0.044))))
        robot.activate()
        time.sleep(0.3)  # the rig falls silent
        with pytest.raises(DeviceError, match="stale"):
            robot.begin(ExploratoryMovement(np.array([0.1, 0.1]), np.array([0.2, 0.1])))
    finally:
        robot.close()
        peer.close()


def test_validate_and_listing_need_no_cyclonedds():
    import subprocess
    import sys

    code = (
        "import sys; sys.modules['cyclonedds'] = None\n"
        "from hapticframe import validate_file\n"
        f"validate_file({str(EXAMPLE)!r})\n"
        "assert 'cyclonedds.domain' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


def test_run_without_the_extra_says_what_to_install(tmp_path):
    import subprocess
    import sys

    hf = shutil.which("hapticframe", path=str(Path(sys.executable).parent))
    assert hf is not None
    code = (
        "import sys; sys.modules['cyclonedds'] = None; sys.modules['cyclonedds.domain'] = None\n"
        "from hapticframe.cli import main\n"
        f"sys.exit(main(['run', {str(EXAMPLE)!r}, '--out', {str(tmp_path / 'x')!r}]))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2, done.stderr
    assert "hapticframe[ros2]" in done.stderr
    assert "Traceback" not in done.stderr
