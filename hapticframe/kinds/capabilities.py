"""Optional capabilities a component declares: trainable, persistent, grid-queryable.

A kind's interface holds what every component of the kind does. What only some do is
declared here, as :func:`~typing.runtime_checkable` protocols: a component has the
capability when its class defines the protocol's methods, and the core, the conformance
kit and other plugins ask ``isinstance(component, Trainable)`` instead of looking a method
up by name. A plugin may also list the protocol among its base classes, which states the
intent and lets a type checker hold the signatures to the protocol's.

- :class:`Trainable`: ``fit`` (the kind's own signature) and ``training_report()``. The
  core fits feature extractors and classifiers whether or not they report; a trainable
  one's report is written to ``train.json`` and to ``run.json`` (``details.training``).
- :class:`Persistent`: ``save(directory)`` and ``load(directory)``. ``hapticframe train``
  saves each fitted persistent component into ``DIR/<component id>/``.
- :class:`GridQueryable`: a map that computes its mean and std on a regular grid faster
  than :meth:`~hapticframe.kinds.Map.query` on the same points; planners use it when offered.
- :class:`PhysicalTruthSource`: a simulated robot that exposes its physical state per step
  (a :class:`~hapticframe.kinds.PhysicalTruth`), so that device emulators can be driven by
  the simulation.
- :class:`Device`: a component that drives hardware (or an emulation of it) through the
  lifecycle configure → activate → deactivate → cleanup; the run loop drives it and
  reports its health counters.
- :class:`EnvironmentCoupled`: an emulated robot whose actuators feel the simulated
  environment's force on the tool (servo currents rise as the fingertip meets the sand).
- :class:`RobotFollower`: a simulation that moves with another robot instead of on its own
  (the sandbox computing the physics around an emulated arm); the run loop tells it each
  movement and step of the robot it follows.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds._records import ExploratoryMovement, PhysicalTruth, RobotState

if TYPE_CHECKING:
    from hapticframe.devices import DeviceHealth

__all__ = [
    "Device",
    "EnvironmentCoupled",
    "GridQueryable",
    "Persistent",
    "PhysicalTruthSource",
    "RobotFollower",
    "Trainable",
]

FloatArray = NDArray[np.float64]


@runtime_checkable
class Trainable(Protocol):
    """A component that learns from recordings and reports how the learning went.

    ``fit`` keeps its kind's signature (:meth:`FeatureExtractor.fit(batches)
    <hapticframe.kinds.FeatureExtractor.fit>`, :meth:`Classifier.fit(batches, labels)
    <hapticframe.kinds.Classifier.fit>`).
    """

    def fit(self, *args: Any, **kwargs: Any) -> None:
        """Learn from recordings (the kind's signature)."""

    def training_report(self) -> Mapping[str, Any]:
        """What the last fit did, as plain JSON-able values (counts, losses, accuracies,
        times in seconds, learned thresholds). An empty mapping before any fit; after a fit,
        never empty."""
        ...


@runtime_checkable
class Persistent(Protocol):
    """A component whose learned state can be written to and read from a directory."""

    def save(self, directory: str | Path) -> Any:
        """Write the learned state into ``directory`` (it exists); plain arrays and JSON,
        never pickles. The return value is ignored."""

    def load(self, directory: str | Path) -> None:
        """Read the state :meth:`save` wrote into ``directory``; raise ``ValueError`` when
        it does not fit this component's config."""


@runtime_checkable
class GridQueryable(Protocol):
    """A map that evaluates itself on a regular grid over its region in one call."""

    def probability_grid(
        self, spacing_m: float
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``(xs, ys, mean, std)``: the cell centres ``xs (nx,)`` and ``ys (ny,)`` in metres
        of a grid of about ``spacing_m`` over the region, and the occupancy mean and its
        standard deviation there, each ``(ny, nx)`` (the values :meth:`Map.query` gives at
        those points, to rounding)."""
        ...


# --- physical truth of simulated robots (issue 14, DESIGN §2) ---------------------------------


@runtime_checkable
class PhysicalTruthSource(Protocol):
    """A simulation that exposes its physical truth, so that any device emulator can be
    driven by it.

    A simulated robot implements this (the sandbox robot does); an emulated sensor whose
    inputs name such a robot asks ``isinstance(robot, PhysicalTruthSource)`` and, at each
    ``read()``, advances its own (fake) clock to :attr:`truth_time_s` and draws the values
    its device would report at time ``t`` from :meth:`physical_truth` ``(t)``. No plugin
    needs another plugin's private methods for this.

    Conventions (world frame, REP 103: x forward, z up; SI units): the record's position is
    the wrist sensor's origin; the force and torque are what the environment exerts on the
    tool (the torque about the sensor origin); the acceleration is kinematic, gravity not
    included. Sensor physics (specific force, sensor frames, the end effector's inertial
    load) belongs to the emulators: see ``docs/simulated-devices.md``.
    """

    def physical_truth(self, timestamp_s: float) -> PhysicalTruth:
        """The state of the latest simulation step at or before ``timestamp_s``
        (sample-and-hold); the current state when ``timestamp_s`` is at or after
        :attr:`truth_time_s`. Before the first step: the state the simulation starts from."""
        ...

    @property
    def truth_time_s(self) -> float:
        """Time of the latest step, in seconds (the simulation clock)."""
        ...


# --- Device (the run loop's hardware lifecycle) ----------------------------------------


@runtime_checkable
class Device(Protocol):
    """A component that talks to a device: a serial sensor, an arm, or their emulation.

    The lifecycle is ros2_control's: ``configure`` (open the port, identify the device),
    ``activate`` (start streaming, tare), then reads or writes, then ``deactivate`` (stop
    streaming, stop moving) and ``cleanup`` (close the port).
    :class:`hapticframe.devices.DeviceLifecycle` implements it with checked transitions and
    bounded recovery. ``hapticframe run`` configures and activates every device after
    building the experiment, in build order, and deactivates and cleans them up in reverse
    order when the run ends, whether it succeeded or not; ``deactivate`` and ``cleanup``
    must be safe to call again on a device already closed.

    A device that cannot go on raises :class:`hapticframe.devices.DeviceError`: the run
    halts every robot and ends with exit status 1 and a message naming the device.
    """

    def configure(self) -> None:
        """Open the link and set the device up (UNCONFIGURED → INACTIVE)."""

    def activate(self) -> None:
        """Start the device's data flow (INACTIVE → ACTIVE)."""

    def deactivate(self) -> None:
        """Stop the data flow (ACTIVE → INACTIVE); a no-op when not active."""

    def cleanup(self) -> None:
        """Release the link (INACTIVE → UNCONFIGURED); a no-op when already released."""

    @property
    def health(self) -> DeviceHealth:
        """Counters of the link's health (bytes, frames, CRC errors, resyncs, timeouts...):
        written to ``metrics.json`` under ``devices``; the non-zero fault counters are shown
        in the run's progress lines."""
        ...

    @property
    def live(self) -> bool:
        """True when the device is real hardware, so the run is paced by the wall clock;
        False for an emulated device that the simulation paces."""
        ...


# --- simulated worlds around emulated robots (issue 15) ------------------------------------


@runtime_checkable
class EnvironmentCoupled(Protocol):
    """An emulated robot whose actuators can be loaded by a simulated environment.

    A simulated world that follows the robot (a :class:`RobotFollower`) calls
    :meth:`couple_environment` once, at build time. From then on the robot's emulator asks
    ``environment.physical_truth(t)`` for the force and torque the environment exerts on the
    tool at its model time ``t`` (world frame, N and N·m, see :class:`PhysicalTruthSource`)
    and turns them into actuator loads (joint torques ``τ = Jᵀ f``, the current a servo
    draws to hold its position against them).
    """

    def couple_environment(self, environment: PhysicalTruthSource) -> None:
        """Let ``environment`` load the emulated actuators; raise ``ValueError`` when the
        robot drives real hardware (a simulated force cannot load a real motor)."""


@runtime_checkable
class RobotFollower(Protocol):
    """A simulation that moves with another robot instead of on its own.

    The sandbox, configured to follow an emulated arm, computes the granular physics around
    the arm's measured fingertip (the force that drives the emulated wrist sensor and loads
    the arm's servos) rather than moving a plate of its own. The run loop gives movements
    only to robots that follow nobody; for the robot a follower follows, it calls
    :meth:`follow_begin` before the robot's ``begin`` and :meth:`follow_step` after each of
    the robot's steps, before any sensor is read. A follower that can checkpoint is rewound
    with the robot when the loop looks ahead.
    """

    @property
    def followed_robot_id(self) -> str:
        """The id of the robot this simulation follows; ``""`` when it follows none and
        moves on its own (a class may implement both roles, chosen by its config)."""
        ...

    def follow_begin(self, movement: ExploratoryMovement) -> ExploratoryMovement:
        """The followed robot is about to begin ``movement`` (or a part of one); return the
        movement to give it: ``movement`` itself, or a copy whose open depth
        (``depth_m=None``) the simulation filled in (the sandbox's depth schedule)."""
        ...

    def follow_step(self, state: RobotState) -> None:
        """The followed robot's new state (every step, in order)."""
