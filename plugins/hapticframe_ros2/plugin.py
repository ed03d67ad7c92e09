"""Registration of the ROS 2 sensor and robot (import-light: no cyclonedds here)."""

from __future__ import annotations

import os
from collections.abc import Iterator

from hapticframe import Kind, RobotSpec, SensorSpec, hookimpl

from ._config import Ros2RobotConfig, Ros2TopicSensorConfig

__all__ = ["hapticframe_robots", "hapticframe_sensors"]

_HINT = "pip install 'hapticframe[ros2]' (cyclonedds)"
# The kit's checks run against the emulated rig, on a domain of their own, under topics of
# this process alone: parallel test workers (pytest-xdist) each run a rig on the same domain,
# and DDS matches topics by name, so a shared name would cross their streams.
_CHECK_DOMAIN = 231
_CHECK_PREFIX = f"/hapticframe_check_{os.getpid()}"
_CHECK_TOPICS = {name: f"{_CHECK_PREFIX}/{name.removesuffix('_topic')}"
                 for name in ("goal_topic", "setpoint_topic", "pose_topic", "wrench_topic")}


@hookimpl
def hapticframe_sensors() -> Iterator[SensorSpec]:
    yield SensorSpec(
        name="ros2-topic",
        summary="A ROS 2 topic (geometry_msgs/WrenchStamped or sensor_msgs/Imu) over DDS, "
        "without a ROS install: stamps from the headers, late, dropped and out-of-order "
        "samples counted.",
        config=Ros2TopicSensorConfig,
        factory="hapticframe_ros2._sensor:Ros2TopicSensor",
        capabilities=frozenset({"hardware"}),
        install_hint=_HINT,
        inputs=(Kind.ROBOT,),
        check_config={"topic": _CHECK_TOPICS["wrench_topic"], "domain_id": _CHECK_DOMAIN,
                      "robot_sync_timeout_s": 1.0},
        check_inputs=("robot/ros2",),
    )


@hookimpl
def hapticframe_robots() -> Iterator[RobotSpec]:
    yield RobotSpec(
        name="ros2",
        summary="A ros2_control rig over DDS: each movement a Path goal and a PoseStamped "
        "setpoint per control period, the plate's pose read back, a stop on halt; 'rig: "
        "emulated' serves the sandbox behind the topics.",
        config=Ros2RobotConfig,
        factory="hapticframe_ros2._robot:Ros2Robot",
        capabilities=frozenset({"hardware"}),
        install_hint=_HINT,
        check_config={"rig": "emulated", "domain_id": _CHECK_DOMAIN, **_CHECK_TOPICS},
    )
