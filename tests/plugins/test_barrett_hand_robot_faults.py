"""The ``barrett-hand`` robot under the puck emulator's faults (notes §4.5), fault by fault:
each is survived with bounded recovery and counted, or fails cleanly with the carrier halted.

The hand's clock reaches about 5.3 s by the end of activate (waking, homing, the posture
move); faults at 6 s happen while the carrier rakes."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from hapticframe import Kind, get_registry
from hapticframe.devices import DeviceError, LifecycleState
from hapticframe.kinds import BuildContext, ExploratoryMovement, Robot, RobotState
from hapticframe.testing import make_component, release_component
from hapticframe_barrett._hand_config import BarrettHandRobotConfig
from hapticframe_barrett._hand_robot import BarrettHandRobot

pytest.importorskip("can")

LINE = ExploratoryMovement(np.array([0.1, 0.1]), np.array([0.5, 0.1]), 0.05, depth_m=0.044)
DURING = 6.0  # s on the hand's clock: while raking


@pytest.fixture
def made() -> Iterator[list[BarrettHandRobot]]:
    hands: list[BarrettHandRobot] = []
    yield hands
    for hand in hands:
        emulator = hand.emulator
        if emulator is not None:
            assert emulator.errors == [] and emulator.notifier_exception is None
        hand.close()
        release_component(hand.carrier)


def carrier() -> Robot:
    spec = get_registry().plugins[Kind.ROBOT]["sandbox"].spec
    return make_component(spec, interface=Robot)


def build(made: list[BarrettHandRobot], *events: dict[str, Any], up: bool = True,
          seed: int = 0, **config: Any) -> BarrettHandRobot:
    config.setdefault("palm_below_tool_point_m", -0.07)
    if events:
        config["faults"] = list(events)
    hand = BarrettHandRobot(BarrettHandRobotConfig(**config), BuildContext(
        id="hand", rng=np.random.default_rng(seed), inputs={"arm": carrier()}))
    made.append(hand)
    if up:
        hand.configure()
        hand.activate()
    return hand


def rake(hand: BarrettHandRobot) -> list[RobotState]:
    states = hand.execute(LINE)
    assert hand.halt_reason == ""
    assert np.linalg.norm(states[-1].position_m - LINE.end_m) < 1e-3
    return states


class Steps:
    """Counts the carrier's steps."""

    def __init__(self, robot: Robot, monkeypatch: pytest.MonkeyPatch) -> None:
        self.count = 0
        step = robot.step

        def counted() -> RobotState | None:
            self.count += 1
            return step()

        monkeypatch.setattr(robot, "step", counted)


def fails_cleanly(hand: BarrettHandRobot, monkeypatch: pytest.MonkeyPatch,
                  match: str) -> DeviceError:
    """Rake until DeviceError; then the carrier is halted and never steps again."""
    steps = Steps(hand.carrier, monkeypatch)
    hand.begin(LINE)

    def rake_on() -> None:
        for _ in range(2000):
            hand.step()

    with pytest.raises(DeviceError, match=match) as info:
        rake_on()
    assert info.value.device_id == "hand"
    assert hand.halt_reason == "device_error"
    taken = steps.count
    assert hand.step() is None and hand.carrier.step() is None
    assert steps.count == taken + 1  # only the direct call above: the hand sent none
    return info.value


# --- configure, activate -----------------------------------------------------------------------


def test_a_puck_that_never_wakes_is_named_at_configure(made: list[BarrettHandRobot]) -> None:
    with pytest.raises(DeviceError, match=r"13 \(F3\) did not wake"):
        build(made, {"kind": "never_wakes", "at_s": 0.0, "params": {"node": 13}})
    assert made[0].lifecycle_state is LifecycleState.ERROR
    # STAT read from each puck, then once more from the one still in RESET: bounded.
    assert made[0].health.frames == 5


def test_a_missing_puck_is_named_at_configure(made: list[BarrettHandRobot]) -> None:
    with pytest.raises(DeviceError, match=r"puck\(s\) 14 \(spread\) did not wake"):
        build(made, emulated_nodes=(11, 12, 13))


def test_an_estop_during_the_posture_move_fails_activate(made: list[BarrettHandRobot]) -> None:
    with pytest.raises(DeviceError, match="from its target"):
        build(made, {"kind": "estop", "at_s": 3.0})
    assert made[0].lifecycle_state is LifecycleState.ERROR


def test_faults_need_the_emulator() -> None:
    with pytest.raises(ValidationError, match="need channel 'emulated'"):
        BarrettHandRobotConfig(channel="can0", faults="standard")


# --- survived while raking ---------------------------------------------------------------------


def test_late_replies_time_out_are_retried_and_discarded_when_they_come(
    made: list[BarrettHandRobot],
) -> None:
    hand = build(made, {"kind": "late_reply", "at_s": DURING, "params": {"node": 12}})
    rake(hand)
    assert hand.health.timeouts == 1  # the MODE read of puck 12, answered on the retry
    assert hand.health.resyncs >= 1  # the late reply, discarded when it came
    assert hand.emulator is not None and hand.emulator.stats["late"] == 1


@pytest.mark.parametrize("how", ["bit7", "byte1", "short", "wrong_property"])
def test_malformed_replies_are_counted_and_retried(made: list[BarrettHandRobot], how: str) -> None:
    hand = build(made, {"kind": "malformed_reply", "at_s": DURING, "params": {"how": how}})
    rake(hand)
    if how == "wrong_property":  # not this request's reply: waited out, then retried
        assert hand.health.timeouts == 1 and hand.health.resyncs >= 1
    else:
        assert hand.health.invalid_samples == 1


def test_duplicate_replies_are_discarded(made: list[BarrettHandRobot]) -> None:
    hand = build(made, {"kind": "duplicate_reply", "at_s": DURING, "params": {"count": 3}})
    rake(hand)
    assert hand.health.resyncs == 3 and hand.health.timeouts == 0


def test_a_missing_position_is_counted_and_not_judged(made: list[BarrettHandRobot]) -> None:
    hand = build(made, {"kind": "missing_position", "at_s": DURING, "params": {"node": 13}})
    rake(hand)
    assert hand.health.dropped_samples == 1
    assert hand.stats["missing_polls"] == 1 and hand.stats["displaced"] == 0


def test_error_frames_are_counted_and_survived(made: list[BarrettHandRobot]) -> None:
    hand = build(made, {"kind": "error_frame", "at_s": DURING, "params": {"count": 3}})
    rake(hand)
    assert hand.health.crc_errors == 3
    assert hand.host is not None and hand.host.stats["error_frames"] == 3


def test_a_short_bus_off_is_recovered(made: list[BarrettHandRobot]) -> None:
    hand = build(made, {"kind": "bus_off", "at_s": DURING, "duration_s": 0.3})
    rake(hand)
    health = hand.health
    assert health.stalls == 1 and health.reconnects == 1  # off, then restarted
    assert health.timeouts >= 2 and health.recoveries >= 1
    assert hand.stats["recovered"] == 1
    assert hand.lifecycle_state is LifecycleState.ACTIVE


def test_standard_faults_are_survived_and_replay_with_the_seed(
    made: list[BarrettHandRobot],
) -> None:
    counts = []
    for _ in range(2):
        hand = build(made, faults="standard", seed=3)
        states = rake(hand)
        assert hand.emulator is not None
        counts.append((len(states), hand.health.as_dict(), dict(hand.emulator.stats)))
    assert counts[0] == counts[1]


# --- failing cleanly ---------------------------------------------------------------------------


def test_an_estop_while_raking_halts_the_carrier(
    made: list[BarrettHandRobot], monkeypatch: pytest.MonkeyPatch
) -> None:
    hand = build(made, {"kind": "estop", "at_s": DURING})
    error = fails_cleanly(hand, monkeypatch, r"stopped holding its posture: F1 \(MODE 0\)")
    assert "E-stop" in str(error)
    assert hand.stats["estops"] == 1


def test_a_finger_pushed_back_halts_the_carrier(
    made: list[BarrettHandRobot], monkeypatch: pytest.MonkeyPatch
) -> None:
    hand = build(made)
    emulator = hand.emulator
    assert emulator is not None
    # While raking, the sand pushes the raking finger back by 0.25 rad (about 20 000
    # counts): the puck, holding in PID, ends where it was pushed.
    puck = emulator.puck(13)
    puck.target = puck.counts() - 20_000
    fails_cleanly(hand, monkeypatch, r"F3 was pushed 0\.\d+ rad out of the raking posture")
    assert hand.stats["displaced"] == 1


def test_positions_missing_poll_after_poll_halt_the_carrier(
    made: list[BarrettHandRobot], monkeypatch: pytest.MonkeyPatch
) -> None:
    events = [{"kind": "missing_position", "at_s": DURING, "params": {"node": 11}}] * 3
    hand = build(made, *events)
    fails_cleanly(hand, monkeypatch, r"puck 11 \(F1\) sent no position in 3 polls in a row")
    assert hand.health.dropped_samples == 3


def test_a_puck_gone_while_raking_fails_after_bounded_recoveries(
    made: list[BarrettHandRobot], monkeypatch: pytest.MonkeyPatch
) -> None:
    hand = build(made, {"kind": "never_wakes", "at_s": DURING,
                        "params": {"node": 12, "absent": 1}})
    fails_cleanly(hand, monkeypatch, "did not recover after 3 attempts")
    assert hand.health.recoveries == 3
    assert hand.lifecycle_state is LifecycleState.ERROR


def test_a_lasting_bus_off_fails_after_bounded_recoveries(
    made: list[BarrettHandRobot], monkeypatch: pytest.MonkeyPatch
) -> None:
    hand = build(made, {"kind": "bus_off", "at_s": DURING, "duration_s": 60.0})
    start = hand.clock.now()
    fails_cleanly(hand, monkeypatch, "did not recover")
    assert hand.health.stalls == 1 and hand.health.recoveries == 3
    assert hand.clock.now() - start < 20.0  # bounded on the hand's clock
