"""Registration of the BNO055 IMU sensor (import-light: config model and hapticframe only)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import ChannelSpec, Kind, Knob, SensorSpec, hookimpl

from ._config import Bno055SensorConfig

__all__ = ["SPECS", "hapticframe_sensors"]

#: The specs this package registers (for the conformance kit and tests).
SPECS = (
    SensorSpec(
        name="bno055",
        produces={
            "acceleration_m_per_s2": ChannelSpec((3,), "m/s^2", "accelerometer, gravity included"),
            "linear_acceleration_m_per_s2": ChannelSpec((3,), "m/s^2", "gravity removed"),
            "gravity_m_per_s2": ChannelSpec((3,), "m/s^2"),
            "angular_velocity_rad_per_s": ChannelSpec((3,), "rad/s"),
            "orientation_wxyz": ChannelSpec((4,), "1", "unit quaternion"),
            "calibration": ChannelSpec((4,), "1", "system, gyro, accel, mag: 0-3"),
        },
        summary=(
            "Bosch BNO055 IMU over UART: acceleration, gravity, linear acceleration, angular "
            "rate, orientation and calibration; port 'emulated' runs its emulator on a pty."
        ),
        config=Bno055SensorConfig,
        factory="hapticframe_bno055._sensor:Bno055Sensor",
        capabilities=frozenset(),
        requires=("serial",),
        install_hint="pip install 'hapticframe[hardware]'",
        # The robot is optional: it drives the emulated IMU; a real port ignores it.
        inputs=(Kind.ROBOT,),
        check_config={"port": "emulated"},
        knobs=(
            Knob("rate_hz", "fewer polls per second: less UART traffic per step, staler "
                 "acceleration for the force observer", values=(25.0, 50.0, 100.0)),
        ),
    ),
)


@hookimpl
def hapticframe_sensors() -> Iterator[SensorSpec]:
    yield from SPECS
