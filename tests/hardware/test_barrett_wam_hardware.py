"""The ``barrett-wam`` robot against a real 4-DOF WAM.

Skipped unless pytest runs with ``--hardware`` and ``HAPTICFRAME_CAN_CHANNEL`` names the
arm's CAN channel (SocketCAN, e.g. ``can0`` brought up at 1 Mbit/s; another python-can
interface in ``HAPTICFRAME_CAN_INTERFACE``)::

    HAPTICFRAME_CAN_CHANNEL=can0 python -m pytest --hardware tests/hardware

Before it runs: zero the arm with Barrett's tools, clear the workspace, keep a hand on the
E-stop, and press Shift-Activate when the test asks the arm to activate. The robot never sets
MODE; the test ends with the arm holding its position (release it with Shift-Idle).
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from hapticframe.kinds import BuildContext, ExploratoryMovement
from hapticframe_barrett._wam import BarrettWamRobot
from hapticframe_barrett._wam_config import BarrettWamConfig

pytestmark = pytest.mark.hardware


def _channel() -> str:
    channel = os.environ.get("HAPTICFRAME_CAN_CHANNEL")
    if not channel:
        pytest.skip("set HAPTICFRAME_CAN_CHANNEL to the WAM's CAN channel (e.g. can0)")
    return channel


def _robot() -> BarrettWamRobot:
    config = BarrettWamConfig(
        channel=_channel(),
        interface=os.environ.get("HAPTICFRAME_CAN_INTERFACE", "socketcan"),
    )
    return BarrettWamRobot(config, BuildContext(id="wam", rng=np.random.default_rng(0)))


def test_a_real_wam_wakes_and_reports_its_joints() -> None:
    """Configure only: wake, VERS, CTS, one position poll; nothing is sent to move."""
    robot = _robot()
    try:
        robot.configure()
        assert robot.live is True and robot.host is not None
        assert set(robot.host.tables) == set(robot.nodes)
        assert robot.arm.within_limits(robot.joints_rad), robot.joints_rad
        assert np.all(np.isfinite(robot.state.position_m))
        assert robot.stats["targets_sent"] == 0
    finally:
        robot.close()


def test_a_real_wam_rakes_a_short_line_and_holds() -> None:
    """A 2 cm line at 1 cm/s in the middle of the default workspace (press Shift-Activate
    before this test's activate), then the arm holds."""
    robot = _robot()
    robot.configure()
    try:
        robot.activate()
        movement = ExploratoryMovement(np.array([0.36, 0.25]), np.array([0.38, 0.25]), 0.01,
                                       depth_m=0.01)
        robot.begin(movement)
        states = []
        while (state := robot.step()) is not None:
            states.append(state)
            time.sleep(1 / robot.control_rate_hz)  # the run paces a live robot
        assert robot.halt_reason in ("", "not_settled")
        assert np.linalg.norm(states[-1].position_m - movement.end_m) < 0.005
        assert robot.health.recoveries == 0
    finally:
        robot.close()
