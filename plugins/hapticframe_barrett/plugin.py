"""Registration of the ``barrett-wam`` and ``barrett-hand`` robots (import-light: no
python-can here)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import Kind, Knob, RobotSpec, hookimpl

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
        knobs=(
            Knob("control_rate_hz", "more control steps per second: finer trajectories and "
                 "contact timing, more CAN traffic per movement", values=(50.0, 100.0, 200.0)),
            Knob("ik_step_m", "closer IK solutions along a line: straighter fingertip lines, "
                 "IK solves per line", values=(0.002, 0.004, 0.008, 0.016)),
        ),
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
        knobs=(
            Knob("poll_every_steps", "polling the hand less often: less CAN traffic per step, "
                 "a pushed finger seen later", values=(1, 5, 10, 20)),
        ),
    )
