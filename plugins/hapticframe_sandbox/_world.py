"""What sandbox robots share (one sandbox: clock, depth schedule, truth) and which robot a
sandbox may follow."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds import Device, Robot

from ._truth import GroundTruthLog, MovementTruth, joined

if TYPE_CHECKING:
    from ._robot import SandboxRobot

__all__: list[str] = []


def _followed_robot(own_id: str, followed_id: str, inputs: Mapping[str, Any]) -> Robot:
    """The robot a sandbox follows: in its inputs, not a sandbox, and emulated."""
    robot = inputs.get(followed_id)
    if robot is None:
        raise ValueError(
            f"robot {own_id!r} follows {followed_id!r}: name it in the sandbox's inputs"
        )
    others = sorted(set(inputs) - {followed_id})
    if others:
        raise ValueError(
            f"robot {own_id!r} follows {followed_id!r} and takes no other inputs "
            f"(found {', '.join(repr(o) for o in others)})"
        )
    from . import _robot  # the robot module imports this one

    if isinstance(robot, _robot.SandboxRobot) or not isinstance(robot, Robot):
        raise ValueError(
            f"robot {own_id!r} follows {followed_id!r}, which is not a robot the sandbox can "
            "follow (an emulated robot: a sandbox robot shares the sandbox instead, without "
            "'follows')"
        )
    if isinstance(robot, Device) and robot.live:
        raise ValueError(
            f"robot {own_id!r} follows {followed_id!r}, which drives real hardware: a simulated "
            "sandbox can only surround an emulated robot (set its port to 'emulated')"
        )
    return robot


#: Config fields every robot of one sandbox must share: its clock and depth schedule.
_SHARED_FIELDS = (
    "control_rate_hz", "depth_m", "depth_reduction_m", "depth_reduction_ratio", "min_depth_m",
)


class _Sandbox:
    """What the sandbox robots of one scene share: the clock and the depth schedule.

    A sandbox robot that names other sandbox robots in its ``inputs`` joins their sandbox
    (the scene's objects and material are the same for all); each robot keeps its own
    ground-truth log. Time is the sandbox's step count over all its robots, so steps are
    strictly ordered across robots. The schedule changes once per exploratory movement,
    when every robot's part of it has ended (:meth:`movement_ended`, or a robot's next
    ``begin`` when it runs alone).
    """

    def __init__(self, first: SandboxRobot) -> None:
        cfg = first.config
        self.robots: list[SandboxRobot] = [first]
        self.schedule_depth = cfg.depth_m
        self.next_reduction = cfg.depth_reduction_m
        self.interactions = 0
        #: Exploratory movements settled so far (the index the next one logs).
        self.settled = 0
        self._parts = 0
        self._interacted = False

    @classmethod
    def join(cls, robot: SandboxRobot, inputs: Mapping[str, Any]) -> _Sandbox:
        others = list(inputs.values())
        if not others:
            return cls(robot)
        from . import _robot  # the robot module imports this one

        wrong = [k for k, v in inputs.items() if not isinstance(v, _robot.SandboxRobot)]
        if wrong:
            raise ValueError(
                f"robot {robot.id!r} (type 'sandbox') shares a sandbox only with robots of "
                f"type 'sandbox'; {', '.join(repr(w) for w in wrong)} is not one"
            )
        world: _Sandbox = others[0]._world
        if any(o._world is not world for o in others):
            raise ValueError(f"robot {robot.id!r}: its input robots are in different sandboxes")
        first = world.robots[0]
        for name in _SHARED_FIELDS:
            if getattr(robot.config, name) != getattr(first.config, name):
                raise ValueError(
                    f"robot {robot.id!r} shares the sandbox of {first.id!r} and must have the "
                    f"same {name} ({getattr(first.config, name)})"
                )
        world.robots.append(robot)
        return world

    @property
    def steps(self) -> int:
        """Steps taken by every robot of the sandbox."""
        robots = self.robots
        if len(robots) == 1:
            return len(robots[0]._log_t)
        return sum(len(r._log_t) for r in robots)

    def part_closed(self, interacted: bool) -> None:
        """One robot's part of a movement has ended; settle when it was the last open."""
        self._parts += 1
        self._interacted = self._interacted or interacted
        self._settle()

    def movement_ended(self, index: int) -> None:
        """The run loop's movement ``index`` has ended (every robot hears it)."""
        self._settle()
        if not any(not r._closed for r in self.robots):
            self.settled = max(self.settled, index + 1)

    def _settle(self) -> None:
        if self._parts == 0 or any(not r._closed for r in self.robots):
            return
        if self._interacted:
            # Soil displaced around the object: rake shallower next time (1, 0.5, 0.25 cm ...).
            cfg = self.robots[0].config
            self.interactions += 1
            self.schedule_depth = max(cfg.min_depth_m, self.schedule_depth - self.next_reduction)
            self.next_reduction *= cfg.depth_reduction_ratio
        self.settled += 1
        self._parts = 0
        self._interacted = False

    def ground_truth(self) -> tuple[GroundTruthLog, NDArray[np.str_] | None]:
        """Every robot's log in time order, and the robot of each row (None when alone)."""
        if len(self.robots) == 1:
            return self.robots[0].ground_truth, None
        logs = [r.ground_truth for r in self.robots]
        order = np.argsort(np.concatenate([g.timestamps_s for g in logs]), kind="stable")
        ids = np.concatenate([np.full(len(g), r.id) for g, r in zip(logs, self.robots,
                                                                     strict=True)])
        merged = GroundTruthLog(
            **{name: np.concatenate([getattr(g, name) for g in logs])[order]
               for name in ("timestamps_s", "positions_m", "states", "forces_n",
                            "movement_index", "depth_m")}
        )
        return merged, ids[order]

    def movement_truths(self) -> list[MovementTruth]:
        """The truth of every exploratory movement in order: the parts of a movement that
        several robots made (the same index) joined into one."""
        if len(self.robots) == 1:
            return list(self.robots[0].movements)
        parts: dict[int, list[MovementTruth]] = {}
        for truth in sorted((m for r in self.robots for m in r.movements),
                            key=lambda m: m.start_time_s):
            parts.setdefault(truth.index, []).append(truth)
        return [joined(p) for _, p in sorted(parts.items())]
