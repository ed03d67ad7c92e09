"""Robot interface: executes exploratory movements, simulated or real.

Contract
--------
- :meth:`Robot.begin` starts a movement; :meth:`Robot.step` advances one control period
  (``1 / control_rate_hz`` seconds) and returns the new :class:`RobotState`, or ``None``
  once the movement is complete or halted. Timestamps increase strictly across steps and
  movements.
- :meth:`Robot.halt` stops the current movement (the run loop calls it when the classifier
  reports an interaction); a robot may also halt by itself (a force limit) and say why in
  :attr:`Robot.halt_reason`.
- :attr:`Robot.workspace` (optional, default ``None``): the region the fingertip may reach.
  A robot that declares one refuses (``ValueError`` from :meth:`Robot.begin`) a movement
  whose start or end lies outside it, so that even a direct caller cannot move there; the
  run loop checks it too, before ``begin``, and records the movement as halted
  (``halt_reason="outside_workspace"``, no steps).
- After :meth:`Robot.halt` the next :meth:`Robot.step` returns ``None``: no command is sent
  after a halt (the run's safety halts, an interrupt and a device failure rely on it).
- :attr:`Robot.controlled_robots` (optional, default ``()``): robots this robot moves as
  part of its own movements (a hand's carrier arm). The run loop gives movements only to
  robots no other robot controls; the controlling robot calls their ``begin``, ``step``
  and ``halt`` itself. Their device lifecycle is still the run's.
- :meth:`Robot.execute` is the batch path: it runs one movement to its end and returns the
  states.
"""

from __future__ import annotations

from abc import abstractmethod
from typing import ClassVar

from hapticframe._kind import Kind
from hapticframe.kinds._base import Component
from hapticframe.kinds._records import ExploratoryMovement, Region, RobotState

__all__ = ["Robot"]


class Robot(Component):
    """Moves the fingertip: a simulated sandbox, an arm, a gantry."""

    kind: ClassVar[Kind] = Kind.ROBOT

    @property
    @abstractmethod
    def control_rate_hz(self) -> float:
        """Steps per second."""

    @property
    @abstractmethod
    def state(self) -> RobotState:
        """The latest state."""

    @abstractmethod
    def begin(self, movement: ExploratoryMovement) -> None:
        """Start ``movement`` from its start point."""

    @abstractmethod
    def step(self) -> RobotState | None:
        """Advance one control period; None when the movement is over."""

    @abstractmethod
    def halt(self, reason: str) -> None:
        """Stop the current movement now."""

    @property
    def workspace(self) -> Region | None:
        """The region the fingertip may reach, or None (no limit declared: the default).

        A robot that declares one must refuse, with ``ValueError`` from :meth:`begin`, a
        movement whose start or end lies outside it (``check_robot_refuses_outside_workspace``).
        """
        return None

    @property
    def controlled_robots(self) -> tuple[Robot, ...]:
        """Robots this robot moves as part of its own movements (default: none).

        A BarrettHand on a WAM controls the WAM: the hand's movements are the fingertip's,
        and the hand drives the arm to make them. The run loop never gives a controlled
        robot a movement of its own.
        """
        return ()

    @property
    def halt_reason(self) -> str:
        """Why the last movement stopped early (``""`` if it did not)."""
        return ""

    def execute(
        self, movement: ExploratoryMovement, max_steps: int = 1_000_000
    ) -> list[RobotState]:
        """Run ``movement`` to its end without interruption and return every state."""
        self.begin(movement)
        states: list[RobotState] = []
        for _ in range(max_steps):
            state = self.step()
            if state is None:
                return states
            states.append(state)
        raise RuntimeError(f"robot {self.id!r} did not finish a movement in {max_steps} steps")
