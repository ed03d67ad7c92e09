"""DDS plumbing the sensor, the robot and the emulated rig share (imports cyclonedds).

:func:`require_dds` is what a component calls while it is built: without the ``ros2`` extra
it raises ``ValueError`` with the install line (an invalid set-up: exit 2), before anything
is opened.
"""

from __future__ import annotations

import math
from typing import Any

from ._config import QosConfig, dds_topic_name

__all__ = ["Endpoint", "require_dds", "stamp_of", "time_of"]

INSTALL = "pip install 'hapticframe[ros2]' (cyclonedds)"


def require_dds(component: str) -> None:
    """``ValueError`` naming the extra when Cyclone DDS cannot be imported."""
    try:
        import cyclonedds.domain  # noqa: F401
    except ImportError as exc:
        raise ValueError(
            f"{component} talks to ROS 2 over DDS and needs the 'ros2' extra: {INSTALL} "
            f"({exc})"
        ) from None


def _qos(config: QosConfig) -> Any:
    from cyclonedds.core import Policy, Qos
    from cyclonedds.util import duration

    reliability = (
        Policy.Reliability.Reliable(duration(seconds=1))
        if config.reliability == "reliable" else Policy.Reliability.BestEffort
    )
    durability = (
        Policy.Durability.TransientLocal
        if config.durability == "transient_local" else Policy.Durability.Volatile
    )
    return Qos(reliability, durability, Policy.History.KeepLast(config.history_depth))


class Endpoint:
    """One DDS participant and the readers and writers of ROS 2 topics on it."""

    def __init__(self, domain_id: int) -> None:
        from cyclonedds.domain import DomainParticipant

        self.participant = DomainParticipant(domain_id)
        self._topics: dict[str, Any] = {}

    def _topic(self, topic: str, message: type) -> Any:
        from cyclonedds.topic import Topic

        name = dds_topic_name(topic)
        if name not in self._topics:
            self._topics[name] = Topic(self.participant, name, message)
        return self._topics[name]

    def writer(self, topic: str, message: type, qos: QosConfig) -> Any:
        from cyclonedds.pub import DataWriter

        return DataWriter(self.participant, self._topic(topic, message), qos=_qos(qos))

    def reader(self, topic: str, message: type, qos: QosConfig) -> Any:
        from cyclonedds.sub import DataReader

        return DataReader(self.participant, self._topic(topic, message), qos=_qos(qos))

    def close(self) -> None:
        """Leave the domain (its readers and writers go with it)."""
        self._topics.clear()
        # Cyclone DDS deletes an entity (and its children) when the last reference goes.
        self.participant = None


def stamp_of(t: float) -> tuple[int, int]:
    """A time in seconds as ROS 2's ``builtin_interfaces/Time`` (sec, nanosec)."""
    if not math.isfinite(t):
        raise ValueError(f"cannot stamp a message with t = {t!r}")
    ns = round(t * 1e9)
    sec, nanosec = divmod(ns, 1_000_000_000)
    return int(sec), int(nanosec)


def time_of(sec: int, nanosec: int) -> float:
    """``builtin_interfaces/Time`` as seconds."""
    return sec + nanosec * 1e-9
