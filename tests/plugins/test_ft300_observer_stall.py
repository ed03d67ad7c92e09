"""Issue 26 §6: the stall check watches the force the classifier consumes.

In the device-chain example the jamming classifier reads the force observer's output, which
needs an IMU sample at most ``max_age_s`` old. When the BNO055 drops out, the observer's
output is invalid while the FT 300's own stream stays valid; the classifier holds its last
valid force and the arm used to rake on blind into jammed sand (59.6-62.7 N with
``faults: standard``). Here the BNO055 is unplugged for 0.7 s during the first movement and
the FT 300 has no fault: the arm must be halted within ``run.force_stall_s`` plus one control
period of the observer's last valid sample, with the observer's stream named in the halt.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from hapticframe.cli._cli import main

pytest.importorskip("serial")
pytest.importorskip("hapticframe_robotiq")
pytest.importorskip("hapticframe_bno055")

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "search-ellipse-ft300.yaml"
PULLED_AT_S = 1.0
STALL_S = 0.25
PERIOD_S = 0.01  # the sandbox's control period


def test_an_imu_dropout_halts_the_rig_on_the_observer_stream(tmp_path):
    data = yaml.safe_load(EXAMPLE.read_text())
    sensors = {s["id"]: s for s in data["sensors"]}
    sensors["wrist"]["config"]["faults"] = "none"
    sensors["imu"]["config"]["faults"] = [{"kind": "disconnect", "at_s": PULLED_AT_S,
                                           "duration_s": 0.7}]
    max_age_s = data["feature_extractors"][0]["config"]["max_age_s"]
    data["run"].update({"force_stall_s": STALL_S, "stall_resumes": 0, "max_movements": 1,
                        "record": False})
    path = tmp_path / "imu-dropout.yaml"
    path.write_text(yaml.safe_dump(data))
    code = main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"])
    run = json.loads((tmp_path / "out" / "run.json").read_text())
    # Its only movement halted by the stall check: no result (exit 1), its files kept.
    assert code == 1 and run["status"] == "failed"
    assert "halted by a safety check" in run["error"]
    halts = run["details"].get("safety_halts", [])
    assert halts, "the arm raked on while the classifier's force was invalid"
    first = halts[0]
    assert first["reason"] == "force_stream_stalled"
    assert first["stream"] == "observer/force_n"
    last_valid_s = first["robot_time_s"] - first["silent_s"]
    # The observer's last valid sample came with the IMU's last sample before the pull.
    assert PULLED_AT_S - 2 * PERIOD_S <= last_valid_s <= PULLED_AT_S + max_age_s + PERIOD_S
    assert first["silent_s"] <= STALL_S + PERIOD_S + 1e-9
    # ... while the FT 300's own stream went on at its 100 Hz: its check alone saw nothing.
    with np.load(tmp_path / "out" / "trace.npz") as trace:
        wrist_t = trace["sensor/wrist/timestamps_s"]
    during = wrist_t[(wrist_t > last_valid_s) & (wrist_t <= first["robot_time_s"])]
    assert during.size >= round(first["silent_s"] / PERIOD_S) - 2
    assert np.all(np.diff(during) < 2 * PERIOD_S)
