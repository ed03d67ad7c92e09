"""The ``barrett-hand`` robot against a real BarrettHand on CAN.

Skipped unless pytest runs with ``--hardware``; the hand's CAN channel comes from the
environment (and the python-can interface, socketcan unless said otherwise)::

    HAPTICFRAME_CAN_CHANNEL=can0 python -m pytest --hardware tests/hardware

The hand homes (``CMD HI``) and takes the raking posture: keep it clear of people and objects.
Its carrier here is the simulated ``sandbox`` robot, so nothing but the hand's fingers moves.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator

import numpy as np
import pytest

from hapticframe import Kind, get_registry
from hapticframe.kinds import BuildContext, ExploratoryMovement, Robot
from hapticframe.testing import make_component, release_component

pytestmark = pytest.mark.hardware


def _channel() -> str:
    channel = os.environ.get("HAPTICFRAME_CAN_CHANNEL")
    if not channel:
        pytest.skip("set HAPTICFRAME_CAN_CHANNEL to the BarrettHand's CAN channel (e.g. can0)")
    return channel


@pytest.fixture
def hand() -> Iterator[object]:
    channel = _channel()
    pytest.importorskip("can")
    from hapticframe_barrett._hand_config import BarrettHandRobotConfig
    from hapticframe_barrett._hand_robot import BarrettHandRobot

    sandbox = get_registry().plugins[Kind.ROBOT]["sandbox"].spec
    carrier = make_component(sandbox, interface=Robot)
    config = BarrettHandRobotConfig(
        channel=channel,
        interface=os.environ.get("HAPTICFRAME_CAN_INTERFACE", "socketcan"),
        palm_below_tool_point_m=-0.07,
        reply_timeout_s=1.0,  # libbarrett's bound
    )
    robot = BarrettHandRobot(config, BuildContext(id="hand", rng=np.random.default_rng(0),
                                                  inputs={"arm": carrier}))
    try:
        robot.configure()
        robot.activate()
        yield robot
    finally:
        robot.close()
        release_component(carrier)


def test_barrett_hand_takes_and_holds_the_raking_posture(hand: object) -> None:
    from hapticframe_barrett import Mode
    from hapticframe_barrett._hand_robot import BarrettHandRobot

    assert isinstance(hand, BarrettHandRobot)
    assert hand.live and hand.emulator is None
    config = hand.config
    expected = {11: config.flexed_angle_rad, 12: config.flexed_angle_rad,
                13: config.raking_angle_rad, 14: config.spread_rad}
    for node, angle in expected.items():
        assert abs(hand.posture_rad[node] - angle) <= config.posture_tolerance_rad, node
    assert hand.host is not None
    assert all(hand.host.get(n, "MODE") == int(Mode.PID) for n in expected)  # holding
    # A simulated line: the pucks are polled every few steps and the posture holds.
    states = hand.execute(ExploratoryMovement(np.array([0.1, 0.1]), np.array([0.15, 0.1]),
                                              0.05, depth_m=0.044))
    assert states and hand.halt_reason == ""
    assert hand.stats["polls"] > 0 and hand.stats["displaced"] == 0
    assert states[-1].depth_m == pytest.approx(0.044)
    health = hand.health.as_dict()
    assert health["timeouts"] <= 0.01 * max(1, health["frames"])
    assert math.isfinite(hand.offset_m)


def test_barrett_hand_idles_its_pucks_on_deactivate(hand: object) -> None:
    from hapticframe_barrett import Mode
    from hapticframe_barrett._hand_robot import BarrettHandRobot

    assert isinstance(hand, BarrettHandRobot)
    hand.deactivate()
    assert hand.host is not None  # the bus stays open until cleanup
    assert all(hand.host.get(n, "MODE") == int(Mode.IDLE) for n in (11, 12, 13, 14))
