"""``hapticframe replay``: a recorded run's perception and mapping, re-run exactly."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np
import pytest
import yaml

from hapticframe.cli._cli import main
from hapticframe.kinds import SampleBatch
from hapticframe.record import _recording
from hapticframe.record._recording import RECORDING, RunRecording, read_recording

ROOT = Path(__file__).resolve().parents[2]


def _experiment(folder: Path, name: str, **run: Any) -> Path:
    """The README's main job, three movements, figures off, with ``run`` settings."""
    model = yaml.safe_load((ROOT / "examples" / "search-ellipse.yaml").read_text())
    model["run"].update({"figures": False, "max_movements": 3, **run})
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(model))
    return path


def _metrics(directory: Path) -> dict[str, Any]:
    metrics = json.loads((directory / "metrics.json").read_text())
    metrics.pop("wall_time_s")
    return metrics


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One short search evaluated on the BHM (the planner's map), one on the grid."""
    folder = tmp_path_factory.mktemp("replay")
    out = {}
    for name, evaluated in (("bhm", "bhm"), ("grid", "grid")):
        experiment = _experiment(folder, name, evaluation_map=evaluated)
        # Blocks every 0.1 s of model time, as a real-time run writes them, in small
        # chunks: the cut recording's test needs its movements spread over the file.
        with mock.patch.object(_recording, "EMIT_WALL_S", 0.0), \
                mock.patch.object(_recording, "CHUNK_BYTES", 16 * 1024):
            assert main(["run", str(experiment), "--out", str(folder / f"run-{name}"),
                         "--quiet"]) == 0
        out[name] = folder / f"run-{name}"
        out[f"{name}.yaml"] = experiment
    return out


def _replay(source: Path, experiment: Path, out: Path) -> int:
    return main(["replay", str(source), "--with", str(experiment), "--out", str(out),
                 "--quiet"])


def test_replay_with_the_runs_own_experiment_reproduces_its_metrics(
    runs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capsys.readouterr()
    assert _replay(runs["bhm"], runs["bhm.yaml"], tmp_path / "again") == 0
    assert "warning" not in capsys.readouterr().err  # its own experiment: nothing to say
    assert "replay_warnings" not in json.loads(
        (tmp_path / "again" / "run.json").read_text())["details"]
    replayed = _metrics(tmp_path / "again")
    assert replayed == _metrics(runs["bhm"])  # every key but wall_time_s, exactly
    assert replayed["movements"] == 3
    # The trace too: every array the run's dataflow recorded.
    original = np.load(runs["bhm"] / "trace.npz")
    again = np.load(tmp_path / "again" / "trace.npz")
    assert sorted(original) == sorted(again)
    for key in original:
        assert np.array_equal(original[key], again[key]), key
    record = json.loads((tmp_path / "again" / "run.json").read_text())
    assert record["status"] == "ok"
    assert record["details"]["replayed_from"] == str(runs["bhm"] / RECORDING)
    # The robot's and the planner's metrics are the run's, not recomputed.
    assert {"ems_phase1", "ems_phase2", "max_force_n", "object_interactions",
            "halt_latency_samples_max"} <= set(record["details"]["carried_metrics"])
    assert RECORDING in record["files"]


def test_the_replays_own_recording_replays_to_the_same_metrics(
    runs: dict[str, Path], tmp_path: Path
) -> None:
    assert _replay(runs["bhm"], runs["bhm.yaml"], tmp_path / "once") == 0
    recorded = read_recording(tmp_path / "once" / RECORDING)
    assert recorded["/loop"] and recorded["/metrics"] and len(recorded["/movement"]) == 3
    assert _replay(tmp_path / "once", runs["bhm.yaml"], tmp_path / "twice") == 0
    assert _metrics(tmp_path / "twice") == _metrics(runs["bhm"])


def test_replay_with_another_evaluated_map_gives_that_maps_metrics(
    runs: dict[str, Path], tmp_path: Path
) -> None:
    # The planner reads the BHM in both runs, so they make the same movements; the replay
    # of the BHM run evaluated on the occupancy grid is the grid run.
    assert _replay(runs["bhm"], runs["grid.yaml"], tmp_path / "grid") == 0
    on_grid = _metrics(tmp_path / "grid")
    assert on_grid["evaluated_map"] == "grid"
    assert on_grid == _metrics(runs["grid"])
    assert on_grid["centroid_error_m"] != _metrics(runs["bhm"])["centroid_error_m"]


def test_replay_with_another_sensor_model_changes_the_maps(
    runs: dict[str, Path], tmp_path: Path
) -> None:
    model = yaml.safe_load(runs["bhm.yaml"].read_text())
    model["sensor_models"][0]["config"] = {"schedule": "empirical"}
    other = tmp_path / "other.yaml"
    other.write_text(yaml.safe_dump(model))
    assert _replay(runs["bhm"], other, tmp_path / "other") == 0
    metrics = _metrics(tmp_path / "other")
    original = _metrics(runs["bhm"])
    assert metrics["movements"] == original["movements"]
    assert metrics["ems_phase1"] == original["ems_phase1"]  # the recorded movements
    assert metrics["hausdorff_est_to_true_m"] != original["hausdorff_est_to_true_m"]


def test_a_recording_without_loop_events_is_refused(
    runs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    old = tmp_path / "old"
    old.mkdir()
    recording = RunRecording(old / RECORDING)
    recording.samples("sensor", "wrist", SampleBatch(np.arange(3.0), {"force_n": np.ones((3, 2))}),
                      {"force_n": "N"})
    recording.close()
    capsys.readouterr()
    assert _replay(old, runs["bhm.yaml"], tmp_path / "out") == 2
    err = capsys.readouterr().err
    assert "no /loop events" in err and "Traceback" not in err
    assert not (tmp_path / "out" / "run.json").exists()


def test_a_sensor_the_recording_lacks_is_named(
    runs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = yaml.safe_load(runs["bhm.yaml"].read_text())
    model["sensors"][0]["id"] = "fingertip"
    model["classifiers"][0]["inputs"] = ["fingertip"]
    other = tmp_path / "other.yaml"
    other.write_text(yaml.safe_dump(model))
    capsys.readouterr()
    assert _replay(runs["bhm"], other, tmp_path / "out") == 2
    err = capsys.readouterr().err
    assert "'fingertip'" in err and "'wrist'" in err and "Traceback" not in err


def test_a_cut_recording_replays_what_it_holds(
    runs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cut = tmp_path / "cut"
    cut.mkdir()
    data = (runs["bhm"] / RECORDING).read_bytes()
    # Cut where some but not all movements are held (where depends on the layout of the
    # messages, which the snapshot budget changes).
    for part in np.linspace(0.95, 0.05, 19):
        (cut / RECORDING).write_bytes(data[: int(len(data) * part)])
        holds = read_recording(cut / RECORDING)
        if 0 < len(holds.get("/movement", [])) < 3:
            break
    assert 0 < len(holds.get("/movement", [])) < 3
    capsys.readouterr()
    assert _replay(cut, runs["bhm.yaml"], tmp_path / "out") == 0
    # Said on the console, not only in run.json (issue 26, section 4).
    err = capsys.readouterr().err
    assert "warning:" in err and "is cut" in err and "shorter run" in err
    record = json.loads((tmp_path / "out" / "run.json").read_text())
    assert record["status"] == "ok" and record["details"]["replayed_cut"]
    assert "is cut" in record["details"]["replay_warnings"][0]
    metrics = _metrics(tmp_path / "out")
    assert metrics["movements"] == len(holds["/movement"])
    assert "ems_phase1" not in metrics  # a cut run recorded no metrics to carry
