"""The emulated rig: the simulated sandbox behind ROS 2 topics, as its own DDS participant.

It subscribes to the ``ros2`` robot's goals and setpoints and publishes the plate's pose and
the wrist force, as a ros2_control rig with a wrist force/torque sensor would. It runs the
bundled ``sandbox`` robot and ``sandbox-force`` sensor (their public classes) under the
component ids and seed of the experiment it serves, so a search through DDS makes the
movements the same search makes in-process.

Lockstep: the rig advances its sandbox one control period per setpoint it receives (a
setpoint stamped no later than its last step is a hold, and ignored), so a run is
reproducible however the two processes are scheduled; between setpoints it repeats the
latest pose every ``heartbeat_s`` (what keeps the robot's pose stream fresh). Each step
publishes the step's force samples (``WrenchStamped``, force in x and y, stamped with the
step's time) before the pose.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from hapticframe import Scene
from hapticframe.kinds import BuildContext, ExploratoryMovement

from ._config import QosConfig, Ros2RobotConfig
from ._dds import Endpoint, stamp_of, time_of
from ._messages import (
    Header,
    Path,
    Point,
    Pose,
    PoseStamped,
    Quaternion,
    Time,
    Vector3,
    Wrench,
    WrenchStamped,
)

__all__ = ["EmulatedRig", "component_rng"]

#: How long a setpoint with no movement running waits for its goal (a Path and the first
#: setpoint travel on two topics, so the setpoint may come first).
_GOAL_WAIT_S = 0.2


def component_rng(seed: int, component_id: str) -> np.random.Generator:
    """The generator a run gives ``component_id`` under ``seed`` (the run's own formula)."""
    import zlib

    return np.random.default_rng(
        np.random.SeedSequence(seed, spawn_key=(zlib.crc32(component_id.encode("utf-8")),)))


class EmulatedRig:
    """The sandbox of ``scene`` behind the ``ros2`` robot's topics.

    Parameters
    ----------
    scene : Scene
    domain_id : int
    seed : int
        The experiment's seed.
    robot_id, sensor_id : str
        The component ids the rig's sandbox robot and force sensor are built under (the
        experiment's ``ros2`` robot and ``ros2-topic`` sensor ids give the in-process run's
        random streams).
    goal_topic, setpoint_topic, pose_topic, wrench_topic : str
    qos : QosConfig
    heartbeat_s : float
        The pose is repeated this often while no setpoint comes.
    robot_config, sensor_config : mapping, optional
        Settings of the sandbox robot and sensor (their defaults otherwise).
    """

    def __init__(
        self, scene: Scene, *, domain_id: int, seed: int, robot_id: str = "arm",
        sensor_id: str = "wrist", goal_topic: str = "/hapticframe/goal",
        setpoint_topic: str = "/hapticframe/target_pose",
        pose_topic: str = "/hapticframe/plate_pose",
        wrench_topic: str = "/hapticframe/wrench", qos: QosConfig | None = None,
        heartbeat_s: float = 0.05, robot_config: dict[str, Any] | None = None,
        sensor_config: dict[str, Any] | None = None,
    ) -> None:
        from hapticframe_sandbox import (
            SandboxForceSensor,
            SandboxForceSensorConfig,
            SandboxRobot,
            SandboxRobotConfig,
        )

        self.robot = SandboxRobot(
            SandboxRobotConfig.model_validate(robot_config or {}),
            BuildContext(robot_id, component_rng(seed, robot_id), scene=scene))
        self.sensor = SandboxForceSensor(
            SandboxForceSensorConfig.model_validate(sensor_config or {}),
            BuildContext(sensor_id, component_rng(seed, sensor_id), {robot_id: self.robot},
                         scene=scene))
        qos = qos or QosConfig()
        self._endpoint = Endpoint(domain_id)
        self._goals = self._endpoint.reader(goal_topic, Path, qos)
        self._setpoints = self._endpoint.reader(setpoint_topic, PoseStamped, qos)
        self._pose = self._endpoint.writer(pose_topic, PoseStamped, qos)
        self._wrench = self._endpoint.writer(wrench_topic, WrenchStamped, qos)
        self.frame_id = "world"
        self.heartbeat_s = heartbeat_s
        self._moving = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None
        #: What the rig did: movements begun, steps, stops, ignored setpoints.
        self.counts = {"movements": 0, "steps": 0, "stops": 0, "ignored_setpoints": 0}
        #: Faults to inject (tests): ``{"silent_wrench_after_steps": n}`` stops the force
        #: topic after n steps, ``{"silent_after_steps": n}`` stops answering at all.
        self.faults: dict[str, int] = {}

    @classmethod
    def for_robot(cls, config: Ros2RobotConfig, scene: Scene, robot_id: str,
                  *, seed: int) -> EmulatedRig:
        """The rig behind a ``ros2`` robot's topics (its ``rig: emulated``)."""
        return cls(scene, domain_id=config.domain_id, seed=int(seed), robot_id=robot_id,
                   goal_topic=config.goal_topic, setpoint_topic=config.setpoint_topic,
                   pose_topic=config.pose_topic, wrench_topic=config.wrench_topic,
                   qos=config.qos)

    # -- running -------------------------------------------------------------------------------

    def start(self) -> EmulatedRig:
        """Serve from a daemon thread (until :meth:`stop`)."""
        self._thread = threading.Thread(target=self._serve, name="emulated-rig", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop serving and leave the domain."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self._endpoint.close()

    def serve_forever(self) -> None:
        """Serve in this thread until :meth:`stop` (or KeyboardInterrupt)."""
        self._serve()

    def _serve(self) -> None:
        try:
            last_pose = 0.0
            while not self._stop.is_set():
                worked = self._handle_goals()
                for setpoint in self._setpoints.take(N=64):
                    if not isinstance(setpoint, PoseStamped):
                        continue  # a writer that left
                    self._handle_setpoint(setpoint)
                    worked = True
                    last_pose = time.monotonic()
                if time.monotonic() - last_pose >= self.heartbeat_s:
                    self._publish_pose()
                    last_pose = time.monotonic()
                if not worked:
                    time.sleep(0.0002)
        except BaseException as exc:  # a test reads it; the process prints it
            self.error = exc
            raise

    def _handle_goals(self) -> bool:
        # A writer that leaves shows as an InvalidSample (no data): not a goal.
        goals = [g for g in self._goals.take(N=64) if isinstance(g, Path)]
        for goal in goals:
            if not goal.poses:
                self.robot.halt("stop")
                self._moving = False
                self.counts["stops"] += 1
                continue
            start, end = goal.poses[0], goal.poses[-1]
            a = np.array([start.pose.position.x, start.pose.position.y])
            b = np.array([end.pose.position.x, end.pose.position.y])
            duration = (time_of(end.header.stamp.sec, end.header.stamp.nanosec)
                        - time_of(start.header.stamp.sec, start.header.stamp.nanosec))
            length = float(np.linalg.norm(b - a))
            speed = length / duration if duration > 0 else 0.05
            self.robot.begin(ExploratoryMovement(a, b, speed_m_per_s=speed,
                                                 depth_m=-start.pose.position.z))
            self.sensor.reset()
            self._moving = True
            self.counts["movements"] += 1
        return bool(goals)

    def _handle_setpoint(self, setpoint: Any) -> None:
        t = time_of(setpoint.header.stamp.sec, setpoint.header.stamp.nanosec)
        if t <= float(self.robot.state.timestamp_s) + 1e-9:
            self.counts["ignored_setpoints"] += 1  # a hold
            return
        if not self._moving:
            deadline = time.monotonic() + _GOAL_WAIT_S
            while not self._moving and time.monotonic() < deadline:
                if not self._handle_goals():
                    time.sleep(0.0005)
        silent = self.faults.get("silent_after_steps")
        if not self._moving or (silent is not None and self.counts["steps"] >= silent):
            self.counts["ignored_setpoints"] += 1
            return
        state = self.robot.step()
        if state is None:
            self._moving = False
            self.counts["ignored_setpoints"] += 1
            return
        self.counts["steps"] += 1
        batch = self.sensor.read()
        quiet = self.faults.get("silent_wrench_after_steps")
        if quiet is None or self.counts["steps"] <= quiet:
            for ts, (fx, fy) in zip(batch.timestamps_s.tolist(),
                                    batch.channels["force_n"].tolist(), strict=True):
                self._wrench.write(WrenchStamped(
                    Header(Time(*stamp_of(ts)), "plate"),
                    Wrench(Vector3(fx, fy, 0.0), Vector3())))
        self._publish_pose()

    def _publish_pose(self) -> None:
        import math

        state = self.robot.state
        x, y = (float(v) for v in state.position_m)
        heading = float(state.heading_rad)
        self._pose.write(PoseStamped(
            Header(Time(*stamp_of(float(state.timestamp_s))), self.frame_id),
            Pose(Point(x, y, -float(state.depth_m)),
                 Quaternion(0.0, 0.0, math.sin(heading / 2), math.cos(heading / 2)))))
