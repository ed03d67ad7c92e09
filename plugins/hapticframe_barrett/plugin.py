"""Registration of the ``barrett-wam`` and ``barrett-hand`` robots (import-light: no
python-can here)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import Kind, RobotSpec, hookimpl

from ._hand_config import BarrettHandRobotConfig
from ._wam_config import BarrettWamConfig

_HINT = "pip install 'hapticframe[hardware]' (python-can)"


@hookimpl
def hapticframe_robots() -> Iterator[RobotSpec]:
    yield RobotSpec(
        name="barrett-wam",
        summary="A Barrett WAM (4- or 7-DOF) at trajectory level over CAN pucks: joint-space "
        "targets for straight fingertip lines; channel 'emulated' runs the pucks on "
        "python-can's virtual bus in simulation time.",
        config=BarrettWamConfig,
        factory="hapticframe_barrett._wam:BarrettWamRobot",
        capabilities=frozenset({"hardware"}),
        install_hint=_HINT,
    )
    yield RobotSpec(
        name="barrett-hand",
        summary="A BarrettHand (CAN pucks 11-14) holding a raking posture - two fingers "
        "flexed, one extended - on the carrier robot named in its inputs.",
        config=BarrettHandRobotConfig,
        factory="hapticframe_barrett._hand_robot:BarrettHandRobot",
        capabilities=frozenset({"hardware"}),
        # The carrier (an arm, a gantry, a sandbox) that moves the hand.
        inputs=(Kind.ROBOT,),
        check_inputs=("robot/barrett-wam",),
        install_hint=_HINT,
    )
