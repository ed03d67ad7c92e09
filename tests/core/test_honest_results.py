"""Honest results (issue 26, section 4): a run whose sensors delivered (almost) nothing, or
whose every movement a safety check halted, is no result; a replay says on the console what
makes its figures differ from the recorded run's."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe.cli._cli import main

ROOT = Path(__file__).resolve().parents[2]


def _ft300(folder: Path, name: str, movements: int, **wrist: Any) -> Path:
    model = yaml.safe_load((ROOT / "examples" / "search-ellipse-ft300.yaml").read_text())
    model["run"] = {**(model.get("run") or {}), "max_movements": movements, "figures": False}
    model["sensors"][0]["config"].update(wrist)
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(model))
    return path


def test_a_run_whose_every_ft300_frame_fails_its_crc_is_no_result(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    experiment = _ft300(tmp_path, "crc", 2, faults=[{"kind": "bad_crc", "rate_hz": 100}])
    out = tmp_path / "out"
    assert main(["run", str(experiment), "--out", str(out), "--quiet"]) == 1
    captured = capsys.readouterr()
    # The summary line still says where the files are and what they show, then why not.
    assert f"results in {out}" in captured.out and "object_found=no" in captured.out
    assert "sensor 'wrist' delivered 0 samples" in captured.err
    assert "Traceback" not in captured.err
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "failed" and "sensor 'wrist' delivered" in record["error"]
    assert record["details"]["no_result"]
    # Every file kept for inspection, the device counters among the metrics.
    assert {"metrics.json", "trace.npz", "run.mcap"} <= set(record["files"])
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["devices"]["wrist"]["crc_errors"] > 0


def test_replaying_an_ft300_recording_with_the_sandbox_experiment_warns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    recorded = tmp_path / "ft300"
    assert main(["run", str(_ft300(tmp_path, "ft", 1)), "--out", str(recorded),
                 "--quiet"]) == 0
    plain = yaml.safe_load((ROOT / "examples" / "search-ellipse.yaml").read_text())
    plain["run"].update({"figures": False})
    with_file = tmp_path / "plain.yaml"
    with_file.write_text(yaml.safe_dump(plain))
    capsys.readouterr()
    out = tmp_path / "replay"
    assert main(["replay", str(recorded), "--with", str(with_file), "--out", str(out),
                 "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "warning: sensor 'wrist' was a 'robotiq-ft300'" in err and "'sandbox-force'" in err
    details = json.loads((out / "run.json").read_text())["details"]
    assert "'robotiq-ft300'" in details["replay_warnings"][0]
