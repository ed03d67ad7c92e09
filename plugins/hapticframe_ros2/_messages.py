"""The ROS 2 messages hapticframe speaks, as DDS types (imports cyclonedds: the extra).

Each class is the message's IDL struct under its DDS type name
(``<package>::msg::dds_::<Type>_``), so that a ROS 2 node sees it as the message it knows;
Cyclone DDS serializes it as XCDR1 little-endian, the encoding ROS 2's ``rmw`` uses.
:data:`ROS_TYPES` names each class's ROS type (``geometry_msgs/msg/WrenchStamped``), the name
``rosbags`` (the tests' independent reference) knows it by.

Field order and types follow the message definitions of ROS 2 (``common_interfaces``):
changing either changes the bytes on the wire.
"""

# No `from __future__ import annotations`: Cyclone DDS reads these annotations as types.

from dataclasses import dataclass, field

from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float64, int32, sequence, uint32

__all__ = [
    "ROS_TYPES",
    "Header",
    "Imu",
    "Path",
    "Point",
    "Pose",
    "PoseStamped",
    "Quaternion",
    "Time",
    "Vector3",
    "Wrench",
    "WrenchStamped",
]


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):  # type: ignore[call-arg]
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):  # type: ignore[call-arg]
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):  # type: ignore[call-arg]
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):  # type: ignore[call-arg]
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):  # type: ignore[call-arg]
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Wrench(IdlStruct, typename="geometry_msgs::msg::dds_::Wrench_"):  # type: ignore[call-arg]
    force: Vector3 = field(default_factory=Vector3)
    torque: Vector3 = field(default_factory=Vector3)


@dataclass
class WrenchStamped(IdlStruct, typename="geometry_msgs::msg::dds_::WrenchStamped_"):  # type: ignore[call-arg]
    header: Header = field(default_factory=Header)
    wrench: Wrench = field(default_factory=Wrench)


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):  # type: ignore[call-arg]
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):  # type: ignore[call-arg]
    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)


def _zeros9() -> list[float]:
    return [0.0] * 9


@dataclass
class Imu(IdlStruct, typename="sensor_msgs::msg::dds_::Imu_"):  # type: ignore[call-arg]
    header: Header = field(default_factory=Header)
    orientation: Quaternion = field(default_factory=Quaternion)
    orientation_covariance: array[float64, 9] = field(default_factory=_zeros9)
    angular_velocity: Vector3 = field(default_factory=Vector3)
    angular_velocity_covariance: array[float64, 9] = field(default_factory=_zeros9)
    linear_acceleration: Vector3 = field(default_factory=Vector3)
    linear_acceleration_covariance: array[float64, 9] = field(default_factory=_zeros9)


@dataclass
class Path(IdlStruct, typename="nav_msgs::msg::dds_::Path_"):  # type: ignore[call-arg]
    header: Header = field(default_factory=Header)
    poses: sequence[PoseStamped] = field(default_factory=list)


#: Each message class's ROS 2 type name.
ROS_TYPES: dict[type[IdlStruct], str] = {
    Time: "builtin_interfaces/msg/Time",
    Header: "std_msgs/msg/Header",
    Vector3: "geometry_msgs/msg/Vector3",
    Point: "geometry_msgs/msg/Point",
    Quaternion: "geometry_msgs/msg/Quaternion",
    Wrench: "geometry_msgs/msg/Wrench",
    WrenchStamped: "geometry_msgs/msg/WrenchStamped",
    Pose: "geometry_msgs/msg/Pose",
    PoseStamped: "geometry_msgs/msg/PoseStamped",
    Imu: "sensor_msgs/msg/Imu",
    Path: "nav_msgs/msg/Path",
}
