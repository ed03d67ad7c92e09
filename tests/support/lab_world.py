"""A lab's own world, written against public names only (loaded with ``--plugin-module
lab_world``): constant drag, a jamming step a fixed distance ahead of an object, a rigid
object behind it.

It registers the robot type ``drag-wall``: the sandbox robot (movements, clock, depth
schedule, ground truth, physical truth, ``follows``) holding a :class:`DragWallWorld`, so
that the bundled sensors, emulated rigs and the search run on it unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
from pydantic import Field

from hapticframe import Kind, RobotSpec, Scene, hookimpl
from hapticframe.kinds import PlateMovement, PlateSample, TruthState, World, WorldResponse
from hapticframe_sandbox import SandboxRobot, SandboxRobotConfig


class DragWallConfig(SandboxRobotConfig):
    """The sandbox robot's fields, and the three of this world."""

    drag_n: float = Field(4.0, gt=0, le=1000, description="Free drag, whatever the depth (N).")
    jamming_reach_m: float = Field(
        0.03, ge=0, le=1, description="An object this far ahead of the plate jams the sand.")
    jamming_half_width_m: float = Field(
        0.05, ge=0, le=1, description="How far to either side of the heading it does so.")
    jamming_factor: float = Field(
        4.0, ge=1, le=100, description="The drag while jamming, in units of the free drag.")


class DragWallWorld(World):
    """Constant drag against the motion; ``jamming_factor`` times it while an object holds
    one of a few points ``jamming_reach_m`` ahead of the fingertip, up to
    ``jamming_half_width_m`` to either side; a spring of ``contact_stiffness_n_per_m`` on
    the travel since the fingertip entered an object."""

    def __init__(self, config: DragWallConfig, scene: Scene) -> None:
        self.config = config
        self.scene = scene

    def begin(self, movement: PlateMovement) -> None:
        cfg = self.config
        dx, dy = self.direction = movement.direction
        # The fingertip, then the probes ahead, relative to the fingertip.
        side = np.linspace(-cfg.jamming_half_width_m, cfg.jamming_half_width_m, 5)
        self.probes = np.vstack([
            (0.0, 0.0),
            np.column_stack([cfg.jamming_reach_m * dx - side * dy,
                             cfg.jamming_reach_m * dy + side * dx]),
        ])
        self.contact_travel_m = math.nan  # travel at which the fingertip met the object

    def respond(self, plate: PlateSample) -> WorldResponse:
        cfg = self.config
        (dx, dy) = self.direction
        occupied = self.scene.occupied(np.asarray(plate.position_m) + self.probes)
        inside, jammed = bool(occupied[0]), bool(occupied[1:].any())
        drag, state = cfg.drag_n, TruthState.FREE
        if jammed or inside:
            drag, state = cfg.drag_n * cfg.jamming_factor, TruthState.JAMMING
        if inside:
            if math.isnan(self.contact_travel_m):
                self.contact_travel_m = plate.travelled_m
            drag += cfg.contact_stiffness_n_per_m * (plate.travelled_m - self.contact_travel_m)
            state = TruthState.CONTACT
        else:
            self.contact_travel_m = math.nan
        return WorldResponse((-drag * dx, -drag * dy), state)


class DragWallRobot(SandboxRobot):
    """The sandbox robot with a :class:`DragWallWorld`."""

    config: DragWallConfig

    def build_world(self, scene: Scene, rng: np.random.Generator) -> World:
        return DragWallWorld(self.config, scene)


@hookimpl
def hapticframe_robots() -> Iterator[RobotSpec]:
    yield RobotSpec(
        name="drag-wall",
        summary="A lab's world: constant drag, a jamming step ahead of an object, a rigid "
        "object.",
        config=DragWallConfig,
        factory="lab_world:DragWallRobot",
        capabilities=frozenset({"simulated", "needs-scene"}),
        inputs=(Kind.ROBOT,),
    )
