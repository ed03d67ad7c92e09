"""The ``ros2-topic`` sensor: one ROS 2 topic (WrenchStamped or Imu) over DDS.

A read takes what the DDS reader holds without waiting (or, with ``robot_sync_timeout_s``
and a robot input, waits bounded for the sample of the robot's latest step), checks every
sample and delivers the good ones stamped from their headers:

- a sample that fails to deserialize is counted (``crc_errors``) and never delivered;
- a stamp not after the last delivered one is dropped and counted (``out_of_order``);
- a stamp more than ``max_clock_jump_s`` after the last one stops the run (DeviceError);
- a gap of more than 1.5 periods counts the samples in it as ``dropped_samples``;
- a non-finite value is delivered marked invalid (``invalid_samples``);
- with ``late_after_s``, a sample received that long after its stamp counts ``late_samples``;
- no sample for ``stall_s`` counts a stall; the run's ``force_stall_s`` halts the robot.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import numpy as np

from hapticframe.devices import DeviceError, DeviceLifecycle, LifecycleState
from hapticframe.kinds import BuildContext, ChannelInfo, Robot, SampleBatch, Sensor

from ._config import Ros2TopicSensorConfig
from ._dds import require_dds, time_of

__all__ = ["Ros2TopicSensor"]

#: How often a waiting read looks at the reader.
_POLL_S = 0.0005
#: Samples taken from the reader at once.
_TAKE_N = 256

_WRENCH = "geometry_msgs/msg/WrenchStamped"


def _wrench_values(msg: Any) -> tuple[list[float], list[float]]:
    f, m = msg.wrench.force, msg.wrench.torque
    return [f.x, f.y, f.z], [m.x, m.y, m.z]


def _imu_values(msg: Any) -> tuple[list[float], list[float], list[float]]:
    q, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
    return [q.x, q.y, q.z, q.w], [w.x, w.y, w.z], [a.x, a.y, a.z]


class Ros2TopicSensor(Sensor, DeviceLifecycle):
    """Samples of one ROS 2 topic, stamped from the message headers.

    Parameters
    ----------
    config : Ros2TopicSensorConfig
    context : BuildContext
        ``inputs`` may hold one robot: with ``robot_sync_timeout_s`` a read waits for the
        sample of its latest step.
    """

    def __init__(self, config: Ros2TopicSensorConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        require_dds(f"sensor {context.id!r} (type 'ros2-topic')")
        self.config: Ros2TopicSensorConfig = config
        self.live = True
        robots = [c for c in context.inputs.values() if isinstance(c, Robot)]
        if len(robots) != len(context.inputs) or len(robots) > 1:
            raise ValueError(
                f"sensor {context.id!r} (type 'ros2-topic') takes at most one input, a robot")
        self._robot: Robot | None = robots[0] if robots else None
        if config.robot_sync_timeout_s is not None and self._robot is None:
            raise ValueError(
                f"sensor {context.id!r}: robot_sync_timeout_s needs the robot in inputs")
        rate = config.rate_hz
        if config.message == _WRENCH:
            self._channels = MappingProxyType({
                "force_n": ChannelInfo(shape=(3,), unit="N", rate_hz=rate),
                "torque_nm": ChannelInfo(shape=(3,), unit="N·m", rate_hz=rate),
            })
        else:
            self._channels = MappingProxyType({
                "orientation": ChannelInfo(shape=(4,), unit="1", rate_hz=rate),
                "angular_velocity_rad_per_s": ChannelInfo(shape=(3,), unit="rad/s",
                                                          rate_hz=rate),
                "linear_acceleration_m_per_s2": ChannelInfo(shape=(3,), unit="m/s²",
                                                            rate_hz=rate),
            })
        self._endpoint: Any = None
        self._reader: Any = None
        self._message: type = object
        self._last_t = -math.inf
        self._last_arrival = math.inf
        self._stalled = False
        self._rows: list[tuple[float, tuple[list[float], ...]]] = []

    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        return self._channels

    # -- lifecycle -----------------------------------------------------------------------------

    def on_configure(self) -> None:
        from ._dds import Endpoint
        from ._messages import Imu, WrenchStamped

        message = WrenchStamped if self.config.message == _WRENCH else Imu
        self._message = message
        self._endpoint = Endpoint(self.config.domain_id)
        self._reader = self._endpoint.reader(self.config.topic, message, self.config.qos)

    def on_activate(self) -> None:
        # A publisher must be there (discovered); its first sample may come with the first
        # movement (a lockstep rig publishes force only while it steps).
        deadline = time.monotonic() + self.config.connect_timeout_s
        while self._reader.get_subscription_matched_status().current_count == 0:
            if time.monotonic() > deadline:
                raise DeviceError(
                    f"sensor {self.id!r}: no publisher of {self.config.message} on "
                    f"{self.config.topic} (domain {self.config.domain_id}) in "
                    f"{self.config.connect_timeout_s} s (a publisher of another type, or of "
                    "incompatible QoS, does not match)", device_id=self.id)
            time.sleep(0.005)
        self._take()
        self._rows.clear()  # samples before the run are not data
        self._last_arrival = time.monotonic()

    def on_cleanup(self) -> None:
        if self._endpoint is not None:
            self._endpoint.close()
        self._endpoint = self._reader = None

    def close(self) -> None:
        self.deactivate()
        self.cleanup()

    def reset(self) -> None:
        """Drop the samples received and not yet read."""
        self._rows.clear()

    # -- reading -------------------------------------------------------------------------------

    def read(self) -> SampleBatch:
        """The samples received since the previous read (checked; see the module)."""
        if self.lifecycle_state is not LifecycleState.ACTIVE:
            raise DeviceError(f"sensor {self.id!r} is {self.lifecycle_state.value}, not active",
                              device_id=self.id)
        self._take()
        timeout = self.config.robot_sync_timeout_s
        if timeout is not None and self._robot is not None:
            wanted = float(self._robot.state.timestamp_s) - 1e-9
            deadline = time.monotonic() + timeout
            while self._last_t < wanted and time.monotonic() < deadline:
                time.sleep(_POLL_S)
                self._take()
        now = time.monotonic()
        if now - self._last_arrival > self.config.stall_s and not self._stalled:
            self._stalled = True
            self.health.stalls += 1
        return self._batch()

    def _take(self) -> None:
        while True:
            try:
                samples = self._reader.take(N=_TAKE_N)
            except Exception:  # a sample that does not deserialize: never delivered
                self.health.crc_errors += 1
                continue
            if not samples:
                return
            for msg in samples:
                if isinstance(msg, self._message):
                    self._accept(msg)
                # else: an InvalidSample, the publisher left (no data): the stall watch sees it
            if len(samples) < _TAKE_N:
                return

    def _accept(self, msg: Any) -> None:
        self.health.bytes += 1  # messages: DDS hides the bytes
        try:
            stamp = msg.header.stamp
            t = time_of(int(stamp.sec), int(stamp.nanosec))
            values = (_wrench_values(msg) if self.config.message == _WRENCH
                      else _imu_values(msg))
        except (AttributeError, TypeError, ValueError):
            self.health.crc_errors += 1
            return
        self.health.frames += 1
        self._last_arrival = time.monotonic()
        self._stalled = False
        if t <= self._last_t:
            self.health.out_of_order += 1
            return
        if self._last_t > -math.inf:
            gap = t - self._last_t
            if gap > self.config.max_clock_jump_s:
                raise DeviceError(
                    f"sensor {self.id!r}: the stamps on {self.config.topic} jumped forward by "
                    f"{gap:.6g} s (max_clock_jump_s {self.config.max_clock_jump_s} s): the "
                    "publisher's clock was set; restart the run", device_id=self.id)
            period = 1.0 / self.config.rate_hz
            if gap > 1.5 * period:
                self.health.dropped_samples += max(0, round(gap / period) - 1)
        late = self.config.late_after_s
        if late is not None and time.time() - t > late:
            self.health.late_samples += 1
        self._last_t = t
        self._rows.append((t, values))

    def _batch(self) -> SampleBatch:
        rows, self._rows = self._rows, []
        if not rows:
            return SampleBatch.empty(self._channels)
        times = np.array([r[0] for r in rows], dtype=np.float64)
        channels: dict[str, np.ndarray] = {}
        valid: dict[str, np.ndarray] = {}
        for k, name in enumerate(self._channels):
            values = np.array([r[1][k] for r in rows], dtype=np.float64)
            ok = np.all(np.isfinite(values), axis=1)
            channels[name] = values
            valid[name] = ok
        bad = ~np.all(np.stack(list(valid.values())), axis=0)
        self.health.invalid_samples += int(bad.sum())
        return SampleBatch(times, channels, valid)
