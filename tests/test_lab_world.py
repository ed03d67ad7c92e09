"""A world is a public seam (issue 32 §3): a lab's third world, written with public names only
(``tests/support/lab_world.py``), behind the sandbox robot, drives a search and an emulated
rig; the bundled worlds are the same kind of object."""

from __future__ import annotations

import json
import math
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from hapticframe import Circle, Scene
from hapticframe.cli import main
from hapticframe.kinds import (
    BuildContext,
    ExploratoryMovement,
    PlateMovement,
    PlateSample,
    TruthState,
    World,
    WorldResponse,
)
from hapticframe_mpm_sand import MpmSandRobot, MpmSandRobotConfig, MpmSandWorld
from hapticframe_sandbox import AnalyticSandWorld, SandboxRobot, SandboxRobotConfig
from tests.support.lab_world import DragWallConfig, DragWallRobot, DragWallWorld

SUPPORT = Path(__file__).parent / "support"
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SCENE = Scene(objects=[Circle(center_m=(0.3, 0.25), radius_m=0.04)])
TOWARDS_CIRCLE = ExploratoryMovement((0.05, 0.25), (0.34, 0.25), speed_m_per_s=0.05)


def _robot(cls: type[SandboxRobot], config: SandboxRobotConfig, seed: int = 2) -> SandboxRobot:
    return cls(config, BuildContext(id="arm", rng=np.random.default_rng(seed), scene=SCENE))


@pytest.fixture
def lab(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The lab's world module beside its experiments, imported by ``--plugin-module``."""
    shutil.copy(SUPPORT / "lab_world.py", tmp_path / "lab_world.py")
    monkeypatch.delitem(sys.modules, "lab_world", raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_the_lab_world_answers_by_its_own_law_behind_the_sandbox_robot() -> None:
    robot = _robot(DragWallRobot, DragWallConfig(force_limit_n=60.0))
    assert isinstance(robot.world, DragWallWorld)
    robot.execute(TOWARDS_CIRCLE)
    truth = robot.ground_truth
    states, force = truth.states, truth.force_magnitude_n
    # Free, then jamming from 3 cm before the circle, then contact: in that order.
    assert states[0] == TruthState.FREE and states[-1] == TruthState.CONTACT
    assert np.all(np.diff(states) >= 0)
    np.testing.assert_allclose(force[states == 0], 4.0, rtol=1e-12)
    jam = states == 1
    np.testing.assert_array_equal(force[jam], 16.0)
    x_jam = truth.positions_m[jam, 0]
    assert x_jam.min() == pytest.approx(0.26 - 0.03, abs=0.002)
    # The contact spring rises from the jamming drag; the sandbox halts at its force limit.
    contact = force[states == 2]
    assert np.all(np.diff(contact) > 0) and contact[0] >= 16.0
    assert robot.halt_reason == "force_limit" and contact[-1] > 60.0
    # Against the motion (+x): the force points to -x.
    assert np.all(truth.forces_n[:, 0] < 0) and np.all(truth.forces_n[:, 1] == 0)


WORLDS = [(SandboxRobot, SandboxRobotConfig(force_limit_n=1000.0), AnalyticSandWorld),
          (MpmSandRobot, MpmSandRobotConfig(force_limit_n=1000.0), MpmSandWorld),
          (DragWallRobot, DragWallConfig(force_limit_n=1000.0), DragWallWorld)]


@pytest.mark.parametrize(("cls", "config", "world"), WORLDS)
def test_a_world_is_rewound_with_its_robot(cls, config, world) -> None:
    robot = _robot(cls, config)
    robot.begin(TOWARDS_CIRCLE)
    for _ in range(400):  # near the object: jamming, then contact, ahead
        robot.step()
    snapshot = robot.checkpoint()
    first = [robot.step() for _ in range(60)]
    forces = robot.ground_truth.forces_n[-60:].copy()
    robot.rewind(snapshot)
    again = [robot.step() for _ in range(60)]
    assert [s.position_m.tolist() for s in first if s] == [
        s.position_m.tolist() for s in again if s]
    np.testing.assert_array_equal(robot.ground_truth.forces_n[-60:], forces)
    assert robot.ground_truth.states[-1] == TruthState.CONTACT


@pytest.mark.parametrize(("cls", "config", "world"), WORLDS)
def test_every_world_is_a_world_and_any_can_be_asked_directly(cls, config, world) -> None:
    robot = _robot(cls, config)
    assert type(robot.world) is world and isinstance(robot.world, World)
    line = ExploratoryMovement((0.05, 0.25), (0.15, 0.25), speed_m_per_s=0.05)
    robot.execute(line)
    # The same world, asked without any robot along the same line: the robot's truth.
    other = _robot(cls, config).world
    dt = 1 / config.control_rate_hz
    other.begin(PlateMovement(index=0, start_m=(0.05, 0.25), heading_rad=0.0,
                              length_m=line.length_m, depth_m=config.depth_m,
                              speed_m_per_s=0.05, control_period_s=dt,
                              plate_width_m=config.plate_width_m))
    truth = robot.ground_truth
    travelled = 0.0
    assert len(truth) > 150
    for k in range(len(truth)):
        advance = min(0.05 * dt, line.length_m - travelled)
        travelled += advance
        position = (0.05 + travelled * 1.0, 0.25 + travelled * 0.0)
        assert position == tuple(truth.positions_m[k].tolist())
        response = other.respond(PlateSample(float(truth.timestamps_s[k]), position,
                                             travelled, advance, 0.05, 0.0))
        assert response.force_n == tuple(truth.forces_n[k].tolist())
        assert response.state == truth.states[k]


def test_records_refuse_what_a_world_must_not_say() -> None:
    with pytest.raises(ValueError, match="finite"):
        WorldResponse((math.nan, 0.0), 0)
    with pytest.raises(ValueError, match="finite"):
        WorldResponse((1.0, math.inf), 1)
    with pytest.raises(ValueError, match="state"):
        WorldResponse((1.0, 0.0), 3)
    with pytest.raises(ValueError, match="depth"):
        PlateMovement(0, (0.0, 0.0), 0.0, 0.1, 0.0, 0.05, 0.01, 0.02)
    with pytest.raises(ValueError, match="finite"):
        PlateMovement(0, (0.0, math.nan), 0.0, 0.1, 0.03, 0.05, 0.01, 0.02)
    assert WorldResponse((1.0, -2.0), TruthState.JAMMING).state == 1


def test_a_search_finds_the_object_in_the_lab_world(lab: Path) -> None:
    text = (EXAMPLES / "search-ellipse.yaml").read_text()
    assert text.count("type: sandbox\n") == 1
    (lab / "search.yaml").write_text(
        text.replace("type: sandbox\n", "type: drag-wall\n")
        + "  figures: false\n")
    code = main(["run", "--plugin-module", "lab_world", "search.yaml", "--out", "out",
                 "--quiet"])
    assert code == 0
    metrics = json.loads((lab / "out" / "metrics.json").read_text())
    assert metrics["object_found"] is True and metrics["object_interactions"] >= 1
    assert metrics["centroid_error_m"] < 0.02
    truth = np.load(lab / "out" / "ground_truth.npz")
    force = np.hypot(*truth["force_n"].T)
    # Every step's force is the lab world's: 4 N free, 16 N jamming (the search halts there).
    np.testing.assert_allclose(force[truth["state"] == 0], 4.0, rtol=1e-12)
    assert (truth["state"] == 1).any()
    np.testing.assert_allclose(force[truth["state"] == 1], 16.0, rtol=1e-12)
    # The bundled force sensor reads it with its noise.
    trace = np.load(lab / "out" / "trace.npz")
    measured = np.linalg.norm(trace["sensor/wrist/force_n"], axis=1)
    assert measured.size == force.size and np.median(np.abs(measured - force)) < 0.5


RIG = """\
schema_version: 1
name: lab-world-rig
seed: 3
scene:
  region: {x_min_m: 0.0, x_max_m: 0.3, y_min_m: 0.0, y_max_m: 0.2}
  objects:
    - {shape: circle, center_m: [0.15, 0.06], radius_m: 0.03}
robots:
  - id: gantry
    type: dynamixel
    config: {port: emulated, faults: none,
             workspace: {x_min_m: 0.0, x_max_m: 0.3, y_min_m: 0.0, y_max_m: 0.2}}
  - {id: sand, type: drag-wall, inputs: [gantry], config: {follows: gantry}}
sensors:
  - id: wrist
    type: robotiq-ft300
    inputs: [sand]
    config: {port: emulated, faults: none, tare_s: 0.0, noise_std_n: 0.0, noise_std_nm: 0.0}
classifiers:
  - {id: jamming, type: force-rate-jamming, inputs: [wrist]}
sensor_models:
  - {id: failure-zone, type: failure-zone-kernel, inputs: [jamming, gantry]}
maps:
  - {id: grid, type: occupancy-grid, inputs: [failure-zone]}
planners:
  - {id: planner, type: two-phase-coverage, inputs: [grid]}
run: {max_movements: 1, figures: false}
"""


def test_an_emulated_rig_follows_the_lab_world(lab: Path) -> None:
    """A Dynamixel gantry (emulated servos) moves; the lab world follows its measured
    fingertip; an emulated FT 300 measures the world's force through its protocol."""
    (lab / "rig.yaml").write_text(RIG)
    code = main(["run", "--plugin-module", "lab_world", "rig.yaml", "--out", "out", "--quiet"])
    assert code == 0
    truth = np.load(lab / "out" / "ground_truth.npz")
    trace = np.load(lab / "out" / "trace.npz")
    states, force = truth["state"], np.hypot(*truth["force_n"].T)
    assert (states == 0).sum() > 50 and (states == 1).any()
    np.testing.assert_allclose(force[states == 0], 4.0, rtol=1e-12)
    # The world stood where the gantry measured its fingertip, step for step.
    gantry_t, gantry_xy = trace["robot/gantry/timestamps_s"], trace["robot/gantry/position_m"]
    steps = np.searchsorted(gantry_t, truth["timestamps_s"])
    np.testing.assert_array_equal(gantry_xy[steps], truth["position_m"])
    # The FT 300 (tool frame: x along the motion, z up; no noise) reads the world's drag in
    # the plane and the end effector's weight along z; its 0.01 N counts round it.
    ft = trace["sensor/wrist/force_n"]
    ft_t = trace["sensor/wrist/timestamps_s"]
    moving = (ft_t > truth["timestamps_s"][5]) & (ft_t < truth["timestamps_s"][states == 1][0])
    in_plane = np.hypot(ft[moving, 0], ft[moving, 1])
    assert moving.sum() > 30
    assert np.median(np.abs(in_plane - 4.0)) < 0.05
    np.testing.assert_allclose(ft[moving, 2], 0.8 * 9.80665, atol=0.02)
    assert np.hypot(ft[:, 0], ft[:, 1]).max() > 15.0  # the jamming step, 16 N


def test_the_architecture_pages_world_runs() -> None:
    page = (Path(__file__).resolve().parents[1] / "docs" / "architecture.md").read_text()
    section = page[page.index("### Worlds: the sand behind a simulated robot"):]
    block = section[section.index("```python\n") + 10:section.index("```\n", 10)]
    namespace: dict[str, object] = {"__name__": "architecture_world"}
    exec(compile(block, "docs/architecture.md", "exec"), namespace)
    robot_type = namespace["ConstantDragRobot"]
    assert isinstance(robot_type, type) and issubclass(robot_type, SandboxRobot)
    robot = _robot(robot_type, SandboxRobotConfig())
    robot.execute(TOWARDS_CIRCLE)  # through the circle: this world has no objects
    truth = robot.ground_truth
    assert len(truth) > 500 and not truth.states.any()
    np.testing.assert_allclose(truth.forces_n, np.tile([-4.0, 0.0], (len(truth), 1)))


@pytest.mark.parametrize(("cls", "config", "world"), WORLDS)
def test_any_world_follows_a_robot_as_it_moves_its_own_plate(cls, config, world) -> None:
    """A world behind a follower meets the same physics at a robot that moves exactly as
    the sandbox's own plate would (the analytic world's case is tests/test_follow_world.py)."""
    from tests.test_follow_world import LineRobot

    own = _robot(cls, config, seed=4)
    own.execute(TOWARDS_CIRCLE)
    line = LineRobot()
    sand = cls(config.model_copy(update={"follows": "line"}),
               BuildContext(id="sand", rng=np.random.default_rng(4), inputs={"line": line},
                            scene=SCENE))
    assert type(sand.world) is world
    movement = sand.follow_begin(TOWARDS_CIRCLE)
    line.begin(movement)
    while (state := line.step()) is not None:
        sand.follow_step(state)
    a, b = own.ground_truth, sand.ground_truth
    n = len(a)
    assert len(b) >= n > 400
    assert a.states.max() == TruthState.CONTACT
    np.testing.assert_array_equal(a.states, b.states[:n])
    np.testing.assert_allclose(b.forces_n[:n], a.forces_n, rtol=1e-9, atol=1e-9)
