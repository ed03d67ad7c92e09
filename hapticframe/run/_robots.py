"""Several robots in one closed loop: which robot makes a movement, and its continuation.

Each robot may declare a ``workspace`` (a :class:`~hapticframe.kinds.Region`, None for
everywhere). A planner's movement goes to the first robot, in experiment order, whose
workspace holds its start point. A robot never receives a line that leaves its workspace:
it gets the part up to the boundary, and when it has raked that part without halting, it
has halted at its workspace limit (``workspace_limit``). The movement then continues with
another robot whose workspace holds the halt point and more of the line, from where the
first stopped, at the same depth and speed; the parts are one exploratory movement (one
:class:`~hapticframe.kinds.MovementResult`). With no robot to continue, the movement ends
halted with ``workspace_limit``, as in the dissertation's real trial (section 3.5.3.4).

With one robot and no workspace, every movement goes to that robot unchanged, so a
one-robot run is exactly what it always was.

Not every robot of a run takes movements. A robot that another robot controls (listed in
its :attr:`~hapticframe.kinds.Robot.controlled_robots`: the arm that carries a hand) moves
only as part of the controlling robot's movements, and a simulation that follows a robot (a
:class:`~hapticframe.kinds.RobotFollower` with a ``followed_robot_id``: the sandbox around an
emulated arm) moves with it: :meth:`RobotTeam.begin` and the stepper of
:meth:`RobotTeam.stepper` tell it the followed robot's movements and steps.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from hapticframe._errors import RunError
from hapticframe.kinds import ExploratoryMovement, Region, Robot, RobotFollower, RobotState
from hapticframe.run._dataflow import Dataflow
from hapticframe.run._streams import PoseHistory

__all__ = ["WORKSPACE_LIMIT", "RobotTeam", "exit_distance", "share_poses", "workspace_of"]

#: The halt reason of a movement that left the workspace of every robot that could make it.
WORKSPACE_LIMIT = "workspace_limit"

#: Points this close to a workspace's edge count as inside it (rounding in a robot's own
#: stepping must not strand a halt point just outside a neighbour's abutting workspace).
TOLERANCE_M = 1e-6


def workspace_of(robot: Robot) -> Region | None:
    """The robot's workspace: its optional ``workspace`` property (None: everywhere)."""
    region = getattr(robot, "workspace", None)
    return region if isinstance(region, Region) else None


def _holds(region: Region | None, point: np.ndarray) -> bool:
    return region is None or bool(region.contains(point, TOLERANCE_M)[0])


def exit_distance(
    region: Region | None, start_m: np.ndarray, end_m: np.ndarray, tolerance_m: float = 0.0
) -> float:
    """How far along the line from ``start_m`` (inside ``region``) to ``end_m`` the line
    stays in ``region`` grown by ``tolerance_m``: the line's length when it never leaves
    (or no region)."""
    start = np.asarray(start_m, dtype=np.float64)
    delta = np.asarray(end_m, dtype=np.float64) - start
    length = float(np.hypot(delta[0], delta[1]))
    if region is None or length == 0.0:
        return length
    direction = delta / length
    reach = length
    bounds = ((region.x_min_m, region.x_max_m), (region.y_min_m, region.y_max_m))
    for axis, (low, high) in enumerate(bounds):
        d = float(direction[axis])
        p = float(start[axis])
        if d > 0.0:
            reach = min(reach, (high + tolerance_m - p) / d)
        elif d < 0.0:
            reach = min(reach, (low - tolerance_m - p) / d)
    return max(0.0, reach)


class RobotTeam:
    """The run's robots, in experiment order, and the workspace rules between them.

    ``robots`` are every robot of the run; :attr:`robots` keeps those that take movements
    (neither controlled by another robot nor following one), :attr:`followers` maps a robot's
    id to the simulations that follow it.
    """

    def __init__(self, robots: Sequence[Robot], flow: Dataflow) -> None:
        if not robots:
            raise RunError("a closed-loop run needs at least one robot")
        by_id = {r.id: r for r in robots}
        controlled = {
            c.id: r.id for r in robots for c in r.controlled_robots if c.id in by_id
        }
        following = {r.id: f for r in robots if (f := _followed(r))}
        self.robots = [r for r in robots if r.id not in controlled and r.id not in following]
        self.followers: dict[str, list[Robot]] = {}
        for rid, followed in following.items():
            if followed in controlled:
                raise RunError(
                    f"robot {rid!r} follows {followed!r}, which robot {controlled[followed]!r} "
                    f"controls: follow {controlled[followed]!r}, whose movements they are"
                )
            if followed not in by_id or followed in following:
                raise RunError(
                    f"robot {rid!r} follows {followed!r}, which is not a robot of this run "
                    "that moves on its own"
                )
            self.followers.setdefault(followed, []).append(by_id[rid])
        if not self.robots:
            raise RunError(
                "a closed-loop run needs a robot that takes movements: every robot is "
                "controlled by another or follows one"
            )
        self.workspaces = {r.id: workspace_of(r) for r in self.robots}
        self.several = len(self.robots) > 1
        self._latest_t = -math.inf
        if self.several:
            share_poses(flow, [r.id for r in self.robots])

    def begin(self, robot: Robot, part: ExploratoryMovement) -> ExploratoryMovement:
        """Begin ``part`` on ``robot`` after telling the simulations that follow it, which
        may fill in its open depth; returns the part as begun."""
        for follower in self.followers.get(robot.id, ()):
            part = follower.follow_begin(part)  # type: ignore[attr-defined]
        robot.begin(part)
        return part

    def stepper(self, robot: Robot) -> Callable[[], RobotState | None]:
        """``robot.step``, followed at each step by its followers' ``follow_step``."""
        followers = self.followers.get(robot.id)
        if not followers:
            return robot.step

        def step() -> RobotState | None:
            state = robot.step()
            if state is not None:
                for follower in followers:
                    follower.follow_step(state)  # type: ignore[attr-defined]
            return state

        return step

    def _makes_progress(self, robot: Robot, start: np.ndarray, end: np.ndarray) -> bool:
        region = self.workspaces[robot.id]
        if not _holds(region, start):
            return False
        length = float(np.hypot(*(np.asarray(end) - start)))
        return length <= TOLERANCE_M or exit_distance(region, start, end, TOLERANCE_M) > TOLERANCE_M

    def pick(
        self, start_m: np.ndarray, end_m: np.ndarray, exclude: Sequence[Robot] = ()
    ) -> Robot | None:
        """The first robot (experiment order, those in ``exclude`` left out) whose
        workspace holds ``start_m`` and some of the line on to ``end_m``; None when none
        does."""
        start = np.asarray(start_m, dtype=np.float64)
        for robot in self.robots:
            if all(robot is not r for r in exclude) and self._makes_progress(robot, start, end_m):
                return robot
        return None

    def part_for(
        self, robot: Robot, movement: ExploratoryMovement
    ) -> tuple[ExploratoryMovement, bool]:
        """``movement`` cut at ``robot``'s workspace boundary, and whether it was cut.

        A movement the workspace holds whole is returned as it is (the same object).
        """
        region = self.workspaces[robot.id]
        if region is None:
            return movement, False
        reach = exit_distance(region, movement.start_m, movement.end_m)
        length = movement.length_m
        if reach >= length:
            return movement, False
        direction = (movement.end_m - movement.start_m) / length
        end = movement.start_m + reach * direction
        # On the boundary, never a rounding error beyond it.
        end = np.clip(end, [region.x_min_m, region.y_min_m], [region.x_max_m, region.y_max_m])
        return _line(movement, movement.start_m, end, movement.depth_m), True

    def continuation(
        self, movement: ExploratoryMovement, robot: Robot, used: Sequence[Robot]
    ) -> tuple[Robot, ExploratoryMovement] | None:
        """The robot that continues ``movement`` from where ``robot`` stopped at its
        workspace limit, and the rest of the line at the depth ``robot`` raked; None when
        no robot not yet ``used`` for it can (a straight line crosses a rectangle once)."""
        state = robot.state
        stop = np.asarray(state.position_m, dtype=np.float64)
        if not np.all(np.isfinite(stop)):
            return None
        nxt = self.pick(stop, movement.end_m, exclude=used)
        if nxt is None:
            return None
        depth = float(state.depth_m) if math.isfinite(state.depth_m) else movement.depth_m
        return nxt, _line(movement, stop, movement.end_m, depth)

    def resumption(
        self, movement: ExploratoryMovement, robot: Robot
    ) -> ExploratoryMovement | None:
        """The rest of ``movement`` from where ``robot`` stopped, at the depth it raked, for
        the same robot to continue (after a stalled force stream); None when nothing is left
        of the line or the robot's position is unknown."""
        state = robot.state
        stop = np.asarray(state.position_m, dtype=np.float64)
        if not np.all(np.isfinite(stop)):
            return None
        if float(np.hypot(*(movement.end_m - stop))) <= TOLERANCE_M:
            return None
        depth = float(state.depth_m) if math.isfinite(state.depth_m) else movement.depth_m
        return _line(movement, stop, movement.end_m, depth)

    def after_part(self, robot: Robot, steps: int) -> None:
        """Robots that share a run must share a clock: the steps of a part come after every
        step of the parts before (the pose history and the trace need one time line).
        Checked, with several robots, on each part's last step."""
        if not self.several or steps == 0:
            return
        last_t = float(robot.state.timestamp_s)
        if not last_t > self._latest_t:
            raise RunError(
                f"robot {robot.id!r} stepped at t = {last_t:.6g} s, not after the previous "
                f"part's last step (t = {self._latest_t:.6g} s): the robots of one run must "
                "share a clock (two 'sandbox' robots share one sandbox when the second names "
                "the first in its inputs)"
            )
        self._latest_t = last_t

    def path_label(self, robots: Sequence[Robot]) -> str:
        """``"  arm-a → arm-b"`` for a progress line, ``""`` with a single robot."""
        if not self.several:
            return ""
        return "  " + " → ".join(r.id for r in robots) if robots else "  (no robot)"


def _followed(robot: Robot) -> str:
    """The id of the robot ``robot`` follows, ``""`` for none."""
    if isinstance(robot, RobotFollower):
        return str(robot.followed_robot_id or "")
    return ""


def _line(
    movement: ExploratoryMovement, start: np.ndarray, end: np.ndarray, depth: float | None
) -> ExploratoryMovement:
    return ExploratoryMovement(
        start_m=np.array(start, dtype=np.float64),
        end_m=np.array(end, dtype=np.float64),
        speed_m_per_s=movement.speed_m_per_s,
        depth_m=depth,
        phase=movement.phase,
        label=movement.label,
    )


def share_poses(flow: Dataflow, robot_ids: Sequence[str]) -> None:
    """Let every robot's states feed the pose history of every sensor model that locates
    its measurements with a robot: one history, the moving fingertip's, for all robots."""
    if not any(rid in flow.poses for rid in robot_ids):
        return
    shared = PoseHistory()
    for rid in robot_ids:
        flow.poses[rid] = shared
