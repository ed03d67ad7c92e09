"""The kinds own their plumbing (issue 25 §4, §6): Robot.begin checks depth and workspace and
calls _begin; Map.query checks the points and calls _query; one home for shared rules."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hapticframe import PluginConfig
from hapticframe._config._roles import evaluated_map_id
from hapticframe._defaults import LIVE_PORT, OUTLINE_LEVEL
from hapticframe._kind import Kind
from hapticframe.kinds import (
    BuildContext,
    ExploratoryMovement,
    Map,
    MapEstimate,
    Observations,
    Region,
    Robot,
    RobotState,
    RunOutcome,
    query_points,
)


class DepthConfig(PluginConfig):
    control_rate_hz: float = 50.0
    depth_m: float | None = 0.03


class RecordingRobot(Robot):
    """Keeps what the base hands to _begin; declares a workspace when given one."""

    workspace_slack_m = 0.0

    def __init__(self, workspace: Region | None = None, depth_m: float | None = 0.03) -> None:
        super().__init__(DepthConfig(depth_m=depth_m),
                         BuildContext(id="rec", rng=np.random.default_rng(0)))
        self._workspace = workspace
        self._state = RobotState(0.0, np.zeros(2), 0.0, 0.03, 0.0)
        self.begun: list[tuple[ExploratoryMovement, float]] = []

    def _begin(self, movement: ExploratoryMovement, depth_m: float) -> None:
        self.begun.append((movement, depth_m))

    def step(self) -> RobotState | None:
        return None

    def halt(self, reason: str) -> None:
        self._halt_reason = reason


def line(x0: float, x1: float, depth_m: float | None = None) -> ExploratoryMovement:
    return ExploratoryMovement(np.array([x0, 0.2]), np.array([x1, 0.2]), 0.05, depth_m=depth_m)


def test_the_robot_base_resolves_and_checks_the_depth_before_the_hook() -> None:
    robot = RecordingRobot()
    robot.begin(line(0.1, 0.2))
    robot.begin(line(0.1, 0.2, depth_m=0.05))
    assert [d for _, d in robot.begun] == [0.03, 0.05]
    for bad in (0.0, -0.01, math.nan, math.inf):
        with pytest.raises(ValueError, match="depth must be positive"):
            robot.begin(line(0.1, 0.2, depth_m=bad))
    with pytest.raises(ValueError, match="no depth"):
        RecordingRobot(depth_m=None).begin(line(0.1, 0.2))
    assert len(robot.begun) == 2  # nothing refused reached the hook


def test_the_robot_base_refuses_a_movement_outside_its_workspace() -> None:
    region = Region(0.0, 0.5, 0.0, 0.4)
    robot = RecordingRobot(region)
    robot.begin(line(0.0, 0.5))  # on the boundary: inside
    with pytest.raises(ValueError, match=r"leaves the workspace at \(0\.6, 0\.2\) m"):
        robot.begin(line(0.1, 0.6))
    with pytest.raises(ValueError, match="leaves the workspace"):
        robot.begin(line(0.5 + 1e-7, 0.2))
    class SlackRobot(RecordingRobot):
        workspace_slack_m = 1e-6  # a robot's allowance for rounding at a cut

    slack = SlackRobot(region)
    slack.begin(line(0.5 + 1e-7, 0.2))
    assert len(robot.begun) == 1 and len(slack.begun) == 1
    assert RecordingRobot(None).workspace is None


def test_the_robot_base_properties_read_what_the_robot_keeps() -> None:
    robot = RecordingRobot(Region(0.0, 1.0, 0.0, 1.0))
    assert robot.control_rate_hz == 50.0 and isinstance(robot.control_rate_hz, float)
    assert robot.state.depth_m == 0.03 and robot.halt_reason == ""
    robot.halt("kit")
    assert robot.halt_reason == "kit" and robot.workspace == Region(0.0, 1.0, 0.0, 1.0)


def test_a_robot_without_its_hook_or_state_says_what_to_override() -> None:
    class Bare(Robot):
        def step(self) -> RobotState | None:
            return None

        def halt(self, reason: str) -> None:
            pass

    bare = Bare(PluginConfig(), BuildContext(id="bare", rng=np.random.default_rng(0)))
    with pytest.raises(NotImplementedError, match="_begin"):
        bare.begin(line(0.1, 0.2, depth_m=0.02))
    with pytest.raises(NotImplementedError, match="_state"):
        _ = bare.state
    with pytest.raises(NotImplementedError, match="control_rate_hz"):
        _ = bare.control_rate_hz


class ConstantMap(Map):
    def __init__(self) -> None:
        super().__init__(None, BuildContext(id="const", rng=np.random.default_rng(0)))
        self.seen: list[np.ndarray] = []

    @property
    def region(self) -> Region:
        return Region(0.0, 1.0, 0.0, 1.0)

    def update(self, observations: Observations) -> None:
        pass

    def _query(self, points_m: np.ndarray) -> MapEstimate:
        self.seen.append(points_m)
        return MapEstimate(np.full(len(points_m), 0.25), np.full(len(points_m), 0.1))


def test_the_map_base_checks_query_points_once_before_the_hook() -> None:
    the_map = ConstantMap()
    assert the_map.query([0.1, 0.2]).mean.shape == (1,)
    assert the_map.query(np.zeros((3, 2), dtype=np.float32)).mean.shape == (3,)
    assert the_map.seen[-1].dtype == np.float64
    empties: tuple[list[float], np.ndarray] = ([], np.empty((0, 2)))
    for empty in empties:
        assert the_map.query(empty).mean.shape == (0,)
    assert len(the_map.seen) == 2  # an empty query never reaches the hook
    for bad, message in (([[np.nan, 0.1]], "finite"), ([[0.1, -np.inf]], "finite"),
                         (np.zeros((2, 3)), r"shape \(q, 2\)"), (np.zeros(3), r"shape \(q, 2\)")):
        with pytest.raises(ValueError, match=message):
            the_map.query(bad)
    assert len(the_map.seen) == 2
    np.testing.assert_array_equal(query_points([[1.0, 2.0]]), [[1.0, 2.0]])


class _Entry:
    def __init__(self, kind: Kind, cid: str, inputs: tuple[str, ...] = ()) -> None:
        self.kind, self.id, self.inputs = kind, cid, inputs


def test_the_evaluated_map_rule_has_one_home() -> None:
    grid, bhm = _Entry(Kind.MAP, "grid"), _Entry(Kind.MAP, "bhm")
    planner = _Entry(Kind.PLANNER, "planner", ("bhm",))
    assert evaluated_map_id([grid, bhm, planner], None) == "bhm"  # the planner's map
    assert evaluated_map_id([bhm, grid], None) == "grid"  # else the last map
    assert evaluated_map_id([grid, bhm, planner], "grid") == "grid"  # run.evaluation_map
    assert evaluated_map_id([planner], None) is None


def test_the_outline_level_and_live_port_defaults_have_one_home() -> None:
    from hapticframe._config._model import RunSettings
    from hapticframe.cli._common import LIVE_PORT as CLI_PORT
    from hapticframe.live import DEFAULT_PORT

    assert RunSettings().outline_level == OUTLINE_LEVEL == 0.6
    assert RunOutcome(None, None, (), {}, 0.0).outline_level == OUTLINE_LEVEL  # type: ignore[arg-type]
    assert DEFAULT_PORT == CLI_PORT == LIVE_PORT
