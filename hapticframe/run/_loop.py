"""The run loop: a closed loop of exploratory movements, or an open loop over sensors.

It decides when the perception chain ticks; :class:`~hapticframe.run._dataflow.Dataflow`
knows how samples become features, probabilities, observations and map updates. Calls go
one way: the orchestrator (:mod:`hapticframe.run._run`) calls :func:`run_loop`, which calls the
dataflow and the components; nothing here writes files or scores results.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping

from hapticframe._errors import RunError
from hapticframe.kinds import (
    Component,
    Device,
    ExploratoryMovement,
    MovementResult,
    Planner,
    Robot,
    RobotState,
)
from hapticframe.run._channels import SAFETY_HALT
from hapticframe.run._clock_check import STREAM_OUT_OF_STEP, StepCheck
from hapticframe.run._dataflow import Dataflow
from hapticframe.run._robots import WORKSPACE_LIMIT, RobotTeam, workspace_of
from hapticframe.run._safety import (
    FORCE_LIMIT,
    FORCE_STREAM_STALLED,
    OUTSIDE_WORKSPACE,
    SafetyMonitor,
)
from hapticframe.run._session import Session

__all__ = ["device_faults", "devices_of", "run_loop"]

#: The wall clock that paces live runs (tests replace both).
_monotonic: Callable[[], float] = time.monotonic
_sleep: Callable[[float], None] = time.sleep


def devices_of(components: Mapping[str, Component]) -> dict[str, Device]:
    """The components that are devices (:class:`~hapticframe.kinds.Device`), in build order."""
    return {cid: c for cid, c in components.items() if isinstance(c, Device)}


def device_faults(devices: Mapping[str, Device]) -> str:
    """`` | wrist: crc_errors 3, resyncs 12`` for the devices with non-zero fault counters
    (``""`` when none has any)."""
    parts = []
    for cid, device in devices.items():
        faults = {k: v for k, v in device.health.faults().items() if v}
        if faults:
            parts.append(f"{cid}: " + ", ".join(f"{k} {v}" for k, v in faults.items()))
    return "".join(f" | {part}" for part in parts)


class _Pacer:
    """Waits on the wall clock so that ticks start at most every ``period_s`` seconds.

    Only a run with a live device is paced (real hardware delivers samples in real time;
    reading it faster only spins); simulated and emulated runs go as fast as they can.
    A late tick is not made up for by a burst: the schedule restarts from it.
    """

    def __init__(self, period_s: float | None) -> None:
        self.period_s = period_s
        self._last: float | None = None

    def wait(self) -> None:
        if self.period_s is None:
            return
        now = _monotonic()
        if self._last is not None:
            due = self._last + self.period_s
            if now < due:
                _sleep(due - now)
                self._last = due
                return
        self._last = now


def _pacer(devices: Mapping[str, Device], period_s: float) -> _Pacer:
    live = any(bool(device.live) for device in devices.values())
    return _Pacer(period_s if live else None)


def run_loop(session: Session) -> None:
    """Run the closed loop (a planner and a robot) or the open loop (sensors only)."""
    planners = list(session.components.planners.values())
    robots = list(session.components.robots.values())
    flow = Dataflow(session.experiment, session.components, session.recorder,
                    session.training_sensors)
    flow.recording = session.recording
    if planners or robots:
        if len(planners) != 1 or not robots:
            raise RunError(
                "a closed-loop run needs exactly one planner and at least one robot "
                f"(found {len(planners)} planner(s) and {len(robots)} robot(s))"
            )
        _closed_loop(session, flow, planners[0], robots)
    else:
        _open_loop(session, flow)
    # The maps' last state, which the snapshot rate may have left out.
    flow.snapshot_maps(final=True)


def _closed_loop(
    session: Session, flow: Dataflow, planner: Planner, robots: list[Robot]
) -> None:
    settings = session.settings
    limit = min(settings.max_movements, planner.max_movements)
    team = RobotTeam(robots, flow)
    robots = team.robots  # those that take movements
    rewindable = [session.components[i] for i in flow.rewindable]
    lookahead = settings.lookahead_steps
    devices = devices_of(session.components)
    # A live device: each robot step waits for its control period on the wall clock.
    pacers = {r.id: _pacer(devices, 1.0 / r.control_rate_hz) for r in robots}
    if any(p.period_s is not None for p in pacers.values()):
        lookahead = 1
    safety = SafetyMonitor(settings, flow, session.safety_halts,
                           live=any(bool(d.live) for d in devices.values()))
    # Every streamed sensor is held to the robot's time (the run's clock).
    flow.step_check = StepCheck(
        session.components.clock, {sid: session.components.sensors[sid] for sid in flow.sensors}
    )
    try:
        _movements(session, flow, planner, team, robots, limit, rewindable, lookahead,
                   devices, pacers, safety)
    finally:
        safety.close()


def _movements(
    session: Session, flow: Dataflow, planner: Planner, team: RobotTeam, robots: list[Robot],
    limit: int, rewindable: list[Component], lookahead: int, devices: Mapping[str, Device],
    pacers: Mapping[str, _Pacer], safety: SafetyMonitor,
) -> None:
    settings = session.settings
    for index in range(limit):
        movement = planner.propose()
        if movement is None:
            session.details["ended_by"] = "the planner proposed no further movement"
            return
        # The movement's parts: one robot's, or several when one robot's workspace ends.
        robot = team.pick(movement.start_m, movement.end_m)
        if robot is None:  # no workspace holds its start: refused before any motion
            _refuse_outside_workspace(session, robots, movement, index, devices)
            continue
        flow.start_stream()
        part = movement
        used: list[Robot] = []
        steps = 0
        resumes = 0
        reason = ""
        while robot is not None:
            part, cut = team.part_for(robot, part)
            used.append(robot)
            part = team.begin(robot, part)
            flow.locate_from(robot.state.timestamp_s)
            safety.begin(robot, index)
            chain: list[Component] = [robot, *team.followers.get(robot.id, ()), *rewindable]
            if lookahead > 1 and any(c.checkpoint() is None for c in chain):
                lookahead = 1  # a component that cannot rewind: one step at a time
            taken, halted_by_loop = _movement(
                session, flow, robot, index, chain, lookahead, pacers[robot.id], safety,
                team.stepper(robot),
            )
            safety.end()
            steps += taken
            team.after_part(robot, taken)
            reason = halted_by_loop or robot.halt_reason
            if reason == FORCE_STREAM_STALLED and resumes < settings.stall_resumes:
                # A stalled sensor (replugged, resyncing) halted the line: the same robot
                # continues it from where it stopped, once per stall, the parts one movement.
                rest = team.resumption(movement, robot)
                if rest is not None:
                    resumes += 1
                    flow.flush_maps()
                    flow.start_stream(keep_force=True)
                    part, reason = rest, ""
                    continue
            if not (reason == WORKSPACE_LIMIT or (cut and not reason)):
                break
            # The robot stopped at its workspace limit: another continues the line.
            reason = WORKSPACE_LIMIT
            flow.flush_maps()
            following = team.continuation(movement, robot, used)
            if following is None:
                break
            reason = ""
            robot, part = following
            # The next arm's sensor: a new stream for the classifier, the same movement.
            flow.start_stream(keep_force=True)
        flow.flush_maps()
        result = MovementResult(
            index=index,
            movement=movement,
            halted=bool(reason),
            halt_reason=reason,
            final_state=used[-1].state if used else None,
            final_class=flow.latest_class(),
            max_force_n=flow.force_max_n,
            extra={
                **({"robots": tuple(r.id for r in used)} if team.several else {}),
                **({"stall_resumes": resumes} if resumes else {}),
            },
        )
        session.movements.append(result)
        _record_movement(session, result, devices)
        _note_force(session, flow.force_max_n)
        _progress(session, result, steps, devices, team.path_label(used))
        for component in session.components.values():
            component.on_movement_end(result)
        if reason == STREAM_OUT_OF_STEP:
            _end_out_of_step(session, flow)
            return
    session.details["ended_by"] = (
        f"run.max_movements ({limit})" if limit == settings.max_movements
        else f"the planner's max_movements ({limit})"
    )
    session.echo(f"stopped after {limit} movements (the movement limit)")


def _end_out_of_step(session: Session, flow: Dataflow) -> None:
    """A stream ran out of step with the robot: the search ends here, as no result."""
    fault = flow.step_check.fault if flow.step_check is not None else None
    if fault is None:
        return
    session.details["out_of_step"] = dict(fault)
    session.safety_halts.append(dict(fault))
    session.echo(f"stopped: {fault['detail']}")


def _refuse_outside_workspace(
    session: Session, robots: list[Robot], movement: ExploratoryMovement, index: int,
    devices: Mapping[str, Device],
) -> None:
    """Refuse, before any ``begin``, a movement that starts where no robot's workspace
    reaches: it is recorded as halted (``outside_workspace``, no steps) and every component,
    the planner included, sees the result. (A movement that starts inside and leaves is
    raked to the workspace limit instead, and continued by another robot when one can.)"""
    x, y = (float(v) for v in movement.start_m)
    limits = "; ".join(
        f"{r.id!r}: x {w.x_min_m:g}...{w.x_max_m:g} m, y {w.y_min_m:g}...{w.y_max_m:g} m"
        for r in robots if (w := workspace_of(r)) is not None
    )
    why = (
        f"no robot's workspace holds its start ({x:.4g}, {y:.4g}) m and the line on from it "
        f"({limits})"
    )
    result = MovementResult(
        index=index, movement=movement, halted=True, halt_reason=OUTSIDE_WORKSPACE,
        final_state=robots[0].state, extra={"refused": why},
    )
    session.movements.append(result)
    session.safety_halts.append({
        "reason": OUTSIDE_WORKSPACE, "robots": [r.id for r in robots], "movement": index,
        "detail": why,
    })
    _record_movement(session, result, devices)
    _progress(session, result, 0, devices)
    for component in session.components.values():
        component.on_movement_end(result)


def _movement(
    session: Session, flow: Dataflow, robot: Robot, index: int, chain: list[Component],
    lookahead: int, pacer: _Pacer | None = None, safety: SafetyMonitor | None = None,
    step: Callable[[], RobotState | None] | None = None,
) -> tuple[int, str]:
    """Step the robot through the movement it has begun; returns the steps taken and the
    reason when the loop halted it (``"interaction"``, or a safety halt of ``safety``:
    ``"force_limit"``, ``"force_stream_stalled"``).

    With ``lookahead > 1`` the robot runs up to that many steps ahead and the chain
    classifies them as one batch. A batch in which the primary classifier reports an
    interaction is rewound (``chain``: the robot, streamed sensors, extractors and
    classifiers) and replayed one step at a time, so the loop halts at the same step,
    with the same records, as without look-ahead; so is a batch that may hold a safety
    halt (a force sample over the limit, a stalled force stream). Batches end on multiples of
    ``run.map_update_every_steps`` so that maps are updated at the same steps too.
    ``step`` replaces ``robot.step`` (the team's stepper, which also moves the simulations
    that follow the robot).
    """
    # Settings read once: the step loop below runs some 20,000 times per search.
    settings = session.settings
    every = settings.map_update_every_steps
    halt_on_interaction = settings.halt_on_interaction
    max_steps = settings.max_steps_per_movement
    robot_id = robot.id
    step_robot = robot.step if step is None else step
    halted_by_loop = ""
    steps = 0
    replay_until = 0  # steps below this run one at a time (a rewound batch)
    while True:
        if steps >= max_steps:
            raise RunError(f"movement {index + 1} did not end within {max_steps} steps")
        batch = min(lookahead, max_steps - steps)
        if every:
            batch = min(batch, every - steps % every)
        if batch > 1 and steps >= replay_until and not halted_by_loop:
            snapshots = [component.checkpoint() for component in chain]
            aligned = flow.checkpoint()
            states = []
            for _ in range(batch):
                state = step_robot()
                if state is None:
                    break
                states.append(state)
            if not states:
                break
            outputs, classified = flow.read_and_classify()
            if flow.step_check is not None and flow.step_check.fault is not None:
                # A stream out of step: what it read is kept (the files show it), the
                # movement halts here and the run ends as no result.
                for state in states:
                    flow.record_robot_state(robot_id, state, index)
                flow.commit(outputs, classified)
                steps += len(states)
                robot.halt(STREAM_OUT_OF_STEP)
                return steps, STREAM_OUT_OF_STEP
            if (halt_on_interaction and flow.holds_interaction(classified)) or (
                safety is not None and safety.batch_needs_replay(states, outputs)
            ):
                for component, snapshot in zip(chain, snapshots, strict=True):
                    component.rewind(snapshot)
                flow.rewind(aligned)
                replay_until = steps + len(states)
                continue
            for state in states:
                flow.record_robot_state(robot_id, state, index)
            flow.commit(outputs, classified)
            if safety is not None:
                safety.batch_committed()
            steps += len(states)
        else:
            if pacer is not None:
                pacer.wait()
            state = step_robot()
            if state is None:
                break
            steps += 1
            flow.record_robot_state(robot_id, state, index)
            flow.tick()
            if flow.step_check is not None and flow.step_check.fault is not None:
                robot.halt(STREAM_OUT_OF_STEP)
                return steps, STREAM_OUT_OF_STEP
            if safety is not None and not halted_by_loop:
                halted_by_loop = safety.after_commit()
            if halt_on_interaction and not halted_by_loop:
                detected = flow.interaction_detected()
                if detected is not None:
                    halted_by_loop = "interaction"
                    robot.halt("interaction")
        if every and steps % every == 0:
            flow.flush_maps()
    return steps, halted_by_loop


def _open_loop(session: Session, flow: Dataflow) -> None:
    training = session.training_sensors
    sensors = [s for sid, s in session.components.sensors.items() if sid not in training]
    if not sensors:
        raise RunError("nothing to run: the experiment has no sensors and no robot")
    settings = session.settings
    max_reads = settings.max_reads
    devices = devices_of(session.components)
    pacer = _pacer(devices, settings.live_tick_s)
    clock = session.components.clock
    # The stated length (run.duration_s) in reads of one control period each.
    planned = (
        None if settings.duration_s is None
        else max(1, math.ceil(settings.duration_s / clock.period_s - 1e-9))
    )
    reads = 0
    ended_by = ""
    while True:
        if all(s.exhausted for s in sensors):
            ended_by = "the sensors ended"
            break
        if planned is not None and reads >= planned:
            ended_by = f"run.duration_s ({settings.duration_s:g} s, {planned} reads)"
            break
        if reads >= max_reads:
            session.details["limit"] = {
                "setting": "run.max_reads", "value": max_reads, "reads": reads,
                "clock_s": clock.now_s(),
                "reason": (
                    f"stopped at run.max_reads ({max_reads:,} reads, {clock.now_s():.6g} s "
                    "of the run's clock) before its sensors ended"
                    + ("" if planned is None else " or its run.duration_s was reached")
                    + ": a limit, not the run's end (state its length with run.duration_s)"
                ),
            }
            session.echo(f"stopped: {session.details['limit']['reason']}")
            break
        reads += 1
        pacer.wait()
        if not clock.follows:
            clock.advance()  # the open loop's control period: one per read
        flow.tick()
        flow.flush_maps()
    if ended_by:
        session.details["ended_by"] = ended_by
    session.details["sensor_reads"] = reads
    _note_force(session, flow.force_max_n)
    faults = device_faults(devices)
    if faults:  # the open loop has no per-movement line: the devices' faults at its end
        session.echo(f"{reads} sensor reads{faults}")


def _record_movement(session: Session, result: MovementResult,
                     devices: Mapping[str, Device]) -> None:
    """Into ``run.mcap``: the movement's result, the safety halts since the last one and
    the devices' health counters."""
    recording = session.recording
    if recording is None:
        return
    recording.movement(result)
    for halt in session.safety_halts[recording.halts_recorded:]:
        recording.event(SAFETY_HALT.name, SAFETY_HALT.schema, halt)
    recording.halts_recorded = len(session.safety_halts)
    if devices:
        recording.health({cid: d.health.as_dict() for cid, d in devices.items()})


def _note_force(session: Session, force_n: float) -> None:
    if not math.isnan(force_n):
        previous = session.max_measured_force_n
        session.max_measured_force_n = force_n if math.isnan(previous) else max(previous, force_n)


def _progress(
    session: Session, result: MovementResult, steps: int, devices: Mapping[str, Device],
    robots: str = "",
) -> None:
    m = result.movement
    # The force a sensor measured (noise included), as metrics.json's max_measured_force_n;
    # a simulator's true force is its own metric.
    force = (
        "" if math.isnan(result.max_force_n)
        else f"  max measured force {result.max_force_n:5.1f} N"
    )
    state = result.final_class or "-"
    # Fixed-width fields first and the free-form label last, so the columns line up.
    label = f"  {m.label}" if m.label else ""
    session.echo(
        f"EM {result.index + 1:>3} {m.phase or '':<7} "
        f"{result.halt_reason or 'completed':<12} state {state:<8} "
        f"{steps:>5d} steps{force:<27}{robots}{label}{_limit_hit(session, result)}"
        f"{device_faults(devices)}"
    )


def _limit_hit(session: Session, result: MovementResult) -> str:
    """``  force limit: wrist/force_n 85.2 N > 80 N`` for a movement the force limit
    halted (the stream and sample that crossed it), else empty."""
    for halt in reversed(session.safety_halts):
        if halt.get("movement") != result.index:
            continue
        if halt.get("reason") == FORCE_LIMIT:
            return (f"  force limit: {halt.get('stream') or 'a force'} "
                    f"{float(halt['force_n']):.1f} N > {float(halt['limit_n']):g} N")
    return ""
