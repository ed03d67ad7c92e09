"""ROS 2 without a ROS install: the ``ros2-topic`` sensor and the ``ros2`` robot over DDS.

Registers the sensor ``ros2-topic`` (``geometry_msgs/WrenchStamped`` or ``sensor_msgs/Imu``
from a topic) and the robot ``ros2`` (movements as a Path goal and PoseStamped setpoints, the
plate's pose read back). Only the implementations import Cyclone DDS (the ``ros2`` extra);
this package and its configs do not, so listing and validation work without it.
``python -m hapticframe_ros2.rig EXPERIMENT`` serves the emulated rig. docs/ros2.md.
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import QosConfig, Ros2RobotConfig, Ros2TopicSensorConfig, dds_topic_name

__all__ = [
    "POSE_STALE",
    "EmulatedRig",
    "QosConfig",
    "Ros2Robot",
    "Ros2RobotConfig",
    "Ros2TopicSensor",
    "Ros2TopicSensorConfig",
    "dds_topic_name",
    "rig_for_experiment",
]

_LAZY = {
    "EmulatedRig": "._rig",
    "POSE_STALE": "._robot",
    "Ros2Robot": "._robot",
    "Ros2TopicSensor": "._sensor",
    "rig_for_experiment": ".rig",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
