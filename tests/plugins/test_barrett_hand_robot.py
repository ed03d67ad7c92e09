"""The ``barrett-hand`` robot on emulated pucks, carried by the bundled ``sandbox`` robot (fast)
or the emulated ``dynamixel`` gantry: the posture, the fingertip, the carrier's movements."""

from __future__ import annotations

import math
import uuid
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from hapticframe import Kind, RobotSpec, get_registry
from hapticframe.devices import DeviceError, LifecycleState, MonotonicClock
from hapticframe.kinds import BuildContext, ExploratoryMovement, Robot, RobotState
from hapticframe.testing import (
    make_component,
    parametrize_with_checks,
    release_component,
    run_checks,
)
from hapticframe_barrett import Mode, PuckBus, hand_pucks
from hapticframe_barrett._hand_config import BarrettHandRobotConfig, FingerGeometryConfig
from hapticframe_barrett._hand_robot import BarrettHandRobot, fingertip_below_palm_m

pytest.importorskip("can")

#: The spec the lead registers, with a carrier the kit can build in this tree (the
#: barrett-wam robot is built concurrently elsewhere; the registered spec names it).
SPEC = RobotSpec(
    name="barrett-hand",
    summary="A BarrettHand (CAN pucks) in a raking posture on a carrier robot.",
    config=BarrettHandRobotConfig,
    factory="hapticframe_barrett._hand_robot:BarrettHandRobot",
    capabilities=frozenset({"hardware"}),
    inputs=(Kind.ROBOT,),
    check_inputs=("robot/sandbox",),
)
WORKSPACE = {"x_min_m": 0.0, "x_max_m": 0.8, "y_min_m": 0.0, "y_max_m": 0.5}
#: With the carrier's tool point 7 cm below the palm, the default posture's fingertip is
#: 1.5 cm below the tool point (0.085 m reach - 0.07 m).
BELOW = -0.07


def sandbox(**config: Any) -> Robot:
    spec = get_registry().plugins[Kind.ROBOT]["sandbox"].spec
    return make_component(spec, config=config, interface=Robot)


def build(carrier: Robot | None = None, *, up: bool = True, seed: int = 0,
          **config: Any) -> BarrettHandRobot:
    carrier = carrier if carrier is not None else sandbox(workspace=WORKSPACE)
    config.setdefault("palm_below_tool_point_m", BELOW)
    hand = BarrettHandRobot(BarrettHandRobotConfig(**config),
                            BuildContext(id="hand", rng=np.random.default_rng(seed),
                                         inputs={"arm": carrier}))
    if up:
        try:
            hand.configure()
            hand.activate()
        except Exception:
            hand.cleanup()  # the emulator's bus and reader thread, also from ERROR
            raise
    return hand


@pytest.fixture
def hand() -> Iterator[BarrettHandRobot]:
    robot = build()
    try:
        yield robot
    finally:
        robot.close()
        release_component(robot.carrier)


def line(y: float = 0.1, depth: float | None = 0.044, x1: float = 0.3) -> ExploratoryMovement:
    return ExploratoryMovement(np.array([0.1, y]), np.array([x1, y]), 0.05, depth_m=depth)


class Spy:
    """Records what the hand asks of its carrier."""

    def __init__(self, carrier: Robot, monkeypatch: pytest.MonkeyPatch) -> None:
        self.begun: list[ExploratoryMovement] = []
        self.states: list[RobotState | None] = []
        self.halts: list[str] = []
        begin, step, halt = carrier.begin, carrier.step, carrier.halt

        def spy_begin(movement: ExploratoryMovement) -> None:
            self.begun.append(movement)
            begin(movement)

        def spy_step() -> RobotState | None:
            self.states.append(step())
            return self.states[-1]

        def spy_halt(reason: str) -> None:
            self.halts.append(reason)
            halt(reason)

        monkeypatch.setattr(carrier, "begin", spy_begin)
        monkeypatch.setattr(carrier, "step", spy_step)
        monkeypatch.setattr(carrier, "halt", spy_halt)


# --- the finger's kinematics -----------------------------------------------------------------


def test_finger_kinematics_from_the_published_geometry() -> None:
    g = FingerGeometryConfig()
    # 30°: the outer link at 30 + 10 + 50 = 90° points straight down: 0.07 sin 30° + 0.05.
    assert fingertip_below_palm_m(g, math.radians(30)) == pytest.approx(0.085, abs=1e-4)
    # Flat open finger: only the outer link's 50° bend reaches below the palm.
    assert fingertip_below_palm_m(g, 0.0) == pytest.approx(0.05 * math.sin(0.8727))
    # 90°: the inner link straight down, the outer one bent 30 + 50° further, over the palm.
    assert fingertip_below_palm_m(g, math.pi / 2) == pytest.approx(
        0.07 + 0.05 * math.sin(math.pi / 2 + math.pi / 6 + 0.8727))
    straight = FingerGeometryConfig(coupling=0.0, distal_offset_rad=0.0)
    assert fingertip_below_palm_m(straight, math.pi / 2) == pytest.approx(0.12)


# --- the posture -------------------------------------------------------------------------------


def test_the_raking_posture_is_reached_and_held_at_activate(hand: BarrettHandRobot) -> None:
    assert hand.lifecycle_state is LifecycleState.ACTIVE
    emulator = hand.emulator
    assert emulator is not None
    # counts = angle * CTS / 2π * reduction (4096 counts per motor turn; 125:1 and 17.5:1).
    per_rad = 4096 / (2 * math.pi)
    assert hand.targets == {11: round(math.radians(120) * per_rad * 125),
                            12: round(math.radians(120) * per_rad * 125),
                            13: round(math.radians(30) * per_rad * 125), 14: 0}
    for node, target in hand.targets.items():
        puck = emulator.puck(node)
        assert puck.counts() == target
        assert puck.mode == int(Mode.PID)  # holding (HOLD set), not idle
        assert puck.initialised  # homed with CMD HI first
    assert hand.posture_rad[13] == pytest.approx(math.radians(30), abs=1e-4)
    assert hand.offset_m == pytest.approx(0.085 + BELOW, abs=1e-4)
    # Homing and the posture move took simulation time, none of it real.
    assert 3.0 < hand.clock.now() < 10.0
    assert hand.health.timeouts == 0 and hand.health.frames > 0


def test_the_extended_finger_and_the_spread_are_configurable() -> None:
    hand = build(raking_finger=1, raking_angle_rad=math.radians(60), spread_rad=0.5,
                 palm_below_tool_point_m=-0.1)
    try:
        assert hand.emulator is not None
        assert hand.emulator.puck(11).counts() == hand.targets[11]
        assert hand.targets[13] == hand.targets[12] > hand.targets[11]  # F2, F3 flexed
        assert hand.posture_rad[14] == pytest.approx(0.5, abs=1e-4)
        assert hand.offset_m == pytest.approx(
            fingertip_below_palm_m(FingerGeometryConfig(), hand.posture_rad[11]) - 0.1)
    finally:
        hand.close()
        release_component(hand.carrier)


def test_an_uninitialised_emulated_hand_ignores_moves_and_says_so() -> None:
    with pytest.raises(DeviceError, match="initialise"):
        build(initialize=False)


# --- movements -------------------------------------------------------------------------------


def test_fingertip_state_is_the_carriers_plus_the_offset(
    hand: BarrettHandRobot, monkeypatch: pytest.MonkeyPatch
) -> None:
    spy = Spy(hand.carrier, monkeypatch)
    t0, carrier_t0 = hand.clock.now(), hand.carrier.state.timestamp_s
    states = hand.execute(line())
    carried = [s for s in spy.states if s is not None]
    assert len(states) == len(carried) > 300
    for tip, arm in zip(states, carried, strict=True):
        assert tip.timestamp_s == arm.timestamp_s
        np.testing.assert_array_equal(tip.position_m, arm.position_m)
        assert tip.heading_rad == arm.heading_rad and tip.speed_m_per_s == arm.speed_m_per_s
        assert tip.depth_m == pytest.approx(arm.depth_m + hand.offset_m, abs=1e-12)
    assert states[-1].depth_m == pytest.approx(0.044)
    assert hand.state.depth_m == pytest.approx(0.044)
    assert hand.halt_reason == hand.carrier.halt_reason == ""
    # The hand's pucks were polled every 5 steps, their time moving on with the carrier's.
    assert hand.stats["polls"] >= len(states) // 5
    assert hand.clock.now() - t0 == pytest.approx(states[-1].timestamp_s - carrier_t0)


def test_depth_is_translated_to_the_carrier(
    hand: BarrettHandRobot, monkeypatch: pytest.MonkeyPatch
) -> None:
    spy = Spy(hand.carrier, monkeypatch)
    hand.begin(line(depth=0.05))
    assert spy.begun[-1].depth_m == pytest.approx(0.05 - hand.offset_m)
    np.testing.assert_array_equal(spy.begun[-1].start_m, [0.1, 0.1])
    state = hand.step()
    assert state is not None and state.depth_m == pytest.approx(0.05)
    hand.halt("test")
    # No depth: the carrier keeps its own (the sandbox's schedule) and the tip is deeper.
    hand.begin(line(depth=None))
    assert spy.begun[-1].depth_m is None
    state = hand.step()
    assert state is not None
    assert state.depth_m == pytest.approx(hand.carrier.state.depth_m + hand.offset_m)
    hand.halt("test")


def test_a_configured_default_depth_is_the_fingertips(monkeypatch: pytest.MonkeyPatch) -> None:
    hand = build(depth_m=0.03)
    try:
        spy = Spy(hand.carrier, monkeypatch)
        hand.begin(line(depth=None))
        assert spy.begun[-1].depth_m == pytest.approx(0.03 - hand.offset_m)
    finally:
        hand.close()
        release_component(hand.carrier)


def test_refusals_come_before_any_motion(
    hand: BarrettHandRobot, monkeypatch: pytest.MonkeyPatch
) -> None:
    spy = Spy(hand.carrier, monkeypatch)
    # Too shallow: the carrier's tool point would be at or above the surface.
    with pytest.raises(ValueError, match=r"carrier 'kit-sandbox' at depth -0\.005"):
        hand.begin(line(depth=0.01))
    assert spy.begun == []
    # Outside the carrier's workspace: the carrier's own refusal, with the hand's context.
    with pytest.raises(ValueError, match=r"carrier 'kit-sandbox' refused .*workspace"):
        hand.begin(line(x1=0.95))
    assert hand.step() is None
    assert spy.states == []  # the carrier never stepped
    assert hand.halt_reason == ""


def test_a_movement_before_activate_is_a_device_error() -> None:
    hand = build(up=False)
    try:
        with pytest.raises(DeviceError, match="configure and activate"):
            hand.begin(line())
    finally:
        hand.close()
        release_component(hand.carrier)


def test_halt_reaches_the_carrier_and_no_step_follows(
    hand: BarrettHandRobot, monkeypatch: pytest.MonkeyPatch
) -> None:
    spy = Spy(hand.carrier, monkeypatch)
    hand.begin(line())
    for _ in range(7):
        last = hand.step()
    assert last is not None
    steps = len(spy.states)
    hand.halt("interaction")
    assert spy.halts == ["interaction"]
    assert hand.halt_reason == "interaction"
    for _ in range(3):
        assert hand.step() is None
    assert len(spy.states) == steps  # no carrier step after the halt
    np.testing.assert_array_equal(hand.state.position_m, last.position_m)


def test_a_carrier_that_ends_or_halts_by_itself_ends_the_movement(
    hand: BarrettHandRobot,
) -> None:
    # Through the kit scene's buried cylinder: the sandbox halts on its force limit.
    states = hand.execute(ExploratoryMovement(np.array([0.2, 0.25]), np.array([0.6, 0.25]),
                                              0.05, depth_m=0.044))
    assert hand.carrier.halt_reason
    assert hand.halt_reason == hand.carrier.halt_reason
    assert states[-1].position_m[0] < 0.6


def test_controlled_robots_workspace_and_rate_are_the_carriers(hand: BarrettHandRobot) -> None:
    assert hand.controlled_robots == (hand.carrier,)
    assert hand.workspace == hand.carrier.workspace
    assert hand.control_rate_hz == hand.carrier.control_rate_hz


def test_exactly_one_carrier_robot_is_required() -> None:
    carrier = sandbox()
    config = BarrettHandRobotConfig()
    rng = np.random.default_rng(0)
    for inputs in ({}, {"a": carrier, "b": sandbox()}):
        with pytest.raises(ValueError, match="exactly one input, the carrier"):
            BarrettHandRobot(config, BuildContext(id="hand", rng=rng, inputs=inputs))


def test_deactivate_halts_the_carrier_and_idles_the_hand(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    hand = build()
    try:
        spy = Spy(hand.carrier, monkeypatch)
        hand.begin(line())
        hand.step()
        emulator = hand.emulator
        assert emulator is not None
        hand.deactivate()
        assert spy.halts == ["deactivate"]
        assert hand.step() is None
        emulator.sync()  # the reader thread has handled the group SET
        assert all(emulator.puck(n).mode == int(Mode.IDLE) for n in hand.targets)
        hand.cleanup()
        assert hand.host is None and hand.emulator is None
        assert emulator.errors == [] and emulator.notifier_exception is None
    finally:
        hand.close()
        release_component(hand.carrier)


def test_finalize_reports_the_counters(hand: BarrettHandRobot) -> None:
    hand.execute(line(x1=0.15))
    out = hand.finalize(None)  # type: ignore[arg-type]
    stats = out["barrett_hand"]
    assert stats["polls"] > 0 and stats["estops"] == 0
    assert stats["bus"]["timeouts"] == 0 and stats["emulator"]["replies"] > 0


# --- the environment -------------------------------------------------------------------------


def test_couple_environment_goes_to_an_emulated_carrier_only() -> None:
    coupled: list[object] = []
    arm = sandbox(workspace=WORKSPACE)
    loadable = type("Loadable", (type(arm),), {
        "couple_environment": lambda self, environment: coupled.append(environment)})
    carrier = loadable(arm.config, arm.context)
    hand = build(carrier, up=False)
    environment = object()
    hand.couple_environment(environment)  # type: ignore[arg-type]
    assert coupled == [environment]
    # A carrier no environment can load is refused, so is a real hand.
    with pytest.raises(ValueError, match="cannot be loaded"):
        build(arm, up=False).couple_environment(environment)  # type: ignore[arg-type]
    live = build(carrier, up=False, channel="can0")
    assert live.live
    with pytest.raises(ValueError, match="real BarrettHand"):
        live.couple_environment(environment)  # type: ignore[arg-type]
    assert coupled == [environment]


# --- a real carrier and the kit ---------------------------------------------------------------


def test_on_the_emulated_dynamixel_gantry(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("dynamixel_sdk")
    spec = get_registry().plugins[Kind.ROBOT]["dynamixel"].spec
    gantry = make_component(spec, interface=Robot)
    hand = build(gantry)
    try:
        spy = Spy(gantry, monkeypatch)
        states = hand.execute(ExploratoryMovement(np.array([0.2, 0.25]),
                                                  np.array([0.25, 0.25]), 0.05, depth_m=0.05))
        assert spy.begun[0].depth_m == pytest.approx(0.05 - hand.offset_m)
        assert abs(states[-1].depth_m - 0.05) < 0.002  # the gantry's measured depth + offset
        assert np.linalg.norm(states[-1].position_m - [0.25, 0.25]) <= 0.001 + 1e-9
        assert states[-1].timestamp_s == gantry.state.timestamp_s
    finally:
        hand.close()
        release_component(gantry)


def _kit(spec: RobotSpec) -> None:
    results = run_checks(spec)
    failed = [r for r in results if r.status not in ("PASS", "SKIP")]
    assert not failed, failed
    assert {"check_robot_contract", "check_robot_halt", "check_robot_stops_at_once",
            "check_robot_extremes", "check_robot_refuses_outside_workspace",
            "check_deterministic"} <= {r.check for r in results}


def test_the_kit_robot_checks_pass_on_a_sandbox_carrier() -> None:
    _kit(SPEC)


ON_DYNAMIXEL = RobotSpec(name=SPEC.name, summary=SPEC.summary, config=SPEC.config,
                         factory=SPEC.factory, capabilities=SPEC.capabilities,
                         inputs=SPEC.inputs, check_inputs=("robot/dynamixel",))


@parametrize_with_checks([ON_DYNAMIXEL])
def test_the_kit_passes_on_a_dynamixel_carrier(spec: RobotSpec, check: Any) -> None:
    pytest.importorskip("dynamixel_sdk")
    check(spec)


def test_the_live_path_in_real_time_on_a_virtual_channel() -> None:
    """``channel`` other than 'emulated': python-can opens the named channel and every wait
    is real (MonotonicClock); here pucks emulated in real time answer on a virtual channel."""
    channel = f"hapticframe-live-{uuid.uuid4().hex}"
    pucks = PuckBus(channel, hand_pucks(speed=4_000_000.0), clock=MonotonicClock()).start()
    hand = None
    try:
        hand = build(up=False, channel=channel, interface="virtual", poll_every_steps=20,
                     reply_timeout_s=0.5)  # real time on a loaded machine
        assert hand.live and isinstance(hand.clock, MonotonicClock)
        hand.configure()
        hand.activate()
        assert hand.emulator is None
        assert all(pucks.puck(n).counts() == t for n, t in hand.targets.items())
        states = hand.execute(line(x1=0.12))
        assert states and hand.halt_reason == "" and hand.stats["polls"] > 0
        hand.deactivate()
        pucks.sync()
        assert all(pucks.puck(n).mode == int(Mode.IDLE) for n in hand.targets)
    finally:
        if hand is not None:
            hand.close()
            release_component(hand.carrier)
        pucks.stop()
    assert pucks.errors == []
