"""Config models of the ROS 2 sensor and robot (import-light: pydantic and hapticframe only).

Nothing here imports Cyclone DDS, so ``hapticframe validate`` and ``hapticframe plugins`` work
without the ``ros2`` extra; the implementations import it when they are built.
"""

from __future__ import annotations

import re
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from hapticframe import PluginConfig

__all__ = [
    "DDS_DOMAIN_MAX",
    "EMULATED_RIG",
    "MESSAGE_TYPES",
    "QosConfig",
    "Ros2RobotConfig",
    "Ros2TopicSensorConfig",
    "dds_topic_name",
]

#: The largest DDS domain id a participant can join (DDS-RTPS port mapping, 232).
DDS_DOMAIN_MAX = 232
#: The ``rig`` setting that starts the emulated rig (the sandbox behind topics) in-process.
EMULATED_RIG = "emulated"
#: The message types the ``ros2-topic`` sensor subscribes to.
MESSAGE_TYPES = ("geometry_msgs/msg/WrenchStamped", "sensor_msgs/msg/Imu")

# A ROS 2 topic name, fully qualified: /name/space/topic (letters, digits, underscores).
_TOPIC = re.compile(r"^(/[A-Za-z][A-Za-z0-9_]*)+$")


def dds_topic_name(topic: str) -> str:
    """The DDS topic a ROS 2 topic travels on: ``/wrench`` → ``rt/wrench``."""
    return "rt" + topic


def _checked_topic(value: str) -> str:
    if not _TOPIC.match(value) or "__" in value:
        raise ValueError(
            f"{value!r} is not a fully qualified ROS 2 topic name: '/' then letters, digits "
            "and underscores, each segment starting with a letter (e.g. '/ft_sensor/wrench')"
        )
    return value


class QosConfig(BaseModel):
    """The QoS of a topic, as a ROS 2 node states it (``rclpy.qos.QoSProfile``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    reliability: Literal["reliable", "best_effort"] = Field(
        "reliable", description="'reliable' (ROS 2's default) or 'best_effort' (the sensor "
        "data profile); a reliable reader does not match a best-effort writer.")
    history_depth: int = Field(
        100, ge=1, le=100_000, description="Samples kept per topic (history KEEP_LAST).")
    durability: Literal["volatile", "transient_local"] = Field(
        "volatile", description="'volatile' (ROS 2's default) or 'transient_local' (late "
        "joiners get the last samples).")


class _DdsConfig(PluginConfig):
    domain_id: int = Field(
        0, ge=0, le=DDS_DOMAIN_MAX,
        description="The DDS domain (ROS_DOMAIN_ID of the ROS 2 nodes to talk to).")


class Ros2TopicSensorConfig(_DdsConfig):
    """A sensor that subscribes to one ROS 2 topic over DDS, without a ROS 2 install.

    ``geometry_msgs/msg/WrenchStamped`` gives ``force_n (3,)`` N and ``torque_nm (3,)`` N·m;
    ``sensor_msgs/msg/Imu`` gives ``orientation (4,)`` (x, y, z, w),
    ``angular_velocity_rad_per_s (3,)`` and ``linear_acceleration_m_per_s2 (3,)``. Every
    sample is stamped from its header; a sample not after the last one delivered is dropped
    and counted out of order, a stamp that jumps forward by more than ``max_clock_jump_s``
    stops the run (DeviceError), a non-finite value is delivered marked invalid.
    """

    topic: str = Field(..., description="The ROS 2 topic, fully qualified ('/wrench').")
    message: Literal["geometry_msgs/msg/WrenchStamped", "sensor_msgs/msg/Imu"] = Field(
        "geometry_msgs/msg/WrenchStamped", description="The topic's message type.")
    qos: QosConfig = Field(default_factory=QosConfig, description="The topic's QoS.")
    rate_hz: float = Field(
        100.0, gt=0, le=100_000,
        description="The publisher's rate: a gap of more than 1.5 periods between stamps "
        "counts the missing samples as dropped.")
    late_after_s: float | None = Field(
        None, gt=0, le=3600,
        description="A sample received more than this after its stamp counts late (stamps "
        "on this host's clock only: None for a rig in simulation time).")
    max_clock_jump_s: float = Field(
        1.0, gt=0, le=86_400,
        description="A stamp this far after the previous one is a clock jump: DeviceError.")
    stall_s: float = Field(
        0.25, gt=0, le=3600,
        description="No sample for this long (host time) counts a stall in health; the run's "
        "run.force_stall_s halts the robot.")
    connect_timeout_s: float = Field(
        10.0, gt=0, le=600,
        description="activate() waits this long for the first sample (DeviceError after).")
    robot_sync_timeout_s: float | None = Field(
        None, gt=0, le=60,
        description="With a robot in inputs: each read waits up to this long for the sample "
        "of the robot's latest step (a lockstep rig, such as the emulated one); None never "
        "waits (a live rig).")

    _topic = field_validator("topic")(classmethod(lambda cls, v: _checked_topic(v)))


class Ros2RobotConfig(_DdsConfig):
    """A ros2_control rig that follows Cartesian pose setpoints, over DDS.

    Each exploratory movement is published as a ``nav_msgs/msg/Path`` goal (its start and end
    pose, timed by its speed), then one ``geometry_msgs/msg/PoseStamped`` setpoint per control
    period along the line: what a Cartesian pose controller (cartesian_controllers'
    ``target_frame``, MoveIt Servo's pose tracking) follows. The plate's measured pose comes
    back on ``pose_topic``; a step waits for it at most ``pose_timeout_s``. A halt publishes
    the stop (an empty Path) and a setpoint at the measured pose (hold). No pose for
    ``pose_timeout_s`` before a movement: the robot refuses to move (DeviceError).
    """

    goal_topic: str = Field("/hapticframe/goal", description="Path goals and the stop.")
    setpoint_topic: str = Field(
        "/hapticframe/target_pose", description="PoseStamped setpoints, one per period.")
    pose_topic: str = Field(
        "/hapticframe/plate_pose", description="The plate's measured PoseStamped.")
    frame_id: str = Field("world", min_length=1, max_length=200,
                          description="The frame of goals and setpoints.")
    control_rate_hz: float = Field(100.0, gt=0, le=10_000, description="Setpoints per second.")
    depth_m: float = Field(0.044, gt=0, le=0.3,
                           description="Depth of a movement that gives none.")
    pose_timeout_s: float = Field(
        0.5, gt=0, le=60,
        description="A step waits this long for the pose; a pose stream silent this long is "
        "stale (halt 'pose_stale'; no new movement starts).")
    connect_timeout_s: float = Field(
        10.0, gt=0, le=600, description="activate() waits this long for the first pose.")
    qos: QosConfig = Field(default_factory=QosConfig, description="QoS of every topic.")
    rig: Literal["external", "emulated"] = Field(
        "external",
        description="'external': a rig on the network; 'emulated': start the emulated rig "
        "(the sandbox of the experiment's scene behind these topics) in this process, "
        "publishing its force on wrench_topic.")
    wrench_topic: str = Field(
        "/hapticframe/wrench", description="Emulated rig: where it publishes the plate's force.")

    _topics = field_validator("goal_topic", "setpoint_topic", "pose_topic", "wrench_topic")(
        classmethod(lambda cls, v: _checked_topic(v)))
