"""Several robots in one closed loop: workspaces, continuation at a workspace limit, and the
two-arm example (dissertation 3.5.3.4: EM #2 halted at the arm's limit, EM #3 continued it)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe import RunError, run_experiment, validate_file, validate_mapping
from hapticframe.kinds import ExploratoryMovement
from hapticframe_coverage._coverage import BoustrophedonCoverage

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "search-two-arms.yaml"


def _arm(rid: str, workspace: tuple[float, float] | None, inputs: list[str] | None = None
         ) -> dict[str, Any]:
    arm: dict[str, Any] = {"id": rid, "type": "sandbox"}
    if workspace is not None:
        arm["config"] = {"workspace": {"x_min_m": workspace[0], "x_max_m": workspace[1],
                                       "y_min_m": 0.0, "y_max_m": 0.5}}
    if inputs:
        arm["inputs"] = inputs
    return arm


def _experiment(arms: list[dict[str, Any]], sensor_inputs: list[str]) -> dict[str, Any]:
    """No buried object: every movement rakes freely, so only workspaces end one early."""
    ids = [a["id"] for a in arms]
    return {
        "schema_version": 1,
        "name": "two-arms-test",
        "seed": 3,
        "scene": {"region": {"x_min_m": 0.0, "x_max_m": 0.75, "y_min_m": 0.0, "y_max_m": 0.5},
                  "objects": []},
        "robots": arms,
        "sensors": [{"id": "wrist", "type": "sandbox-force", "inputs": sensor_inputs}],
        "classifiers": [{"id": "jamming", "type": "force-rate-jamming", "inputs": ["wrist"]}],
        "sensor_models": [{"id": "fz", "type": "failure-zone-kernel",
                           "inputs": ["jamming", *ids]}],
        "maps": [{"id": "grid", "type": "occupancy-grid", "inputs": ["fz"]}],
        "planners": [{"id": "planner", "type": "coverage", "inputs": ["grid"]}],
        "run": {"figures": False},
    }


@pytest.fixture
def scripted(monkeypatch):
    """The planner proposes the given lines, then stops."""
    lines: list[tuple[tuple[float, float], tuple[float, float]]] = []

    def propose(self):
        if not lines:
            return None
        start, end = lines.pop(0)
        return ExploratoryMovement(np.array(start), np.array(end), speed_m_per_s=0.05,
                                   phase="phase1", label="scripted")

    monkeypatch.setattr(BoustrophedonCoverage, "propose", propose)
    return lines


def _run(tmp_path: Path, name: str, data: dict[str, Any]):
    lines: list[str] = []
    out = tmp_path / name
    metrics = run_experiment(validate_mapping(data, source=name), out, echo=lines.append)
    with np.load(out / "trace.npz", allow_pickle=False) as trace:
        arrays = {k: trace[k] for k in trace.files}
    with np.load(out / "ground_truth.npz", allow_pickle=False) as truth:
        gt = {k: truth[k] for k in truth.files}
    return metrics, arrays, gt, [line for line in lines if line.startswith("EM ")]


TWO_ARMS = [_arm("arm-a", (0.0, 0.35)), _arm("arm-b", (0.25, 0.75), ["arm-a"])]


def test_a_movement_that_leaves_one_arms_workspace_is_continued_and_counted_once(
    tmp_path, scripted
):
    scripted += [((0.05, 0.1), (0.60, 0.1)), ((0.70, 0.3), (0.50, 0.3))]
    metrics, trace, truth, progress = _run(tmp_path, "two", _experiment(TWO_ARMS,
                                                                        ["arm-a", "arm-b"]))
    assert metrics["movements"] == 2 and metrics["ems_phase1"] == 2
    assert len(progress) == 2
    assert "completed" in progress[0] and "arm-a → arm-b" in progress[0]
    assert "completed" in progress[1] and "  arm-b  " in progress[1] and "arm-a" not in progress[1]
    a_t, a_x = trace["robot/arm-a/timestamps_s"], trace["robot/arm-a/position_m"]
    b_t, b_x = trace["robot/arm-b/timestamps_s"], trace["robot/arm-b/position_m"]
    # arm-a rakes to its limit, arm-b on from there: one movement (index 0) on one clock.
    assert np.all(trace["robot/arm-a/movement_index"] == 0)
    assert a_x[-1, 0] == pytest.approx(0.35, abs=1e-9) and a_x[:, 0].max() <= 0.35
    first_b = trace["robot/arm-b/movement_index"] == 0
    assert b_t[first_b][0] > a_t[-1]
    assert b_x[first_b][0, 0] == pytest.approx(0.35 + 0.05 / 100, abs=1e-9)
    assert b_x[first_b][-1, 0] == pytest.approx(0.60)
    assert np.all(trace["robot/arm-b/movement_index"][~first_b] == 1)
    # The same depth for both parts, and one force stream: the moving arm's.
    depths = np.concatenate([trace["robot/arm-a/depth_m"], trace["robot/arm-b/depth_m"][first_b]])
    assert np.all(depths == depths[0])
    force_t = trace["sensor/wrist/timestamps_s"]
    assert np.array_equal(force_t, np.sort(np.concatenate([a_t, b_t])))
    # The sandbox's truth: both arms' steps in time order, labelled with the arm.
    assert np.all(np.diff(truth["timestamps_s"]) > 0)
    assert set(truth["robot_id"].tolist()) == {"arm-a", "arm-b"}
    assert np.all(truth["movement_index"][truth["timestamps_s"] <= b_t[first_b][-1]] == 0)


def test_no_robot_can_continue_the_movement_ends_halted_at_the_workspace_limit(
    tmp_path, scripted
):
    # A gap between the workspaces: nobody holds the line beyond x = 0.30.
    arms = [_arm("arm-a", (0.0, 0.30)), _arm("arm-b", (0.40, 0.75), ["arm-a"])]
    scripted += [((0.05, 0.1), (0.60, 0.1)), ((0.35, 0.2), (0.60, 0.2))]
    metrics, trace, _, progress = _run(tmp_path, "gap", _experiment(arms, ["arm-a", "arm-b"]))
    assert metrics["movements"] == 2
    assert "workspace_limit" in progress[0] and "arm-a  " in progress[0]
    assert trace["robot/arm-a/position_m"][-1, 0] == pytest.approx(0.30)
    # A start that no workspace holds: refused before any step.
    assert "outside_workspace" in progress[1] and "    0 steps" in progress[1]
    assert "robot/arm-b/timestamps_s" not in trace


def test_one_robot_runs_as_before(tmp_path, scripted):
    # A workspace that holds every movement changes nothing; one that cuts a movement halts
    # it at the limit.
    line = ((0.05, 0.1), (0.60, 0.1))
    scripted += [line]
    free = _run(tmp_path, "free", _experiment([_arm("arm", None)], ["arm"]))
    scripted += [line]
    wide = _run(tmp_path, "wide", _experiment([_arm("arm", (0.0, 0.75))], ["arm"]))
    for key in free[1]:
        assert np.array_equal(free[1][key], wide[1][key]), key
    assert free[3] == wide[3] and "→" not in free[3][0] and "completed" in free[3][0]
    assert {k: v for k, v in free[0].items() if k != "wall_time_s"} == {
        k: v for k, v in wide[0].items() if k != "wall_time_s"}
    assert "robot_id" not in free[2]
    scripted += [line]
    cut = _run(tmp_path, "cut", _experiment([_arm("arm", (0.0, 0.35))], ["arm"]))
    assert "workspace_limit" in cut[3][0]


def test_robots_on_separate_clocks_are_refused(tmp_path, scripted):
    # Two sandboxes that were not linked (no inputs): their clocks overlap.
    arms = [_arm("arm-a", (0.0, 0.35)), _arm("arm-b", (0.25, 0.75))]
    data = _experiment(arms, ["arm-a"])
    scripted += [((0.05, 0.1), (0.60, 0.1))]
    with pytest.raises(RunError, match="share a clock"):
        run_experiment(validate_mapping(data, source="clocks"), tmp_path / "clocks")


def test_the_two_arm_example_validates_and_finds_the_object(tmp_path):
    experiment = validate_file(EXAMPLE)
    lines: list[str] = []
    metrics = run_experiment(experiment, tmp_path / "run", echo=lines.append, progress=False)
    progress = [line for line in lines if line.startswith("EM ")]
    assert metrics["object_found"] and metrics["centroid_error_m"] < 0.03
    assert metrics["movements"] == len(progress)
    assert any("arm-a → arm-b" in line for line in progress)
