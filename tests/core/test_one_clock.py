"""One clock for every stream (issue 34 §1): the run hands its clock to every sensor; a
stream out of step with the robot ends the run as no result, naming the stream, every file
kept; the conformance kit fails a sensor whose time does not advance with the clock, and
says how to fix it. The newcomer's plugin of the issue (tests/support/lab_newcomer.py: a
fake 3-axis force sensor, five samples a read at 100 Hz) is the case."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from hapticframe.cli._cli import main
from hapticframe.kinds import RunClock
from hapticframe.testing import CheckFailure, check_sensor_keeps_time

SUPPORT = Path(__file__).resolve().parent.parent / "support"
PLUGIN = ("--plugin-module", "lab_newcomer")

SEARCH = """\
schema_version: 1
name: newcomer-search
seed: 7
scene:
  region: {{x_min_m: 0.0, x_max_m: 0.75, y_min_m: 0.0, y_max_m: 0.50}}
  objects:
    - {{shape: ellipse, center_m: [0.42, 0.21], semi_axes_m: [0.045, 0.025]}}
robots:
  - {{id: arm, type: sandbox}}
sensors:
  - {{id: lab, type: {sensor}, config: {{{config}}}}}
classifiers:
  - {{id: jamming, type: force-rate-jamming, inputs: [lab]}}
sensor_models:
  - {{id: failure-zone, type: failure-zone-kernel, inputs: [jamming, arm]}}
maps:
  - {{id: grid, type: occupancy-grid, inputs: [failure-zone]}}
planners:
  - {{id: planner, type: two-phase-coverage, inputs: [grid], config: {{max_movements: 2}}}}
run: {{figures: false, max_movements: 2}}
"""


@pytest.fixture
def lab_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    shutil.copy(SUPPORT / "lab_newcomer.py", tmp_path / "lab_newcomer.py")
    monkeypatch.delitem(sys.modules, "lab_newcomer", raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _run(lab_dir: Path, sensor: str, config: str = "", out: str = "") -> tuple[int, Path]:
    path = lab_dir / f"{out or sensor}.yaml"
    path.write_text(SEARCH.format(sensor=sensor, config=config))
    out_dir = lab_dir / (out or sensor)
    return main(["run", *PLUGIN, str(path), "--out", str(out_dir), "--quiet"]), out_dir


def test_the_newcomers_sensor_ends_the_search_as_no_result_naming_its_stream(lab_dir, capsys):
    code, out = _run(lab_dir, "lab-fake-ft")
    record = json.loads((out / "run.json").read_text())
    assert code == 1 and record["status"] == "failed"
    assert "sensor 'lab' ran ahead of the robot" in record["error"]
    assert "context.clock.due_times" in record["error"]  # the fix, in the reason
    fault = record["details"]["out_of_step"]
    assert fault["stream"] == "lab" and fault["offset_s"] > fault["tolerance_s"]
    # Caught at once: five samples a read against one control period, the first read.
    assert fault["sensor_time_s"] == pytest.approx(5 * fault["robot_time_s"])
    for name in ("metrics.json", "trace.npz", "run.mcap"):
        assert (out / name).is_file()
    trace = np.load(out / "trace.npz")
    assert trace["sensor/lab/timestamps_s"].size > 0  # what it delivered is kept
    assert "ran ahead of the robot" in capsys.readouterr().err


def test_the_same_sensor_on_the_runs_clock_keeps_step(lab_dir):
    code, out = _run(lab_dir, "lab-fake-ft-clocked")
    assert code == 0, (out / "run.json").read_text()
    trace = np.load(out / "trace.npz")
    sensor_t, robot_t = trace["sensor/lab/timestamps_s"], trace["robot/arm/timestamps_s"]
    assert sensor_t[-1] == pytest.approx(robot_t[-1], abs=0.01)
    assert np.all(np.diff(sensor_t) > 0)


def test_a_stream_stamped_behind_the_robot_ends_the_run_too(lab_dir):
    code, out = _run(lab_dir, "lab-fake-ft-clocked", "late_s: 0.5", out="late")
    record = json.loads((out / "run.json").read_text())
    assert code == 1 and "sensor 'lab' ran behind the robot" in record["error"]
    fault = record["details"]["out_of_step"]
    assert fault["offset_s"] == pytest.approx(-0.5, abs=0.011)
    # 20 ms late is within its tolerance (one control period and one sample).
    code, out = _run(lab_dir, "lab-fake-ft-clocked", "late_s: 0.015", out="slightly-late")
    assert code == 0


def test_the_kit_fails_the_newcomers_sensor_with_the_fix(lab_dir, monkeypatch):
    monkeypatch.syspath_prepend(str(lab_dir))
    import lab_newcomer

    original, clocked = list(lab_newcomer.hapticframe_sensors())
    with pytest.raises(CheckFailure) as info:
        check_sensor_keeps_time(original)
    message = str(info.value)
    assert "5x the robot's" in message and "self.context.clock.due_times" in message
    check_sensor_keeps_time(clocked)  # the fixed sensor passes


def test_due_times_lie_on_the_rate_grid_whatever_the_read_size():
    clock = RunClock(0.01)
    assert clock.due_times(100.0).size == 0  # nothing is due before the first period
    got = []
    last = None
    for periods in (1, 3, 0, 7, 1):
        clock.advance(periods)
        times = clock.due_times(100.0, after_s=last)
        got.extend(times)
        last = times[-1] if times.size else last
    assert np.allclose(got, 0.01 * np.arange(1, 13))
    # A slower stream owes a sample only every fourth period; a faster one several.
    assert clock.due_times(25.0).tolist() == pytest.approx([0.04, 0.08, 0.12])
    assert clock.due_times(400.0, after_s=0.1).size == 8
    # 10^6 periods do not accumulate error.
    clock.advance(1_000_000)
    assert clock.now_s() == pytest.approx(1_000_012 * 0.01, abs=1e-9)


def test_a_clock_that_follows_a_robot_is_not_advanced_by_hand_and_refuses_bad_rates():
    state = {"t": 0.5}
    clock = RunClock(0.01)
    clock.follow(lambda: state["t"], period_s=0.002)
    assert clock.follows and clock.period_s == 0.002 and clock.now_s() == 0.5
    state["t"] = 0.25  # a robot rewound for a look-ahead replay takes the clock back
    assert clock.now_s() == 0.25
    with pytest.raises(RuntimeError):
        clock.advance()
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError):
            clock.due_times(bad)
        with pytest.raises(ValueError):
            RunClock(bad)
