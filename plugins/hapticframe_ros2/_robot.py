"""The ``ros2`` robot: a ros2_control rig that follows Cartesian pose setpoints, over DDS.

Per movement: a ``nav_msgs/Path`` goal (start and end pose at the movement's depth, the end
stamped ``length / speed`` after the start), then per control period one
``geometry_msgs/PoseStamped`` setpoint ``speed / control_rate_hz`` further along the line
(the last one at the end point). A step publishes the next setpoint and waits, at most
``pose_timeout_s``, for a measured pose stamped after the previous one; that pose is the
step's :class:`RobotState` (position and depth from the pose, the heading from its yaw, the
commanded speed: a pose carries none). No pose in time halts the movement
(``pose_stale``). A halt publishes the stop, an empty Path, and a setpoint at the measured
pose. Before a movement, a pose stream silent for ``pose_timeout_s`` refuses it
(:class:`~hapticframe.devices.DeviceError`: the run stops every robot and exits 1).

The run loop's safety monitor (force limit, stalled force stream) halts this robot like any
other: through :meth:`halt`.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from hapticframe.devices import DeviceError, DeviceLifecycle
from hapticframe.kinds import BuildContext, ExploratoryMovement, Robot, RobotState

from ._config import EMULATED_RIG, Ros2RobotConfig
from ._dds import require_dds, stamp_of, time_of

__all__ = ["POSE_STALE", "Ros2Robot"]

#: The halt reason of a step whose pose did not come in time.
POSE_STALE = "pose_stale"
_POLL_S = 0.0002


def _quaternion(heading_rad: float) -> tuple[float, float, float, float]:
    """A rotation by ``heading_rad`` about z, (x, y, z, w)."""
    return 0.0, 0.0, math.sin(heading_rad / 2), math.cos(heading_rad / 2)


def _yaw(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


class Ros2Robot(Robot, DeviceLifecycle):
    """Exploratory movements as goals and setpoints on ROS 2 topics; the pose read back.

    Parameters
    ----------
    config : Ros2RobotConfig
    context : BuildContext
        With ``rig: emulated``, ``context.scene`` is the emulated rig's sandbox.
    """

    def __init__(self, config: Ros2RobotConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        require_dds(f"robot {context.id!r} (type 'ros2')")
        if config.rig == EMULATED_RIG and context.scene is None:
            raise ValueError(f"robot {context.id!r}: rig 'emulated' needs the experiment's scene")
        self.config: Ros2RobotConfig = config
        self.live = True
        self._endpoint: Any = None
        self._rig: Any = None
        self._goal_writer: Any = None
        self._setpoint_writer: Any = None
        self._pose_reader: Any = None
        self._pose: Any = None  # the latest measured PoseStamped
        self._pose_t = -math.inf  # its stamp
        self._pose_arrival = -math.inf  # host time it arrived
        self._step_t = -math.inf  # stamp of the last step's pose
        self._active = False
        self._plan: list[tuple[float, float]] = []
        self._next = 0
        self._state = RobotState(0.0, np.zeros(2), 0.0, config.depth_m, 0.0)

    # -- lifecycle -----------------------------------------------------------------------------

    def on_configure(self) -> None:
        from ._dds import Endpoint
        from ._messages import Path, PoseStamped

        cfg = self.config
        if cfg.rig == EMULATED_RIG:
            from ._rig import EmulatedRig

            assert self.context.scene is not None
            self._rig = EmulatedRig.for_robot(cfg, self.context.scene, self.context.id,
                                              seed=int(self.context.rng.integers(2**31)))
            self._rig.start()
        self._endpoint = Endpoint(cfg.domain_id)
        self._goal_writer = self._endpoint.writer(cfg.goal_topic, Path, cfg.qos)
        self._setpoint_writer = self._endpoint.writer(cfg.setpoint_topic, PoseStamped, cfg.qos)
        self._pose_reader = self._endpoint.reader(cfg.pose_topic, PoseStamped, cfg.qos)

    def on_activate(self) -> None:
        if not self._wait_for_pose(lambda: self._pose is not None,
                                   self.config.connect_timeout_s):
            raise DeviceError(
                f"robot {self.id!r}: no pose on {self.config.pose_topic} (domain "
                f"{self.config.domain_id}) in {self.config.connect_timeout_s} s: is the rig up?",
                device_id=self.id)
        self._state = self._state_of(self._pose, 0.0)

    def on_deactivate(self) -> None:
        self._publish_stop()

    def on_cleanup(self) -> None:
        if self._endpoint is not None:
            self._endpoint.close()
        self._endpoint = self._goal_writer = self._setpoint_writer = self._pose_reader = None
        if self._rig is not None:
            self._rig.stop()
            self._rig = None

    def close(self) -> None:
        self.deactivate()
        self.cleanup()

    # -- the pose stream -----------------------------------------------------------------------

    def _take_poses(self) -> None:
        from ._messages import PoseStamped

        for msg in self._pose_reader.take(N=256):
            if not isinstance(msg, PoseStamped):
                continue  # the rig's writer left (an InvalidSample: no data)
            stamp = msg.header.stamp
            t = time_of(int(stamp.sec), int(stamp.nanosec))
            p = msg.pose.position
            if not all(math.isfinite(v) for v in (t, p.x, p.y, p.z)):
                self.health.invalid_samples += 1
                continue
            self.health.frames += 1
            self._pose_arrival = time.monotonic()
            if t < self._pose_t:
                self.health.out_of_order += 1
                continue
            self._pose, self._pose_t = msg, t

    def _wait_for_pose(self, done: Any, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while True:
            self._take_poses()
            if done():
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(_POLL_S)

    def _state_of(self, msg: Any, speed: float) -> RobotState:
        p = msg.pose.position
        return RobotState(self._pose_t, np.array([p.x, p.y]), _yaw(msg.pose.orientation),
                          -p.z, speed)

    @property
    def pose_age_s(self) -> float:
        """Host seconds since the last pose arrived (infinite before the first)."""
        return time.monotonic() - self._pose_arrival

    # -- Robot ---------------------------------------------------------------------------------

    def _begin(self, movement: ExploratoryMovement, depth_m: float) -> None:
        self._take_poses()
        if self.pose_age_s > self.config.pose_timeout_s:
            raise DeviceError(
                f"robot {self.id!r}: the pose on {self.config.pose_topic} is stale (last one "
                f"{self.pose_age_s:.3g} s ago, pose_timeout_s {self.config.pose_timeout_s}): "
                "refusing to move", device_id=self.id)
        from ._messages import Header, Path, Point, Pose, PoseStamped, Quaternion, Time

        start = movement.start_m.astype(float)
        end = movement.end_m.astype(float)
        heading = movement.heading_rad
        q = Quaternion(*_quaternion(heading))
        t0 = max(self._pose_t, 0.0)
        duration = movement.length_m / movement.speed_m_per_s

        def pose(xy: np.ndarray, t: float) -> PoseStamped:
            return PoseStamped(Header(Time(*stamp_of(t)), self.config.frame_id),
                               Pose(Point(float(xy[0]), float(xy[1]), -depth_m), q))

        self._goal_writer.write(Path(Header(Time(*stamp_of(t0)), self.config.frame_id),
                                     [pose(start, t0), pose(end, t0 + duration)]))
        # The setpoints: a control period's travel each, the last one at the end.
        length, advance = movement.length_m, movement.speed_m_per_s / self.control_rate_hz
        travelled, plan = 0.0, []
        direction = (end - start) / length if length > 0 else np.zeros(2)
        while travelled < length:
            travelled += min(advance, length - travelled)
            x, y = (start + travelled * direction).tolist()
            plan.append((x, y))
        self._plan, self._next = plan, 0
        self._heading, self._depth, self._speed = heading, depth_m, movement.speed_m_per_s
        self._halt_reason = ""
        self._active = bool(plan)
        self._step_t = self._pose_t

    def step(self) -> RobotState | None:
        if not self._active:
            return None
        if self._next >= len(self._plan):
            self._active = False
            return None
        from ._messages import Header, Point, Pose, PoseStamped, Quaternion, Time

        x, y = self._plan[self._next]
        self._next += 1
        t = self._step_t + 1.0 / self.control_rate_hz
        self._setpoint_writer.write(PoseStamped(
            Header(Time(*stamp_of(t)), self.config.frame_id),
            Pose(Point(x, y, -self._depth), Quaternion(*_quaternion(self._heading)))))
        previous = self._step_t
        if not self._wait_for_pose(lambda: self._pose_t > previous, self.config.pose_timeout_s):
            self.health.timeouts += 1
            self.halt(POSE_STALE)
            return None
        self._step_t = self._pose_t
        self._state = self._state_of(self._pose, self._speed)
        if self._next >= len(self._plan):
            self._active = False
        return self._state

    def halt(self, reason: str) -> None:
        """Publish the stop (an empty Path) and hold the measured pose."""
        if self._active:
            self._active = False
            self._halt_reason = str(reason)
            self._publish_stop()

    def _publish_stop(self) -> None:
        if self._goal_writer is None:
            return
        from ._messages import Header, Path, PoseStamped, Time

        stamp = Time(*stamp_of(max(self._pose_t, 0.0)))
        self._goal_writer.write(Path(Header(stamp, self.config.frame_id), []))
        if self._pose is not None:
            self._setpoint_writer.write(PoseStamped(Header(stamp, self.config.frame_id),
                                                    self._pose.pose))
