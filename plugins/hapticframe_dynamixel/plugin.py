"""Registration of the ``dynamixel`` robot (import-light: no dynamixel_sdk here)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import Knob, RobotSpec, hookimpl

from ._config import DynamixelRobotConfig


@hookimpl
def hapticframe_robots() -> Iterator[RobotSpec]:
    yield RobotSpec(
        name="dynamixel",
        summary="Dynamixel XM430 servos (Protocol 2.0, dynamixel-sdk) as a Cartesian gantry or "
        "a planar two-link arm on a vertical axis; port 'emulated' runs them on a "
        "pseudo-terminal in simulation time.",
        config=DynamixelRobotConfig,
        factory="hapticframe_dynamixel._robot:DynamixelRobot",
        capabilities=frozenset({"hardware"}),
        install_hint="pip install 'hapticframe[hardware]' (dynamixel-sdk, pyserial)",
        knobs=(
            Knob("control_rate_hz", "more control steps per second: finer trajectories and "
                 "contact timing, more bus transactions per movement",
                 values=(25.0, 50.0, 100.0)),
            Knob("tolerance_m", "a tighter end tolerance: exacter line ends, more settle steps",
                 values=(0.0005, 0.001, 0.002, 0.005)),
        ),
    )
