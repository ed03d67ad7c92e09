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

What the base does (template method)
------------------------------------
:meth:`Robot.begin` resolves the movement's depth (its own, else :attr:`Robot.default_depth_m`),
refuses a non-positive or non-finite depth and a movement whose start or end lies outside
:attr:`Robot.workspace` (``ValueError``, before anything moves), then calls the plugin's
:meth:`Robot._begin` with the checked depth, as scikit-learn's ``fit`` calls ``_fit``. The
properties ``control_rate_hz`` (``config.control_rate_hz``), ``state`` (``self._state``),
``halt_reason`` (``self._halt_reason``) and ``workspace`` (``self._workspace``) read the
attributes a robot keeps; a robot overrides any of them when it keeps that elsewhere.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from typing import ClassVar

import numpy as np

from hapticframe._kind import Kind
from hapticframe.kinds._base import Component
from hapticframe.kinds._records import ExploratoryMovement, Region, RobotState

__all__ = ["Robot"]


class Robot(Component):
    """Moves the fingertip: a simulated sandbox, an arm, a gantry."""

    kind: ClassVar[Kind] = Kind.ROBOT

    #: How far (m) a movement's ends may lie outside :attr:`workspace` and still be accepted
    #: (a robot whose movements are cut at a neighbour's boundary allows for rounding).
    workspace_slack_m: ClassVar[float] = 0.0

    #: Set by the robot: its latest state (what :attr:`state` returns).
    _state: RobotState
    #: Why the last movement stopped early (what :attr:`halt_reason` returns).
    _halt_reason: str = ""
    #: The region the fingertip may reach (what :attr:`workspace` returns).
    _workspace: Region | None = None

    @property
    def control_rate_hz(self) -> float:
        """Steps per second (default: ``config.control_rate_hz``)."""
        rate = getattr(self.config, "control_rate_hz", None)
        if rate is None:
            raise NotImplementedError(
                f"{type(self).__name__}: its config has no control_rate_hz; override "
                "Robot.control_rate_hz"
            )
        return float(rate)

    @property
    def state(self) -> RobotState:
        """The latest state (default: ``self._state``, which the robot keeps up to date)."""
        try:
            return self._state
        except AttributeError:
            raise NotImplementedError(
                f"{type(self).__name__}: set self._state in __init__ (or override Robot.state)"
            ) from None

    @property
    def default_depth_m(self) -> float | None:
        """The depth of a movement that gives none (``depth_m`` None), or None when the
        robot has no default (then such a movement is refused). Default: ``config.depth_m``
        when the config has one."""
        depth = getattr(self.config, "depth_m", None)
        return None if depth is None else float(depth)

    def begin(self, movement: ExploratoryMovement) -> None:
        """Start ``movement`` from its start point.

        Refuses (``ValueError``, nothing moves) a movement whose depth is not a positive
        number or whose start or end lies outside :attr:`workspace`; then calls
        :meth:`_begin` with the movement's depth.
        """
        depth = self._checked_depth_m(movement)
        self._refuse_outside_workspace(movement)
        self._begin(movement, depth)

    def _checked_depth_m(self, movement: ExploratoryMovement) -> float:
        """The depth ``movement`` runs at (its own, else :attr:`default_depth_m`); a
        ``ValueError`` unless it is a positive number."""
        depth = self.default_depth_m if movement.depth_m is None else float(movement.depth_m)
        if depth is None:
            raise ValueError(
                f"robot {self.id!r}: the movement gives no depth and the robot has no default"
            )
        if not (math.isfinite(depth) and depth > 0):
            raise ValueError(f"robot {self.id!r}: movement depth must be positive, got {depth}")
        return depth

    def _refuse_outside_workspace(self, movement: ExploratoryMovement) -> None:
        """``ValueError`` naming the first end of ``movement`` outside :attr:`workspace`."""
        region = self.workspace
        if region is None:
            return
        ends = np.vstack([movement.start_m, movement.end_m])
        outside = ends[~region.contains(ends, self.workspace_slack_m)]
        if len(outside):
            x, y = outside[0].tolist()
            raise ValueError(
                f"robot {self.id!r}: the movement leaves the workspace at ({x:.4g}, {y:.4g}) m "
                f"(x {region.x_min_m:g}...{region.x_max_m:g} m, "
                f"y {region.y_min_m:g}...{region.y_max_m:g} m)"
            )

    def _begin(self, movement: ExploratoryMovement, depth_m: float) -> None:
        """Start ``movement`` at ``depth_m`` (already checked: positive, inside the workspace).

        The plugin's hook behind :meth:`begin`; a robot overrides this (or, when it checks
        movements in its own way, :meth:`begin` itself).
        """
        raise NotImplementedError(f"{type(self).__name__} must override Robot._begin")

    @abstractmethod
    def step(self) -> RobotState | None:
        """Advance one control period; None when the movement is over."""

    @abstractmethod
    def halt(self, reason: str) -> None:
        """Stop the current movement now."""

    @property
    def workspace(self) -> Region | None:
        """The region the fingertip may reach, or None (no limit declared: the default).

        Default: ``self._workspace``. :meth:`begin` refuses, with ``ValueError``, a movement
        whose start or end lies outside it (``check_robot_refuses_outside_workspace``).
        """
        return self._workspace

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
        """Why the last movement stopped early (``""`` if it did not; default:
        ``self._halt_reason``)."""
        return self._halt_reason

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
