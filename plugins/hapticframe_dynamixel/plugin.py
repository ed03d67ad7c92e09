"""Registration of the ``dynamixel`` robot (import-light: no dynamixel_sdk here)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import RobotSpec, hookimpl

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
    )
