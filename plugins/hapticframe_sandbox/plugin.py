"""Registration of the simulated sandbox robot and force sensor (import-light)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import ChannelSpec, Kind, Knob, RobotSpec, SensorSpec, hookimpl

from ._config import SandboxForceSensorConfig, SandboxRobotConfig, SandboxTaxelSensorConfig


@hookimpl
def hapticframe_robots() -> Iterator[RobotSpec]:
    yield RobotSpec(
        name="sandbox",
        summary="Simulated plate raked through sand: plate drag, granular jamming, contact.",
        config=SandboxRobotConfig,
        factory="hapticframe_sandbox._robot:SandboxRobot",
        validator="hapticframe_sandbox._checks:check",
        capabilities=frozenset({"simulated", "needs-scene"}),
        knobs=(
            Knob("control_rate_hz", "more control steps per second: finer force and contact "
                 "timing, more steps (classifier and safety work) per movement",
                 values=(50.0, 100.0, 200.0)),
            Knob("sector_angular_samples", "more rays across the failure zone: objects off the "
                 "axis met truer, cost per step", values=(7, 11, 21, 41)),
        ),
        # Another sandbox robot in inputs: this one works in the same sandbox (clock and
        # depth schedule shared), e.g. a second arm with its own workspace.
        inputs=(Kind.ROBOT,),
    )


@hookimpl
def hapticframe_sensors() -> Iterator[SensorSpec]:
    yield SensorSpec(
        name="sandbox-force",
        produces={"force_n": ChannelSpec(
            (2,), "N", "the resistive force on the plate in the plane, world x and y")},
        summary="2-D fingertip force of the simulated sandbox robot, with sensor noise.",
        config=SandboxForceSensorConfig,
        factory="hapticframe_sandbox._sensor:SandboxForceSensor",
        capabilities=frozenset({"simulated", "needs-robot"}),
        inputs=(Kind.ROBOT,),
        check_inputs=("robot/sandbox",),
    )
    yield SensorSpec(
        name="sandbox-taxels",
        produces={
            "taxel_force": ChannelSpec((4, 3), "1", "4 taxels x (x, y, z), normalised"),
            "distance_mm": ChannelSpec((), "mm", "label: distance to the object"),
            "direction_class": ChannelSpec((), "1", "label: direction class"),
            "depth_class": ChannelSpec((), "1", "label: depth class"),
        },
        summary="The sandbox plate's force as a real rake's 4-taxel 3-axis normalized "
        "channels (a measurement model fitted to Chen et al. 2024), with distance, "
        "direction and depth labels; approach_trials makes it a training source.",
        config=SandboxTaxelSensorConfig,
        factory="hapticframe_sandbox._taxels:SandboxTaxelSensor",
        capabilities=frozenset({"simulated", "needs-robot"}),
        inputs=(Kind.ROBOT,),
        check_inputs=("robot/sandbox",),
    )
