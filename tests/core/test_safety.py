"""Safety, the same for every robot: the run's force limit halts within a sample (with and
without look-ahead, latency in metrics.json), a stalled force stream halts, SIGTERM halts and
disables the robot, a movement outside the workspace is refused before motion."""

from __future__ import annotations

import dataclasses
import json
import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe.cli._cli import main
from hapticframe.kinds import ChannelInfo, SampleBatch
from hapticframe.run._dataflow import Dataflow
from hapticframe.testing import check_robot_refuses_outside_workspace, check_robot_stops_at_once
from hapticframe_sandbox import plugin as sandbox_plugin

SUPPORT = Path(__file__).resolve().parent.parent / "support"
PLUGIN = ("--plugin-module", "lab_safety")


@pytest.fixture
def lab_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    shutil.copy(SUPPORT / "lab_safety.py", tmp_path / "lab_safety.py")
    monkeypatch.delitem(sys.modules, "lab_safety", raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def lab() -> Any:
    return sys.modules["lab_safety"]


def scripted(sensor: str = "", run: str = "", arm: str = "", lines: str = "") -> str:
    lines = lines or "[[0.1, 0.2, 0.3, 0.2], [0.1, 0.25, 0.3, 0.25]]"
    return f"""\
schema_version: 1
name: lab-safety
seed: 1
robots:
  - {{id: arm, type: lab-arm, config: {{{arm}}}}}
sensors:
  - {{id: wrist, type: lab-scripted-force, inputs: [arm], config: {{{sensor}}}}}
planners:
  - {{id: planner, type: lab-lines, config: {{lines: {lines}}}}}
run: {{{run}}}
"""


def run(directory: Path, text: str, out: str = "out") -> tuple[int, Path]:
    path = directory / f"{out}.yaml"
    path.write_text(text)
    out_dir = directory / out
    return main(["run", *PLUGIN, str(path), "--out", str(out_dir), "--quiet"]), out_dir


def read(out: Path, name: str) -> dict[str, Any]:
    return json.loads((out / name).read_text())


def halted_throughout(code: int, out: Path) -> None:
    """A run whose every movement a safety check halted is no result: exit 1, run.json
    says failed and why, its files kept (issue 26, section 4)."""
    record = read(out, "run.json")
    assert code == 1 and record["status"] == "failed"
    assert "halted by a safety check" in record["error"]
    assert (out / "metrics.json").is_file() and (out / "trace.npz").is_file()


# --- the force limit -----------------------------------------------------------------------


@pytest.mark.parametrize("lookahead", [1, 64])
@pytest.mark.parametrize("delay", [0, 1, 3])
def test_a_scripted_crossing_gives_exactly_the_expected_latency(lab_dir, delay, lookahead):
    # The force crosses 80 N at the sample of t = 0.5 s, which arrives `delay` steps late.
    code, out = run(lab_dir, scripted(f"cross_at_s: 0.5, delay_steps: {delay}",
                                      f"lookahead_steps: {lookahead}"))
    halted_throughout(code, out)
    metrics, record = read(out, "metrics.json"), read(out, "run.json")
    assert metrics["halt_latency_samples_max"] == delay
    halt, again = record["details"]["safety_halts"]
    assert halt["reason"] == "force_limit" and halt["robot"] == "arm" and halt["movement"] == 0
    assert halt["latency_samples"] == delay
    assert halt["sample_time_s"] == pytest.approx(0.5)
    assert halt["robot_time_s"] == pytest.approx(0.5 + 0.01 * delay)
    assert halt["force_n"] == pytest.approx(100.0) and halt["limit_n"] == 80.0
    first, second = lab().RESULTS
    assert first.halted and first.halt_reason == "force_limit"
    assert first.final_state.timestamp_s == pytest.approx(0.5 + 0.01 * delay)
    # No step after the halt: the trace ends the movement at the halt's step.
    trace = np.load(out / "trace.npz")
    times = trace["robot/arm/timestamps_s"][trace["robot/arm/movement_index"] == 0]
    assert times[-1] == pytest.approx(0.5 + 0.01 * delay)
    assert ("halt", "arm:force_limit") in lab().EVENTS
    # The next movement starts above the limit already (the script stays at its peak) and
    # is halted at its first sample, as late as that sample arrives.
    assert second.halt_reason == "force_limit"
    assert again["movement"] == 1 and again["latency_samples"] == delay


def test_the_limit_is_configurable_and_can_be_switched_off(lab_dir):
    code, out = run(lab_dir, scripted("cross_at_s: 0.5, peak_n: 50", "force_limit_n: 40"))
    halted_throughout(code, out)
    assert read(out, "metrics.json")["halt_latency_samples_max"] == 0
    code, out = run(lab_dir, scripted("cross_at_s: 0.5", "force_limit_n: null"), out="off")
    assert code == 0
    assert read(out, "metrics.json")["halt_latency_samples_max"] is None
    assert "safety_halts" not in read(out, "run.json")["details"]
    assert all(not r.halted for r in lab().RESULTS[-2:])


def sandbox_experiment(lookahead: int) -> str:
    # The sandbox's own (true-force) limit is set above the run's, so that the run's limit on
    # the measured force is what halts the plate as it jams against the ellipse.
    return f"""\
schema_version: 1
name: sandbox-safety
seed: 3
scene:
  region: {{x_min_m: 0.0, x_max_m: 0.75, y_min_m: 0.0, y_max_m: 0.50}}
  objects:
    - {{shape: ellipse, center_m: [0.42, 0.21], semi_axes_m: [0.045, 0.025]}}
robots:
  - {{id: arm, type: sandbox, config: {{force_limit_n: 500}}}}
sensors:
  - {{id: wrist, type: sandbox-force, inputs: [arm]}}
planners:
  - {{id: planner, type: lab-lines, config: {{lines: [[0.25, 0.21, 0.6, 0.21]]}}}}
run: {{force_limit_n: 30, lookahead_steps: {lookahead}, figures: false}}
"""


def test_the_sandbox_halts_within_one_sample_with_and_without_lookahead(lab_dir):
    halts = {}
    for lookahead in (1, 64):
        code, out = run(lab_dir, sandbox_experiment(lookahead), out=f"la{lookahead}")
        halted_throughout(code, out)  # its only movement halted
        metrics, record = read(out, "metrics.json"), read(out, "run.json")
        assert metrics["halt_latency_samples_max"] is not None
        assert metrics["halt_latency_samples_max"] <= 1
        [halt] = record["details"]["safety_halts"]
        assert halt["reason"] == "force_limit" and halt["force_n"] > 30
        halts[lookahead] = halt
        trace = np.load(out / "trace.npz")
        force = np.linalg.norm(trace["sensor/wrist/force_n"], axis=1)
        # The halting sample is the first one over the limit, and the last one recorded.
        assert force[-1] > 30 and np.all(force[:-1] <= 30)
        assert trace["robot/arm/timestamps_s"][-1] == pytest.approx(halt["robot_time_s"])
    assert halts[1] == halts[64]  # the same step, however far the loop looks ahead


def test_the_halt_line_names_the_stream_and_force_that_hit_the_limit(lab_dir, capsys):
    path = lab_dir / "line.yaml"
    path.write_text(sandbox_experiment(1))
    main(["run", *PLUGIN, str(path), "--out", str(lab_dir / "line")])
    halt_line = next(line for line in capsys.readouterr().out.splitlines()
                     if line.startswith("EM ") and "force_limit" in line)
    record = read(lab_dir / "line", "run.json")
    [halt] = record["details"]["safety_halts"]
    assert halt["stream"] == "wrist/force_n"
    assert f"force limit: wrist/force_n {halt['force_n']:.1f} N > 30 N" in halt_line


# --- a stalled force stream ----------------------------------------------------------------


@pytest.mark.parametrize("lookahead", [1, 64])
@pytest.mark.parametrize("silent_as", ["invalid", "missing"])
def test_a_stalled_force_stream_halts_within_the_configured_time(lab_dir, silent_as, lookahead):
    code, out = run(lab_dir, scripted(f"silent_from_s: 0.3, silent_as: {silent_as}",
                                      f"force_stall_s: 0.25, lookahead_steps: {lookahead}, "
                                      "stall_resumes: 0"))
    halted_throughout(code, out)
    halts = read(out, "run.json")["details"]["safety_halts"]
    assert halts[0]["reason"] == "force_stream_stalled" and halts[0]["movement"] == 0
    # The last valid sample arrived at 0.30 s; 0.25 s later the arm is halted.
    assert halts[0]["robot_time_s"] == pytest.approx(0.55)
    assert halts[0]["silent_s"] == pytest.approx(0.25)
    first, second = lab().RESULTS
    assert first.halt_reason == second.halt_reason == "force_stream_stalled"
    # The second movement never gets a valid sample: halted 0.25 s after it began.
    assert second.final_state.timestamp_s == pytest.approx(0.55 + 0.25)
    assert read(out, "metrics.json")["halt_latency_samples_max"] is None


def test_a_stalled_movement_resumes_from_where_it_stopped_a_bounded_number_of_times(lab_dir):
    code, out = run(lab_dir, scripted("silent_from_s: 0.3", "force_stall_s: 0.25"))
    halted_throughout(code, out)
    halts = read(out, "run.json")["details"]["safety_halts"]
    first = [h for h in halts if h["movement"] == 0]
    # Halted at 0.55 s, resumed (the stream still silent) and halted 0.25 s later, twice:
    # run.stall_resumes (2) resumptions, then the movement ends halted.
    assert [h["reason"] for h in first] == ["force_stream_stalled"] * 3
    assert [h["robot_time_s"] for h in first] == pytest.approx([0.55, 0.80, 1.05])
    result = lab().RESULTS[0]
    assert result.halt_reason == "force_stream_stalled"
    assert result.extra["stall_resumes"] == 2
    # Each resumption starts where the robot stopped: one movement, never a step back.
    trace = np.load(out / "trace.npz")
    index = trace["robot/arm/movement_index"]
    x = trace["robot/arm/position_m"][index == 0, 0]
    assert np.all(np.diff(x) >= 0)


def test_the_stall_check_can_be_switched_off(lab_dir):
    code, out = run(lab_dir, scripted("silent_from_s: 0.3", "force_stall_s: null"))
    assert code == 0
    assert all(not r.halted for r in lab().RESULTS)
    assert "safety_halts" not in read(out, "run.json")["details"]


def test_a_read_stuck_in_a_live_run_does_not_stop_the_stall_check(lab_dir, monkeypatch):
    """Issue 26 §6: the watchdog halts the arm while a device call is stuck (the read blocks
    until a halt frees it, or for 10 s). No wall time is asserted: the read is freed by
    the halt, not by its own timeout."""
    from hapticframe.run import _loop

    monkeypatch.setattr(_loop, "_sleep", lambda seconds: None)  # no pacing: a fast test
    code, out = run(lab_dir, scripted("stuck_at_read: 20", "force_stall_s: 0.1, "
                                      "stall_resumes: 0", arm="live: true"))
    assert lab().STUCK == [True]  # freed by the halt while it was stuck
    halts = read(out, "run.json")["details"]["safety_halts"]
    assert halts[0]["reason"] == "force_stream_stalled" and halts[0]["by"] == "watchdog"
    assert halts[0]["silent_s"] >= 0.1
    assert lab().RESULTS[0].halt_reason == "force_stream_stalled"
    assert code == 0


def test_a_stuck_call_takes_no_time_in_a_simulated_run(lab_dir):
    # No live device, no watchdog: the stuck read ends by itself, and in simulation time
    # nothing was silent.
    code, out = run(lab_dir, scripted("stuck_at_read: 2, stuck_for_s: 0.3",
                                      "force_stall_s: 0.1"))
    assert code == 0
    assert lab().STUCK == [False]
    assert "safety_halts" not in read(out, "run.json")["details"]


# --- interrupts ----------------------------------------------------------------------------


def test_sigterm_halts_and_disables_the_robot_before_anything_is_released(lab_dir, capsys):
    code, out = run(lab_dir, scripted("sigterm_at_read: 20", "lookahead_steps: 1"))
    assert code == 143
    record = read(out, "run.json")
    assert record["status"] == "interrupted" and record["signal"] == "SIGTERM"
    assert record["details"]["halted_robots"] == {"reason": "interrupted", "robots": ["arm"]}
    events = lab().EVENTS
    halt = events.index(("halt", "arm:interrupted"))
    # Torque off right after the halt, before any component is closed.
    assert events[halt + 1] == ("torque_off", "arm")
    assert events[halt + 2:] == [("close", "wrist"), ("close", "arm")]
    assert "interrupted (SIGTERM)" in capsys.readouterr().err


# --- the workspace -------------------------------------------------------------------------


def test_a_movement_outside_the_workspace_is_refused_before_motion(lab_dir):
    arm = "workspace: {x_min_m: 0.0, x_max_m: 0.5, y_min_m: 0.0, y_max_m: 0.5}"
    lines = ("[[0.1, 0.2, 0.3, 0.2], [0.7, 0.3, 0.6, 0.3], [0.1, 0.4, 0.3, 0.4], "
             "[0.1, 0.1, 0.7, 0.1]]")
    code, out = run(lab_dir, scripted(arm=arm, lines=lines))
    assert code == 0
    first, refused, third, leaving = lab().RESULTS  # the planner saw the refusal, went on
    assert refused.halted and refused.halt_reason == "outside_workspace"
    assert "holds its start (0.7, 0.3) m" in refused.extra["refused"]
    assert not first.halted and not third.halted
    # A line that leaves is raked up to the boundary, never past it.
    assert leaving.halted and leaving.halt_reason == "workspace_limit"
    trace = np.load(out / "trace.npz")
    assert set(np.unique(trace["robot/arm/movement_index"]).tolist()) == {0, 2, 3}
    assert trace["robot/arm/position_m"][:, 0].max() <= 0.5 + 1e-9
    record = read(out, "run.json")
    assert record["movements"] == 4
    [halt] = record["details"]["safety_halts"]
    assert halt["reason"] == "outside_workspace" and halt["movement"] == 1


# --- the kit's checks on the sandbox -------------------------------------------------------


def sandbox_spec(**check_config: Any) -> Any:
    [spec] = list(sandbox_plugin.hapticframe_robots())
    return dataclasses.replace(spec, check_config=check_config)


def test_the_sandbox_stops_at_once_and_refuses_to_leave_its_workspace():
    check_robot_stops_at_once(sandbox_spec())
    workspace = {"x_min_m": 0.1, "x_max_m": 0.6, "y_min_m": 0.05, "y_max_m": 0.45}
    check_robot_refuses_outside_workspace(sandbox_spec(workspace=workspace))
    check_robot_refuses_outside_workspace(sandbox_spec())  # none declared: nothing to refuse


# --- the dataflow's bookkeeping ------------------------------------------------------------


class _ForceSensor:
    def __init__(self) -> None:
        self.id = "tip"
        self.channels = {"f": ChannelInfo((2,), "N", 100.0), "p": ChannelInfo((), "Pa", 100.0)}


@pytest.mark.parametrize("per_sample", [True, False])
def test_only_valid_samples_count_and_the_first_over_the_limit_is_kept(per_sample):
    flow = object.__new__(Dataflow)  # only the force bookkeeping is exercised
    flow.force_max_n, flow.force_limit_n = float("nan"), 80.0
    t = np.arange(6) / 100
    force = np.array([[3.0, 4.0], [60.0, 80.0], [90.0, 0.0], [np.nan, np.nan], [0, 200], [1, 0]])
    valid = np.array([True, False, True, False, True, True])  # 100 N at 0.01 s is not valid
    pressure = np.zeros(6)
    batch = SampleBatch(t, {"f": force, "p": pressure}, {"f": valid})
    parts = [batch.select(slice(i, i + 1)) for i in range(6)] if per_sample else [batch]
    for part in parts:
        flow._track_force(_ForceSensor(), part)  # type: ignore[arg-type]
    assert flow.valid_force_samples == 4
    assert flow.force_violation_stream == "tip/f"
    assert flow.take_force_violation() == (0.02, 90.0)
    assert flow.take_force_violation() is None  # taken
    assert flow.force_max_n == 200.0  # the console's figure counts every finite sample
