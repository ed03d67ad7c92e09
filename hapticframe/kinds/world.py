"""World interface: the sand around a raked plate, asked for its force once per control step.

A world is not a kind of its own: it is what a simulated robot (the bundled ``sandbox`` and
``mpm-sand`` robots, or a lab's) consults for the physics while it moves the plate, or while
it follows an emulated arm (:class:`~hapticframe.kinds.RobotFollower`). The robot owns the
plumbing every world shares (movements, clock, depth schedule, halts, workspace, ground-truth
logs, :class:`~hapticframe.kinds.PhysicalTruth` for emulated sensors and servos); the world
owns only the mechanics. Any world can therefore stand behind any robot that takes one, and
the emulated rigs that read the robot's physical truth follow whichever world it holds.

Contract
--------
- A world is built for one scene (its objects and material); how it is configured is its
  own business. All its randomness comes from a ``numpy.random.Generator`` it was given.
- :meth:`World.begin` starts each straight movement (or part of one) with a
  :class:`PlateMovement`; then :meth:`World.respond` is called once per control step, in
  time order, with a :class:`PlateSample`, and returns a :class:`WorldResponse`: the force
  the sand exerts on the plate (world x and y, N) and the true state of the step
  (:class:`TruthState`: free, jamming or contact).
- :meth:`World.respond` may keep state between the steps of a movement (a drag fluctuation,
  how far the plate has pressed into an object). The default :meth:`World.checkpoint` is a
  shallow copy of the instance's attributes and :meth:`World.rewind` restores it, so a world
  that *rebinds* its attributes (``self.x = ...``) rather than mutating them in place can be
  rewound with its robot when the run loop looks ahead; a world that mutates in place
  overrides both.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

import numpy as np

__all__ = ["PlateMovement", "PlateSample", "TruthState", "World", "WorldResponse"]


class TruthState(IntEnum):
    """The true state of a step: what a perfect classifier would report."""

    #: The plate moves through free sand.
    FREE = 0
    #: The sand between the plate and an object jams (the force rises before contact).
    JAMMING = 1
    #: The plate touches an object.
    CONTACT = 2


@dataclass(frozen=True, slots=True)
class PlateMovement:
    """One straight movement of the plate through the world (or the part one robot makes).

    Attributes
    ----------
    index : int
        0-based exploratory movement this belongs to.
    start_m : tuple of 2 float
        Where the fingertip (the plate's centre) starts, world x and y.
    heading_rad : float
        Direction of motion, counter-clockwise from +x; constant over the movement.
    length_m : float
        Distance to travel (0: the movement has no steps).
    depth_m : float
        Raking depth of the fingertip below the free surface, constant over the movement.
    speed_m_per_s : float
        Commanded speed (a step's own speed is in its :class:`PlateSample`).
    control_period_s : float
        Time between steps.
    plate_width_m : float
        Width of the plate across the heading.
    interactions : int
        Movements before this one in which the plate or its failure zone reached an object
        (the sand around the object is disturbed by then; the analytic world narrows its
        failure zone with it).
    direction : tuple of 2 float
        The unit vector of ``heading_rad`` (derived).
    """

    index: int
    start_m: tuple[float, float]
    heading_rad: float
    length_m: float
    depth_m: float
    speed_m_per_s: float
    control_period_s: float
    plate_width_m: float
    interactions: int = 0
    direction: tuple[float, float] = field(init=False)

    def __post_init__(self) -> None:
        values = (*self.start_m, self.heading_rad, self.length_m, self.depth_m,
                  self.speed_m_per_s, self.control_period_s, self.plate_width_m)
        if len(self.start_m) != 2 or not all(math.isfinite(v) for v in values):
            raise ValueError(f"PlateMovement: start, heading, length, depth, speed, period and "
                             f"plate width must be finite (got {values})")
        if self.length_m < 0 or self.depth_m <= 0 or self.control_period_s <= 0:
            raise ValueError(
                f"PlateMovement: length >= 0, depth > 0 and control period > 0 required (got "
                f"{self.length_m}, {self.depth_m}, {self.control_period_s})"
            )
        # numpy's cos and sin on an array, as the robots compute their direction: the
        # same bits whoever asks.
        a = np.asarray(self.heading_rad, dtype=np.float64)
        dx, dy = np.stack([np.cos(a), np.sin(a)], axis=-1).tolist()
        object.__setattr__(self, "direction", (dx, dy))


@dataclass(frozen=True, slots=True)
class PlateSample:
    """The plate at one control step (the heading and depth are its movement's).

    Attributes
    ----------
    time_s : float
        The step's time on the run's clock.
    position_m : tuple of 2 float
        The fingertip (the plate's centre), world x and y.
    travelled_m : float
        Distance along the heading from the movement's start (never decreasing).
    advance_m : float
        Distance along the heading since the previous step (>= 0).
    speed_m_per_s : float
        The plate's speed at this step.
    acceleration_m_per_s2 : float
        Mean acceleration along the heading over the step.
    """

    time_s: float
    position_m: tuple[float, float]
    travelled_m: float
    advance_m: float
    speed_m_per_s: float
    acceleration_m_per_s2: float


@dataclass(frozen=True, slots=True)
class WorldResponse:
    """What the world answers for one step.

    Attributes
    ----------
    force_n : tuple of 2 float
        The force the sand (and any object touched) exerts on the plate, world x and y, N;
        against the motion in free raking. Finite.
    state : int
        A :class:`TruthState` value: 0 free, 1 jamming, 2 contact.
    """

    force_n: tuple[float, float]
    state: int

    def __post_init__(self) -> None:
        force = self.force_n
        if len(force) != 2 or not (math.isfinite(force[0]) and math.isfinite(force[1])):
            raise ValueError(f"WorldResponse: force_n must be 2 finite values in N (got {force})")
        if self.state not in (0, 1, 2):
            raise ValueError(
                f"WorldResponse: state must be 0 (free), 1 (jamming) or 2 (contact), got "
                f"{self.state!r}"
            )


class World(ABC):
    """The mechanics of the sand around a plate: force and true state per step.

    Subclasses implement :meth:`begin` and :meth:`respond` (see the module's contract).
    """

    @abstractmethod
    def begin(self, movement: PlateMovement) -> None:
        """Start ``movement``: reset whatever the world keeps per movement."""

    @abstractmethod
    def respond(self, plate: PlateSample) -> WorldResponse:
        """The force on the plate and the true state at the step ``plate``."""

    def checkpoint(self) -> Any:
        """A snapshot of the world's state (default: a shallow copy of its attributes)."""
        return dict(self.__dict__)

    def rewind(self, snapshot: Any) -> None:
        """Return to ``snapshot``, taken by :meth:`checkpoint` during this movement."""
        self.__dict__.clear()
        self.__dict__.update(snapshot)
