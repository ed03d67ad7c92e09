"""The ``barrett-wam`` robot: a Barrett WAM raking the fingertip along straight lines, at
trajectory level over the puck protocol (python-can).

Each control step sends the next joint targets (property ``M`` of each arm puck, in motor
counts through ``j2mp``), lets one control period pass, polls the positions with one group
``GET P`` (22-bit replies), reads one puck's ``MODE`` in turn, and turns the joints into the
:class:`~hapticframe.kinds.RobotState` by forward kinematics. The whole joint path of a
movement (the transit to its start, lifted above the surface, and the line itself) is solved
and checked in :meth:`BarrettWamRobot.begin` before anything moves: workspace, joint limits,
joint speeds and the links' height above the surface, at every IK point along the path.

Safety. ``MODE`` belongs to the WAM's safety system (Shift-Activate puts the pucks in a
position-holding mode, Shift-Idle and the E-stop force IDLE); the robot never sets it. It
refuses to activate unless every arm puck is in PID, and any puck found in another mode
(or a joint not following its target) ends the motion with a :class:`DeviceError` naming the
cause, with no command after it. ``halt()`` and ``deactivate()`` hold the present position
(``M`` = present counts); the arm is released only by the operator's Shift-Idle.

``channel: emulated`` runs a :class:`PuckBus` of WAM pucks on a ``virtual`` channel of this
robot's own (an :class:`~._bus.EmulatedCanPort`), on simulation time that each step moves by
one control period, so runs are deterministic. The emulated arm powers on zeroed
(counts = ``j2mp @ q``) in ``emulated_start_rad``, and the operator presses Shift-Activate
when the robot activates (:meth:`PuckBus.activate_wam`). The emulation does not model load:
the pucks are position sources, so :meth:`couple_environment` only records the joint torques
``τ = Jᵀ f`` that the environment's force would cause (:attr:`BarrettWamRobot.load_torque_nm`).

Unverified against hardware: that a WAM puck in PID follows ``M`` streamed at the control
rate (the emulator's model), and every property number (see ``_protocol``). Zeroing the arm is
left to Barrett's tools; packed-torque control is not implemented (``torque_control`` is
refused).
"""

from __future__ import annotations

import contextlib
import itertools
import math
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

import can
import numpy as np
from numpy.typing import NDArray

from hapticframe.devices import (
    Backoff,
    Clock,
    DeviceError,
    DeviceLifecycle,
    FaultSchedule,
)
from hapticframe.kinds import (
    BuildContext,
    ExploratoryMovement,
    PhysicalTruthSource,
    Robot,
    RobotState,
    RunOutcome,
)

from ._bus import CanPort, EmulatedCanPort
from ._emulator import EmulatedPuck, PuckBus
from ._host import BarrettError, PuckHost
from ._protocol import WAM_NODES, Group, Mode
from ._wam_config import BarrettWamConfig
from ._wam_kinematics import WAM4, WAM7, DHLink, SerialArm, Transmission

__all__ = ["STANDARD_FAULTS", "BarrettWamRobot", "EStop", "NotFollowing"]

#: ``faults: standard``: rare puck faults, each survived.
STANDARD_FAULTS: tuple[dict[str, Any], ...] = (
    {"kind": "missing_position", "rate_hz": 0.05},
    {"kind": "error_frame", "rate_hz": 0.05},
    {"kind": "duplicate_reply", "rate_hz": 0.05},
    {"kind": "malformed_reply", "rate_hz": 0.05},
)

T = TypeVar("T")
FloatArray = NDArray[np.float64]


class EStop(DeviceError):
    """An arm puck left the position-holding mode: the E-stop, Shift-Idle or a puck fault."""


class NotFollowing(DeviceError):
    """The joints stopped following their targets (an E-stop, a collision, a puck fault)."""


class _PollFailed(RuntimeError):
    """A position poll without every puck's reply."""


def _unit(movement: ExploratoryMovement) -> FloatArray:
    return np.array([math.cos(movement.heading_rad), math.sin(movement.heading_rad)])


class BarrettWamRobot(Robot, DeviceLifecycle):
    """A Barrett WAM moving the fingertip along straight lines at constant speed and depth.

    Parameters
    ----------
    config : BarrettWamConfig
    context : BuildContext
        ``context.rng`` seeds the emulator's faults.

    Attributes
    ----------
    arm : SerialArm
        The kinematic model, in the map frame.
    transmission : Transmission or None
        Joints ↔ motor counts (after configure, once each puck's ``CTS`` is read).
    port : CanPort
        The CAN channel (an :class:`~._bus.EmulatedCanPort` for ``channel: emulated``).
    clock : Clock
        The port's: simulation time when emulated, else the monotonic clock.
    emulator : PuckBus or None
        The emulated pucks (``channel: emulated``, after configure).
    host : PuckHost or None
        The puck protocol over the bus (after configure).
    joints_rad : (n,) float64
        The joints at the latest poll.
    load_torque_nm : (n,) float64
        ``Jᵀ f`` of a coupled environment's force at the latest step (zero uncoupled).
    stats : dict of str to int
        ``targets_sent`` (SET M frames), ``polls``, ``poll_retries``, ``mode_checks``,
        ``mode_unread``, ``estops``, ``not_following``.
    """

    def __init__(self, config: BarrettWamConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self.config: BarrettWamConfig = config
        self.max_recoveries = config.max_recoveries
        preset = WAM4 if config.arm == "wam4" else WAM7
        links = preset.links if config.dh is None else tuple(
            DHLink(r.a_m, r.alpha_rad, r.d_m, r.theta_offset_rad) for r in config.dh)
        self.arm = SerialArm(
            links,
            preset.tool_offset_m if config.tool_offset_m is None else config.tool_offset_m,
            preset.limits_rad if config.joint_limits_rad is None else config.joint_limits_rad,
            config.base_position_m, config.base_yaw_rad,
            preset.tool_axis if config.tool_axis is None else config.tool_axis)
        self._j2mp = np.array(preset.j2mp if config.j2mp is None else config.j2mp)
        Transmission(self._j2mp, 4096)  # checked at build: invertible
        self._seed = np.array(preset.ik_seed_rad if config.ik_seed_rad is None
                              else config.ik_seed_rad, dtype=np.float64)
        self.nodes: tuple[int, ...] = WAM_NODES[: self.arm.n]
        self._workspace = config.workspace.to_region()
        self._dt = 1.0 / config.control_rate_hz
        self.live = not config.emulated
        self.port: CanPort = (
            EmulatedCanPort(self._emulated_pucks, name=f"hapticframe-wam-{self.id}")
            if config.emulated else CanPort(config.interface, config.channel))
        self.clock: Clock = self.port.clock
        self._rng = context.rng
        self.host: PuckHost | None = None
        self.transmission: Transmission | None = None
        self._environment: PhysicalTruthSource | None = None
        self.stats = dict.fromkeys(("targets_sent", "polls", "poll_retries", "mode_checks",
                                    "mode_unread", "estops", "not_following"), 0)
        self._backoff = list(Backoff(config.recovery_backoff_s, 2.0, 1.0,
                                     attempts=config.max_recoveries))
        center = self._workspace.center_m
        self._ready = np.array([center[0], center[1], config.transit_height_m])
        self.joints_rad = self._seed.copy()
        self.load_torque_nm = np.zeros(self.arm.n)
        self._target = self._seed.copy()
        self._state = RobotState(0.0, center, 0.0, config.depth_m, 0.0)
        self._tip = np.array([*center, -config.depth_m])
        self._active = False
        self._halt_reason = ""
        self._lagging = 0
        self._mode_turn = 0
        self._steps = 0
        self._transit_speed = config.transit_speed_m_per_s
        self._stopped = False  # the safety system stopped the arm: send nothing until activate

    # --- Robot interface (the base checks depth and workspace, then calls _begin) ------------

    def _begin(self, movement: ExploratoryMovement, depth: float) -> None:
        self._active = False
        config = self.config
        self._require_active()
        start = np.array([*movement.start_m, -depth])
        end = np.array([*movement.end_m, -depth])
        # The whole path is solved and checked before any command.
        transit = self._transit_points(start)
        transit_q = self._plan(transit, self.joints_rad, "the transit to its start")
        self._check_speed(transit_q, transit, config.transit_speed_m_per_s, "the transit",
                          refuse=False)
        line = _samples(start, end, config.ik_step_m)
        line_q = self._plan(line, transit_q[-1], "the movement")
        if np.max(np.abs(line_q[0] - transit_q[-1])) > config.following_error_rad:
            raise ValueError(  # the line's IK had to start over in another posture
                f"robot {self.id!r}: the movement starts in a posture the transit does not end "
                f"in (IK branch change at {_where(start)}): move the start or the base")
        self._check_speed(line_q, line, float(movement.speed_m_per_s), "the movement",
                          refuse=True)
        self._halt_reason = ""
        self._guarded(lambda: self._run_transit(transit, transit_q))
        self._knots_q = line_q
        self._knots_s = np.linalg.norm(line - line[0], axis=1)
        self._start, self._end = start, end
        self._length = float(np.linalg.norm(end - start))
        self._speed = float(movement.speed_m_per_s)
        self._heading = movement.heading_rad
        self._travelled = 0.0
        self._extra = 0
        self._active = True

    def step(self) -> RobotState | None:
        if not self._active:
            return None
        result: RobotState = self._guarded(self._step)
        return result

    def halt(self, reason: str) -> None:
        was_active = self._active
        self._active = False
        if was_active or not self._halt_reason:
            self._halt_reason = reason
        if self.lifecycle_state.value != "active" or self.host is None:
            return
        with contextlib.suppress(Exception):  # best effort: the pucks hold their last target
            self._hold()

    def couple_environment(self, environment: PhysicalTruthSource) -> None:
        """Record the joint torques the environment's force causes (the emulation does not
        model load: the pucks keep following their targets).

        Raises
        ------
        ValueError
            On a real arm: a simulated force cannot load real motors.
        """
        if not self.config.emulated:
            raise ValueError(
                f"robot {self.id!r} drives a real WAM on {self.config.channel!r}: a simulated "
                "environment cannot load its motors (couple only channel 'emulated')")
        self._environment = environment

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        host = self.host
        out: dict[str, Any] = {**self.stats, "health": self.health.as_dict()}
        if host is not None:
            out["bus"] = dict(host.stats)
        if self.emulator is not None:
            out["emulator"] = dict(self.emulator.stats)
        return {"barrett_wam": out}

    def close(self) -> None:
        self.deactivate()
        self.cleanup()

    # --- planning ----------------------------------------------------------------------------

    def _transit_points(self, start: FloatArray) -> FloatArray:
        """Up from the present fingertip to the transit height, across, down to ``start``."""
        here = self._tip
        lift = max(float(here[2]), self.config.transit_height_m)
        if np.linalg.norm(here[:2] - start[:2]) <= self.config.tolerance_m:
            return _samples(here, start, self.config.ik_step_m)
        corners = [here, np.array([*here[:2], lift]), np.array([*start[:2], lift]), start]
        legs = [_samples(a, b, self.config.ik_step_m) for a, b in itertools.pairwise(corners)]
        return np.vstack([legs[0], *(leg[1:] for leg in legs[1:])])

    def _plan(self, points: FloatArray, seed: FloatArray, what: str) -> FloatArray:
        """Joints for each point, checked: reachable, within limits, links above the surface."""
        config = self.config
        tol, gain = config.ik_tolerance_m, config.pointing_gain
        q, errors = self.arm.solve_line(points, seed, tolerance_m=tol, pointing_gain=gain)
        if errors.max() > tol:
            # The present posture may lead into a poor branch: start over from the seed.
            first = self.arm.solve(points[0], self._seed, min_iterations=50, tolerance_m=tol,
                                   pointing_gain=gain)
            q, errors = self.arm.solve_line(points, first.q, tolerance_m=tol, pointing_gain=gain)
        bad = int(np.argmax(errors))
        if errors[bad] > config.ik_tolerance_m:
            raise ValueError(
                f"robot {self.id!r}: {what} passes {_where(points[bad])}, which the arm does not "
                f"reach (IK error {errors[bad]:.3g} m)")
        inside = self.arm.within_limits(q)
        if not inside.all():
            i = int(np.argmin(inside))
            lo, hi = self.arm.limits[:, 0], self.arm.limits[:, 1]
            joint = int(np.argmax((q[i] < lo) | (q[i] > hi)))
            raise ValueError(
                f"robot {self.id!r}: {what} needs joint {joint + 1} at {q[i, joint]:.3f} rad at "
                f"{_where(points[i])}, beyond its limits {lo[joint]:g}...{hi[joint]:g} rad")
        for qi, point in zip(q, points, strict=True):
            self._check_links(qi, point, what)
        return q

    def _check_links(self, q: FloatArray, point: FloatArray, what: str) -> None:
        heights = self.arm.link_points(q)[1:-1, 2]
        low = float(heights.min())
        if low < self.config.min_link_height_m:
            raise ValueError(
                f"robot {self.id!r}: {what} brings a joint of the arm to {low:.3f} m above the "
                f"surface at {_where(point)} (min_link_height_m {self.config.min_link_height_m}"
                " m): move the base or the workspace")

    def _check_speed(self, q: FloatArray, points: FloatArray, speed: float, what: str,
                     refuse: bool) -> None:
        if len(q) < 2:
            return
        ds = np.linalg.norm(np.diff(points, axis=0), axis=1)
        rate = np.max(np.abs(np.diff(q, axis=0)), axis=1) / np.maximum(ds, 1e-12) * speed
        worst = int(np.argmax(rate))
        if rate[worst] > self.config.max_joint_speed_rad_per_s:
            if refuse:
                raise ValueError(
                    f"robot {self.id!r}: {what} at {speed:g} m/s needs a joint at "
                    f"{rate[worst]:.3g} rad/s near {_where(points[worst])} (limit "
                    f"{self.config.max_joint_speed_rad_per_s:g} rad/s): slower, or elsewhere")
            self._transit_speed = speed * self.config.max_joint_speed_rad_per_s / rate[worst]
        elif not refuse:
            self._transit_speed = speed

    # --- motion ----------------------------------------------------------------------------

    def _require_active(self) -> None:
        if self.lifecycle_state.value != "active":
            raise DeviceError(
                f"robot {self.id!r} is {self.lifecycle_state.value}: configure and activate it "
                "before moving", device_id=self.id)

    def _guarded(self, fn: Callable[[], T]) -> T:
        """Run ``fn``; a DeviceError ends the motion (no further command)."""
        try:
            return fn()
        except DeviceError:
            self._active = False
            self._halt_reason = "device_error"
            raise

    def _run_transit(self, points: FloatArray, q: FloatArray) -> None:
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
        total = float(s[-1])
        steps = math.ceil(total / (self._transit_speed * self._dt)) if total > 0 else 0
        for i in range(1, steps + 1):
            self._move(_interp(s, q, total * i / steps), paced=True)
        for _ in range(self.config.settle_steps):
            if np.linalg.norm(self._tip - points[-1]) <= self.config.tolerance_m:
                break
            self._move(q[-1], paced=True)
        self._publish(0.0, self._state.heading_rad)

    def _step(self) -> RobotState:
        self._travelled = min(self._travelled + self._speed * self._dt, self._length)
        previous = self._tip[:2].copy()
        self._move(_interp(self._knots_s, self._knots_q, self._travelled), paced=False)
        speed = float(np.linalg.norm(self._tip[:2] - previous)) / self._dt
        state = self._publish(speed, self._heading)
        if self._travelled >= self._length:
            if np.linalg.norm(self._tip - self._end) <= self.config.tolerance_m:
                self._active = False
            else:
                self._extra += 1
                if self._extra >= self.config.settle_steps:
                    self._active = False
                    self._halt_reason = "not_settled"
        return state

    def _move(self, q_target: FloatArray, paced: bool) -> None:
        """Send ``q_target``, let one control period pass, read the joints back and check
        that the arm is active and following."""
        self._send_targets(q_target)
        self._tick(paced)
        q = self._read_joints()
        self._steps += 1
        every = self.config.mode_check_every
        if every and self._steps % every == 0:
            self._check_mode()
        error = float(np.max(np.abs(q - q_target)))
        self._lagging = self._lagging + 1 if error > self.config.following_error_rad else 0
        if self._lagging >= self.config.following_steps:
            self.stats["not_following"] += 1
            self._stopped = True
            raise NotFollowing(
                f"robot {self.id!r}: the joints are {error:.3g} rad from their targets after "
                f"{self._lagging} steps: the arm is not following (E-stop, collision or a puck "
                "fault?); check the arm, then press Shift-Activate and reconfigure",
                device_id=self.id)
        self._load()

    def _tick(self, paced: bool) -> None:
        until = self.clock.now() + self._dt
        self.port.wait_until(until)  # a port that owns time (the emulator's) moves it
        remaining = until - self.clock.now()
        if paced and remaining > 0:
            self.clock.sleep(remaining)

    def _publish(self, speed: float, heading: float) -> RobotState:
        tip = self._tip
        self._state = RobotState(self.clock.now(), tip[:2].copy(), heading, float(-tip[2]),
                                 speed)
        return self._state

    def _load(self) -> None:
        env = self._environment
        if env is None:
            return
        force = np.asarray(env.physical_truth(self.clock.now()).force_n, dtype=np.float64)
        jac, *_ = self.arm.jacobian(self.joints_rad)
        self.load_torque_nm = jac.T @ force

    # --- the bus -------------------------------------------------------------------------

    def _need_host(self) -> PuckHost:
        if self.host is None or self.transmission is None:
            raise DeviceError(f"robot {self.id!r}: not configured", device_id=self.id)
        return self.host

    def _send_targets(self, q: FloatArray) -> None:
        self._need_host()
        assert self.transmission is not None
        counts = self.transmission.counts(q)
        self._transact("sending joint targets", lambda: self._set_all("M", counts))
        self._target = np.asarray(q, dtype=np.float64).copy()

    def _set_all(self, name: str, counts: NDArray[np.int64]) -> None:
        host = self._need_host()
        if self._stopped:
            raise EStop(f"robot {self.id!r}: the safety system stopped the arm; activate it "
                        "again before sending targets", device_id=self.id)
        for node, value in zip(self.nodes, counts.tolist(), strict=True):
            host.set(node, name, int(value))
            if name == "M":
                self.stats["targets_sent"] += 1

    def _poll(self) -> FloatArray:
        host = self._need_host()
        assert self.transmission is not None
        self.stats["polls"] += 1
        poll = host.poll_positions(int(Group.WAM), self.nodes,
                                   timeout_s=self.config.position_timeout_s)
        if poll.missing:
            raise _PollFailed(f"pucks {list(poll.missing)} did not answer the position poll")
        q = self.transmission.joints([poll.positions[n] for n in self.nodes])
        self.joints_rad = q
        self._tip = self.arm.forward(q)
        return q

    def _read_joints(self) -> FloatArray:
        result: FloatArray = self._transact("the position poll", self._poll)
        return result

    def _transact(self, what: str, attempt: Callable[[], T]) -> T:
        """``attempt()`` retried, then the bus recovered (bounded), then once more."""
        error: Exception = _PollFailed(what)
        for i in range(self.config.max_retries + 1):
            if i:
                self.stats["poll_retries"] += 1
            try:
                return attempt()
            except (_PollFailed, BarrettError) as exc:
                error = exc
        try:
            self.recover(error)
        except DeviceError as exc:
            raise DeviceError(f"robot {self.id!r}: {what} failed: {exc}",
                              device_id=self.id) from exc
        try:
            return attempt()
        except (_PollFailed, BarrettError) as exc:
            raise DeviceError(f"robot {self.id!r}: {what} failed after a recovery: {exc}",
                              device_id=self.id) from exc

    def _check_mode(self) -> None:
        """One puck's MODE, in turn: anything but PID is the safety system stopping the arm."""
        host = self._need_host()
        node = self.nodes[self._mode_turn % len(self.nodes)]
        self._mode_turn += 1
        self.stats["mode_checks"] += 1
        mode = host.try_get(node, "MODE")
        if mode is None:
            self.stats["mode_unread"] += 1  # counted; the next check reads another puck
            return
        if mode != int(Mode.PID):
            self.stats["estops"] += 1
            self._stopped = True
            raise EStop(
                f"robot {self.id!r}: WAM puck {node} is in MODE {_mode_name(mode)}, not PID: the "
                "safety system stopped the arm (E-stop or Shift-Idle). Nothing more is sent; "
                "clear the stop, press Shift-Activate and reconfigure the robot",
                device_id=self.id)

    def _hold(self) -> None:
        """Targets = present positions: the arm holds where it is."""
        assert self.transmission is not None
        q = self._poll()
        self._set_all("M", self.transmission.counts(q))

    # --- lifecycle hooks -------------------------------------------------------------------

    def on_configure(self) -> None:
        config = self.config
        try:
            bus = self.port.open()
        except (can.CanError, OSError, ValueError) as exc:
            raise DeviceError(
                f"robot {self.id!r}: cannot open CAN channel {self.port.channel!r} "
                f"({config.interface}): {exc}", device_id=self.id) from exc
        channel = self.port.channel
        host = PuckHost(bus, port=self.port, health=self.health,
                        reply_timeout_s=config.reply_timeout_s, attempts=config.attempts,
                        wake_time_s=config.wake_time_s, device_id=self.id)
        self.host = host
        woke = host.wake(self.nodes)
        if not woke.ok:
            raise DeviceError(
                f"robot {self.id!r}: WAM pucks {list(woke.failed)} on {channel!r} did not wake "
                "(STAT stays RESET or no reply): check the arm's power, the CAN cable and "
                "the pendant", device_id=self.id)
        host.identify(self.nodes)
        cts = [host.get(node, "CTS") for node in self.nodes]
        try:
            self.transmission = Transmission(self._j2mp, cts)
        except ValueError as exc:
            raise DeviceError(f"robot {self.id!r}: {exc}", device_id=self.id) from exc
        self._read_joints()
        self._target = self.joints_rad.copy()
        self._publish(0.0, 0.0)

    def on_activate(self) -> None:
        host = self._need_host()
        if self.emulator is not None and self.config.emulated_operator_activates:
            self.emulator.activate_wam()  # the operator presses Shift-Activate
        for node in self.nodes:
            mode = host.get(node, "MODE")
            if mode != int(Mode.PID):
                raise EStop(
                    f"robot {self.id!r}: WAM puck {node} is in MODE {_mode_name(mode)}: the arm "
                    "is not active. Press Shift-Activate on the pendant (the safety system "
                    "owns MODE; this robot never sets it), then activate again",
                    device_id=self.id)
        self._stopped = False
        self._hold()
        self._target = self.joints_rad.copy()
        self._lagging = 0
        self._publish(0.0, self._state.heading_rad)

    def on_deactivate(self) -> None:
        self._active = False
        if self.host is not None and self.transmission is not None:
            with contextlib.suppress(Exception):  # best effort: the pucks hold their target
                self._hold()

    def on_cleanup(self) -> None:
        self._active = False
        if self.host is not None:
            with contextlib.suppress(Exception):
                self.host.bus.shutdown()
            self.host = None
        self.port.stop()

    def on_recover(self, error: Exception) -> None:
        """Wait a backoff on the robot's clock, reopen the bus after a link failure, and
        require a complete position poll on a bus that is not off."""
        host = self._need_host()
        delay = self._backoff[min(self.recovery_streak, len(self._backoff) - 1)]
        self.clock.sleep(delay)
        if isinstance(error.__cause__, can.CanError):  # the link failed (send or receive)
            with contextlib.suppress(Exception):
                host.bus.shutdown()
            host.bus = self.port.open()
            self.health.reconnects += 1
        host._drain()  # error frames: a restarted bus clears bus_off
        if host.bus_off:
            raise BarrettError(f"robot {self.id!r}: the CAN bus is off", device_id=self.id)
        self._poll()

    @property
    def emulator(self) -> PuckBus | None:
        """The emulated pucks (``channel: emulated``, once configured), else None."""
        return self.port.emulator if isinstance(self.port, EmulatedCanPort) else None

    def _emulated_pucks(self) -> tuple[list[EmulatedPuck], FaultSchedule | None]:
        config = self.config
        schedule = None
        if config.faults != "none":
            entries = STANDARD_FAULTS if config.faults == "standard" else config.faults
            schedule = FaultSchedule.from_config([dict(e) for e in entries], self._rng)
        if config.emulated_start_rad is not None:
            start = np.array(config.emulated_start_rad, dtype=np.float64)
        else:
            start = self.arm.solve(self._ready, self._seed, min_iterations=50,
                                   pointing_gain=config.pointing_gain).q
        counts = Transmission(self._j2mp, 4096).counts(start)
        pucks = [EmulatedPuck(node, vers=config.emulated_vers, position=int(c),
                              speed=config.emulated_speed_counts_per_s, hand=False)
                 for node, c in zip(self.nodes, counts.tolist(), strict=True)]
        return pucks, schedule


def _samples(a: FloatArray, b: FloatArray, spacing: float) -> FloatArray:
    """Points from ``a`` to ``b`` (both included) at most ``spacing`` apart."""
    n = max(1, math.ceil(float(np.linalg.norm(b - a)) / spacing))
    return a + (b - a) * np.linspace(0.0, 1.0, n + 1)[:, None]


def _interp(s: FloatArray, q: FloatArray, at: float) -> FloatArray:
    """Joints at arc length ``at`` (linear between the IK points; limits are a box, so
    in between stays within them)."""
    if len(s) == 1 or at <= 0:
        return np.asarray(q[0], dtype=np.float64).copy()
    return np.array([np.interp(at, s, q[:, j]) for j in range(q.shape[1])])


def _where(point: FloatArray) -> str:
    level = f"depth {-point[2]:.3f} m" if point[2] <= 0 else f"{point[2]:.3f} m above the surface"
    return f"({point[0]:.3f}, {point[1]:.3f}) m at {level}"


def _mode_name(mode: int) -> str:
    try:
        return Mode(mode).name
    except ValueError:
        return str(mode)
