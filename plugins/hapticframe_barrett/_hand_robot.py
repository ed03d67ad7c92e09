"""The ``barrett-hand`` robot: a BarrettHand holding a raking posture on a carrier robot.

A BarrettHand cannot rake a straight line by itself. In the dissertation's rigs a hand on an
arm held a posture ("two fingers were flexed toward the palm and a single finger was left
extended for raking") while the arm moved it. So this robot takes exactly one carrier robot
in its ``inputs`` (a ``barrett-wam``, a ``dynamixel`` gantry, a ``sandbox``...), reports it in
:attr:`~hapticframe.kinds.Robot.controlled_robots` (the run loop gives movements only to the
hand), and drives it itself:

- configure: open the CAN bus, wake pucks 11-14 (``STAT``), read ``VERS`` (property tables)
  and ``CTS`` (counts per motor turn);
- activate: ``HOLD`` (the pucks hold the posture in PID), home (``CMD HI``, fingers then
  spread), move to the raking posture, wait done-moving by ``MODE`` (bounded), verify every
  joint within ``posture_tolerance_rad``;
- :meth:`BarrettHandRobot.begin`: the carrier begins the same line ``offset_m`` shallower
  (the extended finger reaches that far below the carrier's tool point);
  :meth:`~BarrettHandRobot.step` steps the carrier and returns the fingertip's state, and
  every ``poll_every_steps`` steps polls the pucks: a joint pushed out of its posture (the
  sand pushed a finger back) or ``MODE`` forced to IDLE (an E-stop) halts the carrier and
  raises :class:`~hapticframe.devices.DeviceError`.

The fingertip offset is vertical only, by design: the carrier's kinematic model is expected
to put its tool point above the raking fingertip (in the map plane, the fingertip is where
the carrier's tool point is), and the posture does not change while raking, so the offset is
a constant of the posture. Heading, speed and plane position are the carrier's.

``channel: emulated`` runs a :class:`~._emulator.PuckBus` on a ``virtual`` channel of its
own (an :class:`~._bus.EmulatedCanPort`), on simulation time that follows the carrier's
timestamps:
homing and the posture move take simulation time, and a run is deterministic. Fault times
(``at_s``) are on that clock: it starts at configure and then moves on as the carrier's
timestamps do.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import can

from hapticframe.devices import (
    Clock,
    DeviceError,
    DeviceLifecycle,
    FaultSchedule,
)
from hapticframe.kinds import (
    BuildContext,
    EnvironmentCoupled,
    ExploratoryMovement,
    PhysicalTruthSource,
    Region,
    Robot,
    RobotState,
    RunOutcome,
)

from ._bus import CanPort, EmulatedCanPort
from ._emulator import EmulatedPuck, PuckBus, hand_pucks
from ._hand_config import BarrettHandRobotConfig, FingerGeometryConfig
from ._host import BarrettError, BarrettHandHost, PuckHost
from ._protocol import HAND_NODES, Cmd, Group, Mode, Stat

__all__ = ["STANDARD_FAULTS", "BarrettHandRobot", "fingertip_below_palm_m"]

#: ``faults: standard``: rare reply faults and error frames, each survived by a retry.
STANDARD_FAULTS: tuple[dict[str, Any], ...] = (
    {"kind": "late_reply", "rate_hz": 0.05},
    {"kind": "malformed_reply", "rate_hz": 0.05},
    {"kind": "duplicate_reply", "rate_hz": 0.05},
    {"kind": "missing_position", "rate_hz": 0.05},
    {"kind": "error_frame", "rate_hz": 0.05},
)
_NAMES = {11: "F1", 12: "F2", 13: "F3", 14: "spread"}
_SPREAD = 14


def fingertip_below_palm_m(geometry: FingerGeometryConfig, inner_rad: float) -> float:
    """How far below the palm (along its normal, palm down) a finger's tip lies when its
    inner joint is at ``inner_rad`` and the outer joint follows by the coupling."""
    outer = geometry.coupling * inner_rad + geometry.distal_offset_rad
    return geometry.proximal_m * math.sin(inner_rad) + geometry.distal_m * math.sin(
        inner_rad + outer)


def _schedule(faults: Any, rng: Any) -> FaultSchedule | None:
    if faults == "none":
        return None
    entries = STANDARD_FAULTS if faults == "standard" else faults
    return FaultSchedule.from_config([dict(e) for e in entries], rng)


class BarrettHandRobot(Robot, DeviceLifecycle):
    """A BarrettHand in a raking posture on a carrier robot (the one robot in ``inputs``).

    Parameters
    ----------
    config : BarrettHandRobotConfig
    context : BuildContext
        ``context.inputs`` holds the carrier; ``context.rng`` seeds the emulator's faults.

    Attributes
    ----------
    carrier : Robot
        The robot that moves the hand.
    port : CanPort
        The CAN channel (an :class:`~._bus.EmulatedCanPort` for ``channel: emulated``).
    clock : Clock
        The port's: simulation time that follows the carrier's timestamps when emulated,
        else the monotonic clock.
    emulator : PuckBus or None
        The emulated pucks (``channel: emulated``, after configure).
    host : PuckHost or None
        The host side of the bus (after configure); its counters go to :attr:`health`.
    targets : dict of int to int
        The posture in encoder counts, by puck (after configure).
    offset_m : float
        The fingertip's depth below the carrier's tool point (measured at activate).
    stats : dict of str to int
        ``polls``, ``estops``, ``displaced`` (a joint pushed out of the posture),
        ``missing_polls`` (polls without a puck's position), ``recovered`` (faults survived
        by a recovery).
    """

    def __init__(self, config: BarrettHandRobotConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self.config: BarrettHandRobotConfig = config
        robots = [c for c in context.inputs.values() if isinstance(c, Robot)]
        if len(robots) != 1 or len(context.inputs) != 1:
            given = ", ".join(f"{name!r} ({c.kind})" for name, c in context.inputs.items())
            raise ValueError(
                f"robot {context.id!r}: a barrett-hand needs exactly one input, the carrier "
                f"robot that moves it (an arm or a gantry); got {given or 'none'}"
            )
        self.carrier: Robot = robots[0]
        self.max_recoveries = config.max_recoveries
        self.live = not config.emulated
        self.port: CanPort = (
            EmulatedCanPort(self._emulated_pucks, name=f"hapticframe-barrett-hand-{self.id}")
            if config.emulated
            else CanPort(config.interface, config.channel, bitrate=config.bitrate))
        self.clock: Clock = self.port.clock
        self._rng = context.rng
        raking = 10 + config.raking_finger
        self._raking = raking
        self._flexed = tuple(n for n in HAND_NODES if n not in (raking, _SPREAD))
        self._angles = {node: config.flexed_angle_rad for node in self._flexed}
        self._angles[raking] = config.raking_angle_rad
        self._angles[_SPREAD] = config.spread_rad
        self.offset_m = config.palm_below_tool_point_m + fingertip_below_palm_m(
            config.finger, config.raking_angle_rad)
        self.host: PuckHost | None = None
        self._hand: BarrettHandHost | None = None
        self._counts_per_rad: dict[int, float] = {}
        self.targets: dict[int, int] = {}
        self.posture_rad: dict[int, float] = {}
        self.stats = {"polls": 0, "estops": 0, "displaced": 0, "missing_polls": 0,
                      "recovered": 0}
        self._missing: dict[int, int] = dict.fromkeys(HAND_NODES, 0)
        self._active = False
        self._halt_reason = ""
        self._steps = 0
        self._carrier_t = self.carrier.state.timestamp_s

    # --- Robot interface -----------------------------------------------------------------

    @property
    def control_rate_hz(self) -> float:
        return float(self.carrier.control_rate_hz)

    @property
    def state(self) -> RobotState:
        return self._fingertip(self.carrier.state)

    @property
    def halt_reason(self) -> str:
        return self._halt_reason

    @property
    def workspace(self) -> Region | None:
        """The carrier's workspace (the fingertip is where the carrier's tool point is, in
        the map plane); the carrier refuses a movement that leaves it."""
        return self.carrier.workspace

    @property
    def controlled_robots(self) -> tuple[Robot, ...]:
        return (self.carrier,)

    def begin(self, movement: ExploratoryMovement) -> None:
        self._active = False
        depth = movement.depth_m if movement.depth_m is not None else self.config.depth_m
        carrier_depth: float | None = None
        if depth is not None:
            carrier_depth = float(depth) - self.offset_m
            if not (math.isfinite(carrier_depth) and carrier_depth > 0):
                raise ValueError(
                    f"robot {self.id!r}: a fingertip depth of {depth:g} m puts the carrier "
                    f"{self.carrier.id!r} at depth {carrier_depth:.4g} m (the raking finger "
                    f"reaches {self.offset_m:.4g} m below its tool point); the carrier's "
                    "depth must be positive: rake deeper, or set palm_below_tool_point_m to "
                    "where the carrier's kinematic model puts its tool point"
                )
        self._require_active()
        self._halt_reason = ""
        self._guarded(self._check_hand)  # the posture holds before the carrier moves
        carried = ExploratoryMovement(
            movement.start_m, movement.end_m, movement.speed_m_per_s, depth_m=carrier_depth,
            phase=movement.phase, label=movement.label)
        try:
            self.carrier.begin(carried)
        except ValueError as exc:
            raise ValueError(
                f"robot {self.id!r}: its carrier {self.carrier.id!r} refused the movement "
                f"(carrier depth {_depth_text(carrier_depth)}, the fingertip "
                f"{self.offset_m:.4g} m deeper): {exc}"
            ) from exc
        self._steps = 0
        self._follow(self.carrier.state.timestamp_s)  # a transit to the start took time
        self._active = True

    def step(self) -> RobotState | None:
        if not self._active:
            return None
        carried = self.carrier.step()
        if carried is None:
            self._active = False
            self._halt_reason = self.carrier.halt_reason
            return None
        self._steps += 1
        self._follow(carried.timestamp_s)
        if self._steps % self.config.poll_every_steps == 0:
            self._guarded(self._check_hand)
        return self._fingertip(carried)

    def halt(self, reason: str) -> None:
        was_active = self._active
        self._active = False
        if was_active or not self._halt_reason:
            self._halt_reason = reason
        self.carrier.halt(reason)

    def couple_environment(self, environment: PhysicalTruthSource) -> None:
        """Let a simulated environment load the carrier's emulated actuators.

        Raises
        ------
        ValueError
            When the hand drives real pucks (a simulated force cannot load them), or the
            carrier is not an emulated robot that an environment can load.
        """
        if self.live:
            raise ValueError(
                f"robot {self.id!r} drives a real BarrettHand on {self.config.channel}: a "
                "simulated environment cannot load it (use channel 'emulated')"
            )
        if not isinstance(self.carrier, EnvironmentCoupled):
            raise ValueError(
                f"robot {self.id!r}: its carrier {self.carrier.id!r} "
                f"({type(self.carrier).__name__}) cannot be loaded by a simulated environment"
            )
        self.carrier.couple_environment(environment)

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        out: dict[str, Any] = dict(self.stats)
        if self.host is not None:
            out["bus"] = dict(self.host.stats)
        if self.emulator is not None:
            out["emulator"] = dict(self.emulator.stats)
        return {"barrett_hand": out}

    def close(self) -> None:
        """Release the hand (the carrier is the run's to close)."""
        self.deactivate()
        self.cleanup()

    @property
    def emulator(self) -> PuckBus | None:
        """The emulated pucks (``channel: emulated``, once configured), else None."""
        return self.port.emulator if isinstance(self.port, EmulatedCanPort) else None

    def _emulated_pucks(self) -> tuple[list[EmulatedPuck], FaultSchedule | None]:
        config = self.config
        nodes = HAND_NODES if config.emulated_nodes is None else config.emulated_nodes
        pucks = [p for p in hand_pucks(config.emulated_vers, speed=config.emulated_speed)
                 if p.node in nodes]
        return pucks, _schedule(config.faults, self._rng)

    # --- the fingertip -----------------------------------------------------------------------

    def _fingertip(self, carried: RobotState) -> RobotState:
        return RobotState(carried.timestamp_s, carried.position_m.copy(), carried.heading_rad,
                          float(carried.depth_m) + self.offset_m, carried.speed_m_per_s)

    def _follow(self, t: float) -> None:
        """The emulated pucks' time moves on as the carrier's does (its own waits, homing
        and recoveries, put it ahead of the carrier's, by design)."""
        dt = t - self._carrier_t
        self._carrier_t = max(self._carrier_t, t)
        if dt > 0:
            self.port.wait_until(self.clock.now() + dt)  # a port that owns time moves it

    # --- motion ----------------------------------------------------------------------------

    def _require_active(self) -> None:
        if self.lifecycle_state.value != "active":
            raise DeviceError(
                f"robot {self.id!r} is {self.lifecycle_state.value}: configure and activate it "
                "before moving", device_id=self.id)

    def _guarded(self, fn: Any) -> Any:
        """Run ``fn``; a DeviceError halts the carrier (no command follows) first."""
        try:
            return fn()
        except DeviceError:
            self._active = False
            self._halt_reason = "device_error"
            try:
                self.carrier.halt("device_error")
            except Exception:  # best effort: the hand's error is the one to report
                pass
            raise

    def _error(self, message: str) -> DeviceError:
        return DeviceError(f"robot {self.id!r}: {message}", device_id=self.id)

    def _check_hand(self) -> None:
        """Poll positions and MODE; a fault of the bus is recovered (bounded), then checked
        again; a finger out of its posture or an E-stop raises DeviceError."""
        try:
            self._poll_once()
        except BarrettError as exc:
            self.recover(exc)  # DeviceError once max_recoveries attempts failed
            self.stats["recovered"] += 1
            try:
                self._poll_once()
            except BarrettError as again:
                raise self._error(f"the hand's pucks fail after a recovery: {again}") from again

    def _poll_once(self) -> None:
        host, hand = self.host, self._hand
        assert host is not None and hand is not None
        self.stats["polls"] += 1
        if self.config.hold:
            modes = {node: host.get(node, "MODE") for node in HAND_NODES}
            idle = [node for node, mode in modes.items() if mode != int(Mode.PID)]
            if idle:
                self.stats["estops"] += 1
                names = ", ".join(f"{_NAMES[n]} (MODE {modes[n]})" for n in idle)
                raise self._error(
                    f"the hand stopped holding its posture: {names}, not PID with HOLD "
                    "(an E-stop or the safety system idled the pucks); the carrier is halted"
                )
        poll = host.poll_positions(int(Group.HAND), HAND_NODES)
        for node in HAND_NODES:
            if node in poll.positions:
                self._missing[node] = 0
                continue
            self._missing[node] += 1
            self.stats["missing_polls"] += 1
            if self._missing[node] >= self.config.max_missing_polls:
                raise self._error(
                    f"puck {node} ({_NAMES[node]}) sent no position in "
                    f"{self._missing[node]} polls in a row; the carrier is halted"
                )
        for node, counts in poll.positions.items():
            error = abs(counts - self.targets[node]) / self._counts_per_rad[node]
            if error > self.config.displacement_tolerance_rad:
                self.stats["displaced"] += 1
                raise self._error(
                    f"{_NAMES[node]} was pushed {error:.3f} rad out of the raking posture "
                    f"(tolerance {self.config.displacement_tolerance_rad:g} rad; the sand "
                    "pushed it back?); the carrier is halted"
                )

    # --- lifecycle hooks ---------------------------------------------------------------------

    def on_configure(self) -> None:
        config = self.config
        try:
            bus = self.port.open()
        except (can.CanError, OSError, ValueError) as exc:
            raise self._error(
                f"cannot open CAN channel {config.channel!r} ({config.interface}): {exc}"
            ) from exc
        self.host = PuckHost(bus, port=self.port, health=self.health,
                             reply_timeout_s=config.reply_timeout_s,
                             attempts=config.attempts, device_id=self.id)
        woke = self.host.wake(HAND_NODES)
        if not woke.ok:
            names = ", ".join(f"{n} ({_NAMES[n]})" for n in woke.failed)
            raise self._error(
                f"hand puck(s) {names} did not wake (STAT) on {config.channel}: check the "
                "hand's power and cable, and that its pucks have IDs 11-14"
            )
        try:
            self.host.identify(HAND_NODES)
            cts = {node: self.host.get(node, "CTS") for node in HAND_NODES}
        except BarrettError as exc:
            raise self._error(f"identifying the hand's pucks failed: {exc}") from exc
        geometry = config.finger
        for node in HAND_NODES:
            ratio = geometry.spread_ratio if node == _SPREAD else geometry.inner_ratio
            self._counts_per_rad[node] = cts[node] / (2 * math.pi) * ratio
            self.targets[node] = round(self._angles[node] * self._counts_per_rad[node])
        tolerance = min(round(config.posture_tolerance_rad * c)
                        for c in self._counts_per_rad.values())
        self._hand = BarrettHandHost(self.host, HAND_NODES, tolerance=max(1, tolerance))

    def on_activate(self) -> None:
        host, hand = self.host, self._hand
        assert host is not None and hand is not None
        config = self.config
        try:
            for node in HAND_NODES:
                if config.hold:
                    host.set(node, "HOLD", 1)
                hand.hold[node] = 1 if config.hold else host.get(node, "HOLD")
            if config.initialize:
                for part in (hand.fingers, hand.spread):
                    for node in part:
                        host.set(node, "CMD", int(Cmd.HI))
                    hand.wait_done(part, timeout_s=config.move_timeout_s)
            result = hand.move_to(self.targets, timeout_s=config.move_timeout_s)
        except BarrettError as exc:
            raise self._error(f"moving the hand to its raking posture failed: {exc}") from exc
        positions = dict(result.poll.positions)
        for _ in range(config.max_missing_polls):  # a position missing from that poll
            if all(node in positions for node in HAND_NODES):
                break
            positions.update({n: c for n, c in host.poll_positions(
                int(Group.HAND), HAND_NODES).positions.items() if n not in positions})
        for node in HAND_NODES:
            if node not in positions:
                raise self._error(f"puck {node} ({_NAMES[node]}) sent no position after the "
                                  "posture move")
            angle = positions[node] / self._counts_per_rad[node]
            error = abs(angle - self._angles[node])
            if error > config.posture_tolerance_rad:
                hint = "" if config.initialize else " (is the hand initialised? set initialize)"
                raise self._error(
                    f"{_NAMES[node]} ended the posture move at {angle:.3f} rad, "
                    f"{error:.3f} rad from its target {self._angles[node]:.3f} rad (MODE "
                    f"{result.modes.get(node)}){hint}"
                )
            self.posture_rad[node] = angle
        self.offset_m = config.palm_below_tool_point_m + fingertip_below_palm_m(
            config.finger, self.posture_rad[self._raking])
        self._missing = dict.fromkeys(HAND_NODES, 0)

    def on_deactivate(self) -> None:
        self._active = False
        try:
            self.carrier.halt("deactivate")
        finally:
            # Hand pucks' MODE is the host's (only arm pucks' MODE is the safety system's).
            if self.host is not None:
                try:
                    self.host.set_group(int(Group.HAND), HAND_NODES, "MODE", int(Mode.IDLE))
                except BarrettError:  # the bus is down: the pucks hold or idle on their own,
                    self.health.timeouts += 1  # and deactivation must go on to the carrier

    def on_cleanup(self) -> None:
        self._active = False
        if self.host is not None:
            self.host.bus.shutdown()
            self.host = None
            self._hand = None
        self.port.stop()

    def on_recover(self, error: Exception) -> None:
        """Wait a backoff on the hand's clock, then every puck must answer ``STAT`` READY
        (a bus that went off and came back, replies that were late or garbled)."""
        host = self.host
        if host is None:
            raise error
        backoff = self.config.recovery_backoff_s * 2 ** self.recovery_streak
        self.port.elapse(backoff)
        silent = [n for n in HAND_NODES if host.try_get(n, "STAT") != int(Stat.READY)]
        if silent:
            raise self._error(f"hand puck(s) {silent} do not answer after {error}")


def _depth_text(depth: float | None) -> str:
    return "its own" if depth is None else f"{depth:.4g} m"
