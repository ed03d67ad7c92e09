"""Devices in a run: configured and activated before the loop, released after it in reverse
order; a DeviceError halts the robots and fails the run cleanly; health counters reach
metrics.json and the progress lines; a live device paces the loop by the wall clock."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from hapticframe.cli._cli import main
from hapticframe.kinds import BuildContext, Device
from hapticframe.run import _loop
from tests.support import lab_devices

SUPPORT = Path(__file__).resolve().parent.parent / "support"
PLUGIN = ("--plugin-module", "lab_devices")


def closed_loop(a: str = "", b: str = "", run: str = "") -> str:
    return f"""\
schema_version: 1
name: lab-devices
seed: 1
robots:
  - {{id: arm, type: lab-line-robot, config: {{steps: 4}}}}
sensors:
  - {{id: a, type: lab-device, inputs: [arm], config: {{{a}}}}}
  - {{id: b, type: lab-device, inputs: [arm], config: {{{b}}}}}
planners:
  - {{id: planner, type: lab-line-planner, config: {{movements: 3}}}}
run: {{{run}}}
"""


def open_loop(config: str, run: str = "") -> str:
    return f"""\
schema_version: 1
name: lab-devices-open
seed: 1
sensors:
  - {{id: wrist, type: lab-device, config: {{{config}}}}}
run: {{{run}}}
"""


@pytest.fixture
def lab_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    shutil.copy(SUPPORT / "lab_devices.py", tmp_path / "lab_devices.py")
    monkeypatch.delitem(sys.modules, "lab_devices", raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def run(directory: Path, text: str, *, quiet: bool = True, out: str = "out") -> tuple[int, Path]:
    path = directory / "devices.yaml"
    path.write_text(text)
    out_dir = directory / out
    args = ["run", *PLUGIN, str(path), "--out", str(out_dir)] + (["--quiet"] if quiet else [])
    return main(args), out_dir


def events() -> list[tuple[str, str]]:
    return list(sys.modules["lab_devices"].EVENTS)


def test_the_hand_made_devices_satisfy_the_protocol():
    context = BuildContext(id="x", rng=np.random.default_rng(0))
    sensor = lab_devices.DeviceSensor(lab_devices.DeviceSensorConfig(), context)
    robot = lab_devices.LineRobot(lab_devices.LineRobotConfig(), context)
    planner = lab_devices.LinePlanner(lab_devices.LinePlannerConfig(), context)
    assert isinstance(sensor, Device) and isinstance(robot, Device)
    assert not isinstance(planner, Device)
    assert sensor.live is False and sensor.health.faults() == {}


def test_devices_come_up_in_build_order_and_go_down_in_reverse(lab_dir):
    code, out = run(lab_dir, closed_loop())
    assert code == 0, (out / "run.json").read_text()
    up = [("configure", "arm"), ("activate", "arm"), ("configure", "a"), ("activate", "a"),
          ("configure", "b"), ("activate", "b")]
    down = [("deactivate", "b"), ("cleanup", "b"), ("deactivate", "a"), ("cleanup", "a"),
            ("deactivate", "arm"), ("cleanup", "arm")]
    # Sensors are read only while active (a read otherwise fails the run), and every
    # device is released before any component is closed.
    assert events() == [*up, *down, ("close", "b"), ("close", "a"), ("close", "arm")]
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "ok" and record["movements"] == 3


def test_a_device_error_halts_the_robot_and_fails_the_run_cleanly(lab_dir, capsys):
    code, out = run(lab_dir, closed_loop(b="fail_at_read: 6"))
    assert code == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.startswith("error: the run failed: device failure in 'b' (sensor): ")
    assert "b: no valid frame for 0.16 s and 3 recoveries failed" in err
    assert "(halted 'arm')" in err
    log = events()
    # The robot is stopped, and deactivated, before any other device is released.
    halt = log.index(("halt", "arm:device failure"))
    assert log[halt + 1] == ("deactivate", "arm")
    assert log[halt + 2:halt + 6] == [("deactivate", "b"), ("cleanup", "b"),
                                      ("deactivate", "a"), ("cleanup", "a")]
    assert ("cleanup", "arm") in log[halt:]
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "failed"
    assert record["error"].startswith("device failure in 'b' (sensor): b: no valid frame")
    assert record["details"]["devices"]["b"]["frames"] == 5
    assert not (out / "metrics.json").exists()


def test_health_counters_reach_metrics_json_and_the_progress_lines(lab_dir, capsys):
    code, out = run(lab_dir, closed_loop(a="crc_errors_per_read: 1"), quiet=False)
    assert code == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics["devices"]) == {"arm", "a", "b"}
    assert metrics["devices"]["a"]["crc_errors"] == 12 and metrics["devices"]["a"]["frames"] == 12
    assert metrics["devices"]["a"]["resyncs"] == 48
    assert metrics["devices"]["b"]["crc_errors"] == 0 and metrics["devices"]["b"]["frames"] == 12
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("EM ")]
    assert len(lines) == 3
    assert lines[0].endswith("| a: crc_errors 4, resyncs 16")
    assert lines[2].endswith("| a: crc_errors 12, resyncs 48")
    assert all("b:" not in line and "arm:" not in line for line in lines)  # no faults, no noise


def test_the_open_loop_reports_device_faults_at_its_end(lab_dir, capsys):
    code, _ = run(lab_dir, open_loop("reads: 3, crc_errors_per_read: 2"), quiet=False)
    assert code == 0
    # Three reads (the loop once counted the check that found the sensor ended as a fourth).
    assert "3 sensor reads | wrist: crc_errors 6, resyncs 24" in capsys.readouterr().out


class FakeWallClock:
    def __init__(self) -> None:
        self.now = 100.0
        self.sleeps: list[float] = []

    def monotonic(self) -> float:
        self.now += 0.001  # every look at the clock costs a millisecond of "work"
        return self.now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.now += seconds


@pytest.fixture
def wall_clock(monkeypatch: pytest.MonkeyPatch) -> FakeWallClock:
    clock = FakeWallClock()
    monkeypatch.setattr(_loop, "_monotonic", clock.monotonic)
    monkeypatch.setattr(_loop, "_sleep", clock.sleep)
    return clock


def test_a_live_device_paces_the_open_loop(lab_dir, wall_clock):
    code, _ = run(lab_dir, open_loop("reads: 6, live: true", run="live_tick_s: 0.02"))
    assert code == 0
    # Six ticks: the first starts at once, each later one 20 ms after the one before it
    # (the clock advanced 1 ms between looks, so each wait is 19 ms).
    assert wall_clock.sleeps == pytest.approx([0.019] * 5)


def test_simulated_runs_are_never_paced(lab_dir, wall_clock):
    code, _ = run(lab_dir, open_loop("reads: 6", run="live_tick_s: 0.02"))
    assert code == 0
    code, _ = run(lab_dir, closed_loop(), out="closed")
    assert code == 0
    assert wall_clock.sleeps == []


def test_a_live_device_paces_the_closed_loop_at_the_robot_rate(lab_dir, wall_clock):
    code, _ = run(lab_dir, closed_loop(a="live: true"))
    assert code == 0
    # 3 movements of 4 steps, plus the step that ends each movement: 15 steps; the robot
    # runs at 100 Hz, so each step after the first waits for 10 ms less the 1 ms of work.
    assert len(wall_clock.sleeps) == 14
    assert wall_clock.sleeps == pytest.approx([0.009] * 14)
