"""The sandbox as the world around another robot (``follows``), and the run loop's roles:
robots that follow or are controlled take no movements of their own."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe import Circle, PluginConfig, RunError, Scene, run_experiment, validate_mapping
from hapticframe.kinds import (
    BuildContext,
    ClassProbabilities,
    ExploratoryMovement,
    MovementResult,
    Robot,
    RobotFollower,
    RobotState,
)
from hapticframe.run._dataflow import Dataflow
from hapticframe.run._robots import RobotTeam
from hapticframe.run._verdict import RunInconclusive
from hapticframe_sandbox import SandboxRobot, SandboxRobotConfig

ROOT = Path(__file__).resolve().parents[1]
SCENE = Scene(objects=[Circle(center_m=(0.3, 0.25), radius_m=0.04)])
TOWARDS_CIRCLE = ExploratoryMovement((0.05, 0.25), (0.34, 0.25), speed_m_per_s=0.05)


class LineRobot(Robot):
    """Moves exactly along each line at its speed, one control period per step: what the
    sandbox's own plate does, so that a sandbox following it must compute the same forces."""

    def __init__(self, rid: str = "line", rate_hz: float = 100.0) -> None:
        super().__init__(PluginConfig(), BuildContext(id=rid, rng=np.random.default_rng(0)))
        self._rate = rate_hz
        self._steps = 0
        self._state = RobotState(0.0, np.zeros(2), 0.0, 0.044, 0.0)
        self._active = False
        self.coupled: Any = None
        self.begun: list[ExploratoryMovement] = []

    @property
    def control_rate_hz(self) -> float:
        return self._rate

    @property
    def state(self) -> RobotState:
        return self._state

    def couple_environment(self, environment: Any) -> None:
        self.coupled = environment

    def begin(self, movement: ExploratoryMovement) -> None:
        self.begun.append(movement)
        self._movement = movement
        self._travelled = 0.0
        self._active = movement.length_m > 0
        self._direction = (movement.end_m - movement.start_m) / movement.length_m

    def step(self) -> RobotState | None:
        if not self._active:
            return None
        m = self._movement
        dt = 1.0 / self._rate
        advance = min(m.speed_m_per_s * dt, m.length_m - self._travelled)
        self._travelled += advance
        self._steps += 1
        sx, sy = m.start_m.tolist()
        dx, dy = self._direction.tolist()
        position = np.array([sx + self._travelled * dx, sy + self._travelled * dy])
        self._state = RobotState(self._steps * dt, position, m.heading_rad,
                                 float(m.depth_m if m.depth_m is not None else 0.044),
                                 m.speed_m_per_s)
        if self._travelled >= m.length_m:
            self._active = False
        return self._state

    def halt(self, reason: str) -> None:
        self._active = False


def _follower(robot: Robot, seed: int = 4, **config: Any) -> SandboxRobot:
    return SandboxRobot(
        SandboxRobotConfig(follows=robot.id, **config),
        BuildContext(id="sand", rng=np.random.default_rng(seed), inputs={robot.id: robot},
                     scene=SCENE),
    )


def _follow(sand: SandboxRobot, robot: Robot, movement: ExploratoryMovement) -> None:
    movement = sand.follow_begin(movement)
    robot.begin(movement)
    while (state := robot.step()) is not None:
        sand.follow_step(state)


def test_following_an_exact_robot_reproduces_the_sandboxs_own_physics() -> None:
    own = SandboxRobot(SandboxRobotConfig(),
                       BuildContext(id="own", rng=np.random.default_rng(4), scene=SCENE))
    own.execute(TOWARDS_CIRCLE)
    line = LineRobot()
    sand = _follower(line)
    _follow(sand, line, TOWARDS_CIRCLE)
    a, b = own.ground_truth, sand.ground_truth
    # The sandbox halts its own plate at its force limit; a follower never halts a robot
    # (the run loop's force limit does): the same steps up to there.
    assert own.halt_reason == "force_limit"
    n = len(a)
    assert len(b) > n > 400
    assert np.array_equal(a.states, b.states[:n])
    assert a.states.max() == 2  # the line reached the object: jamming, then contact
    np.testing.assert_allclose(b.forces_n[:n], a.forces_n, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(b.timestamps_s[:n], a.timestamps_s, rtol=0, atol=1e-12)


def test_follower_fills_open_depths_from_its_schedule_and_couples_the_robot() -> None:
    line = LineRobot()
    sand = _follower(line, depth_m=0.03, min_depth_m=0.01)
    assert line.coupled is sand
    assert isinstance(sand, RobotFollower) and sand.followed_robot_id == "line"
    begun = sand.follow_begin(TOWARDS_CIRCLE)
    assert begun.depth_m == pytest.approx(0.03)
    given = ExploratoryMovement((0.05, 0.4), (0.2, 0.4), depth_m=0.02)
    sand.on_movement_end(MovementResult(0, TOWARDS_CIRCLE, False, "", line.state))
    assert sand.follow_begin(given) is given  # a depth given is kept


def test_follower_shows_the_tool_at_rest_between_movements() -> None:
    line = LineRobot()
    sand = _follower(line)
    _follow(sand, line, TOWARDS_CIRCLE)
    last = sand.truth_time_s
    during = sand.physical_truth(last)
    assert np.hypot(*during.force_n[:2]) > 1.0  # raking: the sand pushes back
    sand.on_movement_end(MovementResult(0, TOWARDS_CIRCLE, False, "", line.state))
    rest = sand.physical_truth(last + 0.5)  # transiting to the next start
    assert np.all(rest.force_n == 0.0) and np.all(rest.linear_velocity_m_per_s == 0.0)
    assert np.array_equal(sand.physical_truth(last).force_n, during.force_n)


def test_follower_refuses_what_cannot_be_meant() -> None:
    line = LineRobot()
    sand = _follower(line)
    with pytest.raises(ValueError, match="makes no movements of its own"):
        sand.begin(TOWARDS_CIRCLE)
    with pytest.raises(ValueError, match="before follow_begin"):
        sand.follow_step(RobotState(0.01, np.zeros(2), 0.0, 0.044, 0.0))
    sand.follow_begin(TOWARDS_CIRCLE)
    sand.follow_step(RobotState(0.01, np.array([0.05, 0.25]), 0.0, 0.044, 0.05))
    with pytest.raises(ValueError, match="does not come after"):
        sand.follow_step(RobotState(0.01, np.array([0.05, 0.25]), 0.0, 0.044, 0.05))
    with pytest.raises(ValueError, match="name it in the sandbox's inputs"):
        SandboxRobot(SandboxRobotConfig(follows="other"),
                     BuildContext(id="s", rng=np.random.default_rng(0), scene=SCENE))


def test_follower_refuses_real_hardware() -> None:
    class LiveRobot(LineRobot):
        live = True

        def configure(self) -> None: ...
        def activate(self) -> None: ...
        def deactivate(self) -> None: ...
        def cleanup(self) -> None: ...

        @property
        def health(self) -> Any:
            return None

    with pytest.raises(ValueError, match="drives real hardware"):
        _follower(LiveRobot())


def test_team_gives_movements_only_to_robots_that_follow_and_are_controlled_by_none() -> None:
    class Hand(LineRobot):
        def __init__(self, carrier: Robot) -> None:
            super().__init__("hand")
            self.carrier = carrier

        @property
        def controlled_robots(self) -> tuple[Robot, ...]:
            return (self.carrier,)

    arm = LineRobot("arm")
    hand = Hand(arm)
    sand = _follower(hand)
    flow = Dataflow.__new__(Dataflow)  # RobotTeam reads flow.poses only with several robots
    team = RobotTeam([arm, hand, sand], flow)
    assert team.robots == [hand]
    assert team.followers == {"hand": [sand]}
    begun = team.begin(hand, TOWARDS_CIRCLE)
    assert begun.depth_m == pytest.approx(0.044) and hand.begun == [begun]
    step = team.stepper(hand)
    state = step()
    assert state is not None and sand.truth_time_s == state.timestamp_s
    # Following the controlled arm instead of the hand is refused, with what to do.
    with pytest.raises(RunError, match="follow 'hand'"):
        RobotTeam([arm, hand, _follower(arm)], flow)
    with pytest.raises(RunError, match="moves on its own"):
        RobotTeam([_follower(arm)], flow)


def test_samples_from_before_a_movement_are_not_located() -> None:
    calls: list[np.ndarray] = []

    class Poses:
        def at(self, times: np.ndarray) -> tuple[np.ndarray, ...]:
            calls.append(times)
            n = len(times)
            return np.zeros((n, 2)), np.zeros(n), np.full(n, 0.04)

    flow = Dataflow.__new__(Dataflow)
    flow.sensor_models = []  # no sensor model: _observe returns after the filter
    flow.movement_start_s = -math.inf
    flow.recording = None
    flow.locate_from(2.0)
    probs = ClassProbabilities(np.array([1.0, 1.5]), np.array([[1.0, 0.0]] * 2), ("a", "b"))
    flow._observe("clf", probs)  # everything before the start: nothing located
    assert calls == []
    flow.sensor_models = ["fz"]
    flow.sm_classifier = {"fz": "clf"}
    flow.sm_pose_source = {"fz": "arm"}
    flow.poses = {"arm": Poses()}

    class Model:
        def observe(self, located: Any) -> list[Any]:
            return []

    flow.components = type("C", (), {"sensor_models": {"fz": Model()}})()
    probs = ClassProbabilities(np.array([1.0, 2.0, 3.0]), np.array([[1.0, 0.0]] * 3), ("a", "b"))
    flow._observe("clf", probs)
    assert len(calls) == 1 and calls[0].tolist() == [2.0, 3.0]


def test_the_dynamixel_example_runs_the_whole_rig(tmp_path: Path) -> None:
    experiment = validate_mapping(_quick(ROOT / "examples" / "search-ellipse-dynamixel.yaml"),
                                  source="example")
    metrics = run_experiment(experiment, tmp_path / "run")
    assert metrics["movements"] == 2
    assert set(metrics["devices"]) == {"gantry", "wrist", "imu"}
    assert metrics["devices"]["gantry"]["frames"] > 1000
    assert metrics["max_force_n"] > 5.0  # the sandbox computed the sand's force
    assert (tmp_path / "run" / "ground_truth.npz").exists()


def _quick(path: Path) -> dict[str, Any]:
    import yaml

    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    data.setdefault("run", {}).update({"max_movements": 2, "figures": False})
    return data


def test_the_whole_emulated_rig_halts_at_the_force_limit_within_one_sample(
    tmp_path: Path,
) -> None:
    data = _quick(ROOT / "examples" / "search-ellipse-dynamixel.yaml")
    # Above the free drag at 4.4 cm (15 N, or every movement would halt at once: refused),
    # below the jamming surge ahead of the ellipse.
    data["run"].update({"max_movements": 1, "force_limit_n": 20.0})
    # Its only movement halted: the run is no result (exit 1), its files kept.
    with pytest.raises(RunInconclusive, match="halted by a safety check") as caught:
        run_experiment(validate_mapping(data, source="example"), tmp_path / "run")
    metrics = caught.value.metrics
    assert metrics["halt_latency_samples_max"] is not None
    assert metrics["halt_latency_samples_max"] <= 1
    run = json.loads((tmp_path / "run" / "run.json").read_text(encoding="utf-8"))
    (halt,) = run["details"]["safety_halts"]
    assert halt["reason"] == "force_limit" and halt["robot"] == "gantry"
    assert halt["force_n"] > 20.0 and halt["latency_samples"] <= 1
