"""Registration of the Robotiq FT 300 force/torque sensor (import-light)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import ChannelSpec, Kind, SensorSpec, hookimpl

from ._config import Ft300Config

__all__ = ["SPECS", "hapticframe_sensors"]

#: The specs this package registers (for the conformance kit and tests).
SPECS = (
    SensorSpec(
        name="robotiq-ft300",
        produces={
            "force_n": ChannelSpec((3,), "N", "the wrench's force in the sensor frame"),
            "torque_nm": ChannelSpec((3,), "N·m", "the wrench's torque in the sensor frame"),
        },
        summary=(
            "Robotiq FT 300 wrist force/torque sensor: Modbus RTU handshake and the 100 Hz "
            "stream over a serial port, or its emulator behind a pseudo-terminal."
        ),
        config=Ft300Config,
        factory="hapticframe_robotiq._sensor:Ft300Sensor",
        capabilities=frozenset({"hardware"}),
        install_hint="pip install 'hapticframe[hardware]' (pyserial)",
        requires=("serial",),
        # The robot is optional: an emulated sensor reads its physical truth, a real one
        # ignores it.
        inputs=(Kind.ROBOT,),
        sample_rate_hz=100.0,
        check_config={"port": "emulated"},
    ),
)


@hookimpl
def hapticframe_sensors() -> Iterator[SensorSpec]:
    yield from SPECS
