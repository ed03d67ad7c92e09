"""The simulated sandbox: a plate raked through sand towards buried objects.

Each control step the robot advances the fingertip along a straight exploratory movement
and asks its :class:`~hapticframe.kinds.World` for the true interaction force and state
(:meth:`SandboxRobot.build_world`; by default the :class:`AnalyticSandWorld`: free plate drag
modulated by the shear-band nucleation cycle, a jamming surge once the failure zone (thesis
Eq. 3.2, Figure 3.2) reaches an object, and a stiff contact force once the plate does). The
sandbox force sensor reads that force from here. Every world gets the same plumbing from the
robot: movements, clock, depth schedule, halts, ground truth, physical truth, ``follows``.

The robot is also a :class:`~hapticframe.kinds.PhysicalTruthSource`: per step it exposes the
tool's pose, velocity, acceleration and the environment's force and torque on it as a
:class:`~hapticframe.kinds.PhysicalTruth`, which drives emulated wrist force/torque sensors and
IMUs (``docs/simulated-devices.md``). With ``acceleration_m_per_s2`` set, each movement follows
a trapezoidal speed profile, so that the tool's inertia shows in those sensors.

With ``follows: <robot id>`` the sandbox moves no plate of its own: it is the world around an
emulated robot (a :class:`~hapticframe.kinds.RobotFollower`). The run loop tells it each
movement and step of that robot; it computes the same physics at the robot's *measured*
fingertip, fills the movements' open depths from its depth schedule, and loads the robot's
emulated actuators with the force (:class:`~hapticframe.kinds.EnvironmentCoupled`).

At the end of a run the robot writes its per-step truth into ``ground_truth.npz`` in the run's
directory (see :meth:`SandboxRobot.finalize`): time, true state (0 free, 1 jamming, 2
contact), true force, position and movement of every step, the labels a classifier is
calibrated against (``hapticframe train`` with the ``trace-recording`` sensor).
"""

from __future__ import annotations

import dataclasses
import math
from bisect import bisect_right
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe import Scene, save_npz
from hapticframe.kinds import (
    BuildContext,
    EnvironmentCoupled,
    ExploratoryMovement,
    MovementResult,
    PhysicalTruth,
    PhysicalTruthSource,
    PlateMovement,
    PlateSample,
    Robot,
    RobotFollower,
    RobotState,
    RunOutcome,
    World,
)
from hapticframe_granular import arthur_angle, rupture_distance, side_crescent_angle

from . import _functional as F
from ._analytic import AnalyticSandWorld
from ._config import SandboxRobotConfig
from ._truth import CONTACT, FREE, JAMMING, STATE_NAMES, GroundTruthLog, MovementTruth
from ._world import _followed_robot, _Sandbox

__all__ = [
    "CONTACT",
    "FREE",
    "JAMMING",
    "STATE_NAMES",
    "GroundTruthLog",
    "MovementTruth",
    "SandboxRobot",
]

#: How far past its workspace a movement may reach (rounding of a cut at the boundary).
WORKSPACE_SLACK_M = 1e-6

class SandboxRobot(Robot, PhysicalTruthSource, RobotFollower):
    """Simulated robot that rakes a rigid plate through a sandbox at constant depth and speed.

    With ``acceleration_m_per_s2`` set, the speed follows a trapezoid within each movement
    (accelerate, cruise at the movement's speed, decelerate to stop at the end point); a
    halt still stops at once. See :meth:`physical_truth` for the state it exposes.

    Parameters
    ----------
    config : SandboxRobotConfig
    context : BuildContext
        Needs ``context.scene``; all randomness comes from ``context.rng``.
    """

    def __init__(self, config: SandboxRobotConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        if context.scene is None:
            raise ValueError(
                f"robot {context.id!r} (type 'sandbox') needs a scene: add a 'scene' section "
                "to the experiment"
            )
        self._scene = context.scene
        self._workspace = None if config.workspace is None else config.workspace.to_region()
        self._rng = context.rng
        self._dt = 1.0 / config.control_rate_hz
        material = context.scene.material
        self._beta_rad = (
            math.radians(config.shear_band_angle_deg)
            if config.shear_band_angle_deg is not None
            else arthur_angle(
                math.radians(material.friction_angle_deg),
                math.radians(material.dilation_angle_deg),
            )
        )
        self._rake_rad = math.radians(config.rake_angle_deg)
        # Following an emulated robot: that robot moves; this sandbox is the sand around it.
        self._followed: Robot | None = None
        #: Following: the log rows after which the tool rests (each movement's last step).
        self._rest_after: set[int] = set()
        if config.follows is not None:
            self._followed = _followed_robot(context.id, config.follows, context.inputs)
            self._dt = 1.0 / self._followed.control_rate_hz
        # The mechanics: what this robot's world answers each step.
        self._physics = self.build_world(context.scene, context.rng)
        if not isinstance(self._physics, World):
            raise TypeError(f"robot {context.id!r}: build_world returned "
                            f"{type(self._physics).__name__}, not a hapticframe.kinds.World")
        # One sandbox, shared with the sandbox robots named in inputs: its clock and the
        # depth schedule (section 3.5.1), which shrinks after each movement that reached
        # an object.
        self._world = _Sandbox.join(
            self, {} if self._followed is not None else context.inputs
        )
        # Clock and current movement.
        self._time = 0.0
        self._index = -1
        self._active = False
        self._closed = True
        self._halt_reason = ""
        home = context.scene.region.to_region().center_m
        self._state = RobotState(0.0, home, 0.0, config.depth_m, 0.0)
        # Ground-truth log, kept as growing lists and turned into arrays on demand.
        self._log_t: list[float] = []
        self._log_pos: list[tuple[float, float]] = []
        self._log_state: list[int] = []
        self._log_force: list[tuple[float, float]] = []
        self._log_index: list[int] = []
        self._log_depth: list[float] = []
        self._movements: list[MovementTruth] = []
        self._max_force = 0.0
        # Physical truth: (heading, speed, acceleration along the heading) per step, beside
        # the logs above; records are built only when asked for (physical_truth).
        self._log_motion: list[tuple[float, float, float]] = []
        self._accel = config.acceleration_m_per_s2
        self._profile: F.TrapezoidTiming | None = None
        self._em_steps = 0
        self._truth_speed = 0.0
        # The pose held before the first step: (x, y, heading, depth), at rest.
        self._origin = (*home.tolist(), 0.0, config.depth_m)
        if isinstance(self._followed, EnvironmentCoupled):
            self._followed.couple_environment(self)

    # --- the world -------------------------------------------------------------------------

    def build_world(self, scene: Scene, rng: np.random.Generator) -> World:
        """The world this robot consults each step (called once, while it is built).

        The sandbox's own is the :class:`AnalyticSandWorld` configured by this robot's
        config; a robot type with another world (``mpm-sand``, a lab's) overrides this
        method. ``rng`` is the robot's generator: every draw of the world comes from it.
        """
        return AnalyticSandWorld(self.config, scene, rng)

    @property
    def world(self) -> World:
        """The world this robot's forces and true states come from."""
        return self._physics

    # --- Robot interface (the base checks depth and workspace, then calls _begin) ------------

    #: A micrometre of slack: a line cut at a neighbouring arm's workspace boundary ends
    #: there up to rounding.
    workspace_slack_m = WORKSPACE_SLACK_M

    @property
    def default_depth_m(self) -> float:
        """The depth schedule's current depth (:attr:`current_depth_m`)."""
        return self.current_depth_m

    def begin(self, movement: ExploratoryMovement) -> None:
        if self._followed is not None:
            raise ValueError(
                f"robot {self.id!r} follows {self._followed.id!r}: it makes no movements of "
                f"its own (give them to {self._followed.id!r})"
            )
        # The movement before ends here, before the checks: booking it moves the depth
        # schedule that an open depth reads (and a refused movement leaves none running).
        self._close_movement()
        super().begin(movement)

    def _begin(self, movement: ExploratoryMovement, depth_m: float) -> None:
        self._start_movement(movement, depth_m)

    def _start_movement(self, movement: ExploratoryMovement, depth: float) -> None:
        """Set up the physics of a new movement (or part of one) from ``movement``."""
        self._close_movement()
        cfg = self.config
        self._index += 1
        self._closed = False
        self._halt_reason = ""
        world = self._world
        self._em = world.settled
        self._depth = depth
        self._speed = float(movement.speed_m_per_s)
        self._length = movement.length_m
        self._heading = movement.heading_rad
        self._direction = F.unit_vector(self._heading)
        self._start = movement.start_m
        # The per-step arithmetic runs on plain floats: the same IEEE operations, element by
        # element, as on these arrays, without numpy's per-call overhead.
        self._direction_xy = tuple(self._direction.tolist())
        self._start_xy = tuple(np.asarray(self._start, dtype=np.float64).tolist())
        self._travelled = 0.0
        # The failure zone's geometry, recorded in the movement's truth whatever the world.
        self._rupture = rupture_distance(depth, self._rake_rad, self._beta_rad)
        self._eta_rad = (
            math.radians(cfg.side_crescent_angle_deg)
            if cfg.side_crescent_angle_deg is not None
            else side_crescent_angle(world.interactions // 2)
        )
        self._physics.begin(PlateMovement(
            index=self._em, start_m=self._start_xy, heading_rad=float(self._heading),
            length_m=float(self._length), depth_m=float(depth), speed_m_per_s=self._speed,
            control_period_s=self._dt, plate_width_m=cfg.plate_width_m,
            interactions=world.interactions,
        ))
        self._em_start_time = self._time
        self._em_max_state = FREE
        self._em_max_force = 0.0
        self._jam_onset = math.nan
        self._contact_onset = math.nan
        self._active = self._length > 0.0
        self._state = RobotState(self._time, self._start, self._heading, depth, 0.0)
        self._em_steps = 0
        self._truth_speed = 0.0
        self._profile = (
            None
            if self._accel is None
            else F.trapezoid_timing(self._length, self._speed, self._accel)
        )
        if not self._log_t:
            self._origin = (*self._start_xy, self._heading, depth)

    def step(self) -> RobotState | None:
        if not self._active:
            return None
        if self._profile is None:
            # Instantaneous start and stop: the commanded speed throughout, no acceleration.
            advance = min(self._speed * self._dt, self._length - self._travelled)
            self._travelled += advance
            speed, acceleration = self._speed, 0.0
        else:
            self._em_steps += 1
            travelled, speed = F.trapezoid_motion(
                self._em_steps * self._dt, self._length, self._accel or 0.0, self._profile
            )
            if travelled >= self._length:
                travelled, speed = self._length, 0.0
            # Monotone despite rounding at the profile's corners.
            travelled = max(travelled, self._travelled)
            advance = travelled - self._travelled
            self._travelled = travelled
            # The mean acceleration over the step: velocities integrate exactly from it.
            acceleration = (speed - self._truth_speed) / self._dt
            self._truth_speed = speed
        # Time from the sandbox's step count: exact, and strictly increasing across
        # movements and the robots that share the sandbox.
        self._time = (self._world.steps + 1) * self._dt
        (sx, sy), (dx, dy), travelled = self._start_xy, self._direction_xy, self._travelled
        position = (sx + travelled * dx, sy + travelled * dy)
        magnitude = self._simulate(position, advance, speed, acceleration)
        self._state = RobotState(self._time, np.array(position), self._heading, self._depth, speed)
        if magnitude > self.config.force_limit_n:
            self.halt("force_limit")
        elif self._travelled >= self._length:
            self._active = False
        return self._state

    def _simulate(
        self, position: tuple[float, float], advance: float, speed: float, acceleration: float
    ) -> float:
        """The sand's force with the plate at ``position`` after moving ``advance`` along the
        heading, logged with the step's motion; returns the force's magnitude."""
        response = self._physics.respond(
            PlateSample(self._time, position, self._travelled, advance, speed, acceleration)
        )
        magnitude = self._record(position, response.force_n, response.state)
        self._log_motion.append((self._heading, speed, acceleration))
        return magnitude

    # --- following an emulated robot (RobotFollower) -------------------------------------

    @property
    def followed_robot_id(self) -> str:
        """``config.follows``: the robot whose fingertip this sandbox follows (``""``: none)."""
        return self._followed.id if self._followed is not None else ""

    def follow_begin(self, movement: ExploratoryMovement) -> ExploratoryMovement:
        """The followed robot begins ``movement``: a new movement of the sandbox's physics.
        An open depth is filled from the depth schedule (returned in the movement)."""
        if self._followed is None:
            raise ValueError(f"robot {self.id!r} follows no robot (set 'follows')")
        if movement.depth_m is None:
            movement = dataclasses.replace(movement, depth_m=self._world.schedule_depth)
        self._start_movement(movement, self._checked_depth_m(movement))
        self._profile = None  # the followed robot's own motion sets speed and acceleration
        self._follow_xy = self._start_xy
        self._follow_speed = 0.0
        self._active = False  # never stepped by the run loop: follow_step moves it
        return movement

    def follow_step(self, state: RobotState) -> None:
        """One step of the followed robot: the sand's physics at its measured fingertip.

        The plate advances by the measured displacement along the movement's heading (never
        backwards: a servo's lag or overshoot does not unload the sand), at the measured
        speed; the step's acceleration is the speed change over the time since the last step.
        """
        if self._closed:
            raise ValueError(
                f"robot {self.id!r}: a step of {self.followed_robot_id!r} before follow_begin"
            )
        t = float(state.timestamp_s)
        if not (math.isfinite(t) and t > self._time):
            raise ValueError(
                f"robot {self.id!r}: the followed robot's step at t = {t!r} s does not come "
                f"after the last (t = {self._time:.6g} s)"
            )
        x, y = (float(v) for v in state.position_m)
        (sx, sy), (dx, dy) = self._start_xy, self._direction_xy
        along = max(self._travelled, (x - sx) * dx + (y - sy) * dy)
        advance = along - self._travelled
        self._travelled = along
        speed = float(state.speed_m_per_s)
        elapsed = t - self._time if self._log_t else self._dt
        acceleration = (speed - self._follow_speed) / elapsed
        self._follow_speed = speed
        self._time = t
        self._simulate((x, y), advance, speed, acceleration)
        self._state = RobotState(t, np.array((x, y)), self._heading, self._depth, speed)

    def halt(self, reason: str) -> None:
        """Stop the current movement; the first reason given for a movement is kept."""
        if self._active:
            self._active = False
            self._halt_reason = str(reason)

    def checkpoint(self) -> tuple[dict[str, Any], int, Mapping[str, Any], Any]:
        """The state a step changes: every attribute, the log length, the generator and
        the world's own checkpoint.

        Attribute values are immutable or, like the ground-truth logs, only appended to
        within a movement, so a shallow copy suffices. Valid until the movement ends.
        """
        return (dict(self.__dict__), len(self._log_t), self._rng.bit_generator.state,
                self._physics.checkpoint())

    def rewind(self, checkpoint: tuple[dict[str, Any], int, Mapping[str, Any], Any]) -> None:
        attributes, logged, generator, world = checkpoint
        if attributes["_index"] != self._index or logged > len(self._log_t):
            raise ValueError(f"robot {self.id!r}: the checkpoint is not from this movement")
        for log in (self._log_t, self._log_pos, self._log_state, self._log_force,
                    self._log_index, self._log_depth, self._log_motion):
            del log[logged:]
        self.__dict__.update(attributes)
        self._rng.bit_generator.state = generator
        self._physics.rewind(world)

    def on_movement_end(self, result: MovementResult) -> None:
        self._close_movement()
        self._world.movement_ended(result.index)

    @property
    def sandbox_robots(self) -> tuple[SandboxRobot, ...]:
        """The robots that share this robot's sandbox (itself included), in build order."""
        return tuple(self._world.robots)

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        """Write ``ground_truth.npz`` (and ``forces.png`` with figures); return metrics.

        ``ground_truth.npz`` in the run's directory holds the simulator's truth, one row
        per robot step of every movement (plain arrays, no pickles):

        - ``timestamps_s`` (n,): the step's time (the robot's ``timestamp_s``);
        - ``state`` (n,) int64: 0 free movement, 1 granular jamming, 2 direct contact
          (names in ``state_names``);
        - ``force_n`` (n, 2): the true interaction force on the fingertip (no noise);
        - ``position_m`` (n, 2): the fingertip position;
        - ``movement_index`` (n,) int64: the 0-based exploratory movement;
        - ``depth_m`` (n,): the raking depth.

        These are the labels for calibrating classifiers from a recorded run: the
        ``trace-recording`` sensor replays the run's ``trace.npz`` with them
        (``labels: <run directory>``).
        """
        self._close_movement()
        world = self._world
        if world.robots[0] is not self:
            return {}  # the sandbox's first robot writes the shared truth and its metrics
        for robot in world.robots:
            robot._close_movement()
        out_dir = Path(outcome.out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        truth, robot_ids = world.ground_truth()
        extra: dict[str, Any] = {} if robot_ids is None else {"robot_id": robot_ids}
        save_npz(
            out_dir / "ground_truth.npz",
            timestamps_s=truth.timestamps_s,
            state=truth.states,
            force_n=truth.forces_n,
            position_m=truth.positions_m,
            movement_index=truth.movement_index,
            depth_m=truth.depth_m,
            state_names=np.array(STATE_NAMES),
            **extra,
        )
        movements = world.movement_truths()
        if outcome.figures:
            from ._plots import classifier_force_thresholds, plot_movement_forces

            plot_movement_forces(
                truth, movements, Path(outcome.out_dir) / "forces.png",
                thresholds=classifier_force_thresholds(outcome.components),
                verdict=outcome.verdict,
            )
        return {
            "max_force_n": float(max(r._max_force for r in world.robots)),
            "object_interactions": int(world.interactions),
        }

    # --- physical truth (PhysicalTruthSource) --------------------------------------------

    @property
    def truth_time_s(self) -> float:
        """Time of the latest step (0 before the first): the simulation clock."""
        return self._time

    def physical_truth(self, timestamp_s: float) -> PhysicalTruth:
        """The tool's physical state at the latest step at or before ``timestamp_s``.

        Sample-and-hold: a time between two steps gets the earlier step's state (its
        ``timestamp_s`` is that step's time); a time at or after :attr:`truth_time_s` the
        latest step's; a time before the first step the pose the robot starts from, at rest
        with no force. Between movements the tool moves to the next start point at once: the
        next movement's first step shows it there. A sandbox that follows a robot shows the
        tool at rest, without force, after each movement's last step (the robot transits to
        the next start lifted out of the sand).

        Conventions (world frame, z up; details in ``docs/simulated-devices.md``):

        - ``position_m``: the wrist sensor's origin, ``(x, y, sensor_height_m - depth)``;
          world z = 0 is the free surface of the sand and the fingertip is at ``-depth``.
        - ``orientation_wxyz``: a yaw by the heading about z (tool x along the motion, tool
          z up); the plate never tilts, so the angular velocity is zero (a heading changes
          only between movements).
        - velocity and acceleration along the heading; the acceleration of a step is the
          mean over the step (the speed change divided by the period), so zero while
          cruising and always zero without ``acceleration_m_per_s2``. A halt stops the tool
          at once: no deceleration is shown for it.
        - ``force_n``: the sandbox's 2-D force on the plate as ``(fx, fy, 0)``: the force the
          sand exerts on the tool, against the motion in free raking.
        - ``torque_nm``: that force acting at the fingertip, ``sensor_height_m`` below the
          sensor origin: ``r x f`` with ``r = (0, 0, -sensor_height_m)``.
        """
        times = self._log_t
        if times and timestamp_s >= times[-1]:
            i = len(times) - 1
        else:
            i = bisect_right(times, timestamp_s) - 1
        if i < 0:
            x, y, heading, depth = self._origin
            return self._truth_record(0.0, x, y, depth, heading, 0.0, 0.0, 0.0, 0.0)
        x, y = self._log_pos[i]
        heading, speed, acceleration = self._log_motion[i]
        if i in self._rest_after and timestamp_s > times[i]:
            # Following a robot: between its movements it transits, lifted out of the sand.
            return self._truth_record(times[i], x, y, self._log_depth[i], heading, 0.0, 0.0,
                                      0.0, 0.0)
        fx, fy = self._log_force[i]
        return self._truth_record(
            times[i], x, y, self._log_depth[i], heading, speed, acceleration, fx, fy
        )

    def _truth_record(
        self,
        time_s: float,
        x: float,
        y: float,
        depth: float,
        heading: float,
        speed: float,
        acceleration: float,
        fx: float,
        fy: float,
    ) -> PhysicalTruth:
        cfg = self.config
        c, s = math.cos(heading), math.sin(heading)
        h = cfg.sensor_height_m
        return PhysicalTruth(
            timestamp_s=time_s,
            position_m=np.array([x, y, h - depth]),
            orientation_wxyz=np.array([math.cos(heading / 2), 0.0, 0.0, math.sin(heading / 2)]),
            linear_velocity_m_per_s=np.array([speed * c, speed * s, 0.0]),
            linear_acceleration_m_per_s2=np.array([acceleration * c, acceleration * s, 0.0]),
            angular_velocity_rad_per_s=np.zeros(3),
            force_n=np.array([fx, fy, 0.0]),
            # (0, 0, -h) x (fx, fy, 0)
            torque_nm=np.array([h * fy, -h * fx, 0.0]),
            end_effector_mass_kg=cfg.end_effector_mass_kg,
        )

    # --- ground truth --------------------------------------------------------------------

    @property
    def ground_truth(self) -> GroundTruthLog:
        """Every step so far: time, position, true state and force (a :class:`GroundTruthLog`)."""
        n = len(self._log_t)
        return GroundTruthLog(
            timestamps_s=np.asarray(self._log_t, dtype=np.float64),
            positions_m=np.asarray(self._log_pos, dtype=np.float64).reshape(n, 2),
            states=np.asarray(self._log_state, dtype=np.int64),
            forces_n=np.asarray(self._log_force, dtype=np.float64).reshape(n, 2),
            movement_index=np.asarray(self._log_index, dtype=np.int64),
            depth_m=np.asarray(self._log_depth, dtype=np.float64),
        )

    @property
    def scene(self) -> Scene:
        """The scene this sandbox holds (its buried objects)."""
        return self._scene

    @property
    def steps_taken(self) -> int:
        """Number of steps logged so far (all movements)."""
        return len(self._log_t)

    def true_forces_since(self, first: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Timestamps ``(k,)`` and true forces ``(k, 2)`` of steps ``first, first+1, ...``."""
        t = np.asarray(self._log_t[first:], dtype=np.float64)
        f = np.asarray(self._log_force[first:], dtype=np.float64).reshape(t.size, 2)
        return t, f

    def true_force_of_step(self, index: int) -> tuple[float, tuple[float, float]]:
        """Timestamp and true force ``(x, y)`` of step ``index`` (0-based, all movements)."""
        return self._log_t[index], self._log_force[index]

    @property
    def movements(self) -> tuple[MovementTruth, ...]:
        """Truth of every finished movement (a movement finishes at the next begin or end call)."""
        return tuple(self._movements)

    @property
    def current_depth_m(self) -> float:
        """Depth the next movement will use unless it commands its own."""
        return float(self._world.schedule_depth)

    @property
    def shear_band_angle_deg(self) -> float:
        return math.degrees(self._beta_rad)

    def _record(
        self, position: tuple[float, float], force: tuple[float, float], state: int
    ) -> float:
        """Log one step; returns the force magnitude."""
        # numpy's hypot (the C library's), not math.hypot, whose last bit can differ.
        magnitude = float(np.hypot(force[0], force[1]))
        if state >= JAMMING and math.isnan(self._jam_onset):
            self._jam_onset = self._time
        if state == CONTACT and math.isnan(self._contact_onset):
            self._contact_onset = self._time
        self._em_max_state = max(self._em_max_state, state)
        self._em_max_force = max(self._em_max_force, magnitude)
        self._max_force = max(self._max_force, magnitude)
        self._log_t.append(self._time)
        self._log_pos.append(position)
        self._log_state.append(state)
        self._log_force.append(force)
        self._log_index.append(self._em)
        self._log_depth.append(self._depth)
        return magnitude

    def _close_movement(self) -> None:
        """Book the current movement once: its truth record and the depth schedule."""
        if self._closed:
            return
        if self._followed is not None:
            self._halt_reason = self._followed.halt_reason
            if self._log_t:
                self._rest_after.add(len(self._log_t) - 1)
        self._closed = True
        self._active = False
        truth = MovementTruth(
            index=self._em,
            depth_m=self._depth,
            rupture_distance_m=self._rupture,
            side_crescent_angle_deg=math.degrees(self._eta_rad),
            start_time_s=self._em_start_time,
            end_time_s=self._time,
            jamming_onset_s=self._jam_onset,
            contact_onset_s=self._contact_onset,
            max_state=self._em_max_state,
            max_force_n=self._em_max_force,
            halt_reason=self._halt_reason,
        )
        self._movements.append(truth)
        self._world.part_closed(truth.interacted)
