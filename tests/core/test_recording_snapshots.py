"""Map snapshots, the scene and fingertip poses in ``run.mcap``, on Foxglove's schemas."""

from __future__ import annotations

import json
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any
from unittest import mock

import jsonschema
import numpy as np
import pytest
import yaml
from mcap.reader import make_reader

from hapticframe._scene import Scene
from hapticframe.cli._cli import main
from hapticframe.kinds import MapEstimate, Region, RobotState
from hapticframe.record import _foxglove, _recording
from hapticframe.record._recording import RECORDING, SCHEMAS, RunRecording, read_recording
from hapticframe.run._channels import (
    LOOP,
    MAP_GRID,
    METRICS,
    MOVEMENT,
    ROBOT_STATE,
    SCENE,
    SENSOR,
    MapSnapshot,
    check_topic,
)
from hapticframe.run._dataflow import Dataflow

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def short_search(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The README's main job cut to two movements, figures off, run once per session."""
    folder = tmp_path_factory.mktemp("short-search")
    model = yaml.safe_load((ROOT / "examples" / "search-ellipse.yaml").read_text())
    # Every due snapshot (not thinned by their CPU share, which varies with the machine):
    # the recovery tests need the same file layout on every run.
    model["run"].update({"figures": False, "max_movements": 2, "snapshot_cpu_share": 1.0})
    experiment = folder / "search.yaml"
    experiment.write_text(yaml.safe_dump(model))
    out = folder / "out"
    # Blocks every 0.1 s of model time, as a real-time run writes them (not paced by the
    # wall clock), in small chunks: the recovery tests cut and damage a recording of
    # several chunks.
    with mock.patch.object(_recording, "EMIT_WALL_S", 0.0), \
            mock.patch.object(_recording, "CHUNK_BYTES", 64 * 1024):
        assert main(["run", str(experiment), "--out", str(out), "--quiet"]) == 0
    return out


def _registered_schemas(path: Path) -> dict[str, dict[str, Any]]:
    """The JSON schemas the file registers, by name, as written into it."""
    with open(path, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    return {s.name: json.loads(s.data) for s in summary.schemas.values()}


def _validate(schema: dict[str, Any], message: dict[str, Any]) -> None:
    jsonschema.Draft202012Validator.check_schema(schema)
    jsonschema.Draft202012Validator(schema).validate(message)


def test_a_run_records_map_snapshots_on_foxglove_schemas(short_search):
    recorded = read_recording(short_search / RECORDING)
    registered = _registered_schemas(short_search / RECORDING)
    for name in (_foxglove.GRID, _foxglove.SCENE_UPDATE, _foxglove.POSE_IN_FRAME):
        assert registered[name] == _foxglove.SCHEMAS[name] == SCHEMAS[name]
    movements = [t for t, _ in recorded["/movement"]]
    for map_id in ("grid", "bhm"):
        grids = recorded[f"/map/{map_id}/grid"]
        # The maps are updated once per movement (run.map_update_every: 0), seconds apart.
        assert [t for t, _ in grids] == movements
        for _, message in grids:
            _validate(registered[_foxglove.GRID], message)
            assert message["frame_id"] == "map"
            decoded = _foxglove.decode_grid(message)
            # 0.01 m cells over the 0.75 x 0.5 m region, its lower-left corner at the origin.
            assert decoded["mean"].shape == decoded["std"].shape == (50, 75)
            assert message["cell_size"] == pytest.approx({"x": 0.01, "y": 0.01})
            assert message["pose"]["position"] == {"x": 0.0, "y": 0.0, "z": 0.0}
            assert 0 <= decoded["mean"].min() and decoded["mean"].max() <= 1
            assert decoded["std"].min() >= 0
        # The object was met: the last snapshot's mean peaks near the buried ellipse.
        last = _foxglove.decode_grid(grids[-1][1])
        row, col = np.unravel_index(np.argmax(last["mean"]), last["mean"].shape)
        assert np.hypot(last["xs"][col] - 0.42, last["ys"][row] - 0.21) < 0.06
    scene = recorded["/scene"]
    first_t, first = scene[0]
    assert first_t == 0
    kinds = {e["id"]: {p["key"]: p["value"] for p in e["metadata"]}["kind"]
             for e in first["entities"]}
    assert kinds == {"region": "region", "object/0": "true object"}
    for _, update in scene:
        _validate(registered[_foxglove.SCENE_UPDATE], update)
    estimates = {e["id"] for _, u in scene[1:] for e in u["entities"]}
    assert estimates == {"estimate/grid", "estimate/bhm"}
    poses = recorded["/robot/arm/pose"]
    for _, pose in poses:
        _validate(registered[_foxglove.POSE_IN_FRAME], pose)
    states = np.concatenate([d["timestamps_s"] for _, d in recorded["/robot/arm/state"]])
    # 5 per second of model time, the first at the first state.
    assert poses[0][0] == round(states[0] * 1e9)
    assert len(poses) == pytest.approx((states[-1] - states[0]) * 5, abs=1.01)
    steps = np.diff([t for t, _ in poses]) / 1e9
    assert steps.min() >= 0.2 - 1e-9


class _Ramp:
    """A map whose mean rises along x and whose std falls along y (duck-typed)."""

    region = Region(0.0, 0.5, 0.0, 0.25)

    def query(self, points_m: Any) -> MapEstimate:
        p = np.asarray(points_m, dtype=np.float64)
        return MapEstimate(p[:, 0] / 0.5, 0.5 - p[:, 1])


def test_a_snapshot_is_the_map_on_its_grid(tmp_path):
    recording = RunRecording(tmp_path / "a.mcap")
    recording.configure_snapshots(5.0)
    recording.map_snapshot(MapSnapshot.of("ramp", _Ramp(), 1.5, 0.05, 0.6))  # type: ignore[arg-type]
    recording.close()
    recorded = read_recording(tmp_path / "a.mcap")
    [(t, message)] = recorded["/map/ramp/grid"]
    assert t == 1_500_000_000 and message["timestamp"] == {"sec": 1, "nsec": 500_000_000}
    grid = _foxglove.decode_grid(message)
    assert grid["mean"].shape == (5, 10)  # rows along y, columns along x
    np.testing.assert_allclose(grid["xs"], 0.05 * (np.arange(10) + 0.5))
    np.testing.assert_allclose(grid["ys"], 0.05 * (np.arange(5) + 0.5))
    expected = _Ramp().query(np.column_stack([np.tile(grid["xs"], 5),
                                              np.repeat(grid["ys"], 10)]))
    np.testing.assert_array_equal(grid["mean"].ravel(), expected.mean.astype(np.float32))
    np.testing.assert_array_equal(grid["std"].ravel(), expected.std.astype(np.float32))
    # The estimated outline: the 0.6 curve of a ramp along x is the band x > 0.3.
    [(_, update)] = recorded["/scene"]
    [entity] = update["entities"]
    points = np.array([[p["x"], p["y"]] for p in entity["lines"][0]["points"]])
    assert entity["id"] == "estimate/ramp" and points[:, 0].min() == pytest.approx(0.3, abs=0.01)


def test_a_map_without_an_estimate_removes_its_outline(tmp_path):
    class Empty(_Ramp):
        def query(self, points_m: Any) -> MapEstimate:
            n = len(np.asarray(points_m))
            return MapEstimate(np.full(n, 0.5), np.full(n, 0.3))

    recording = RunRecording(tmp_path / "a.mcap")
    recording.map_snapshot(MapSnapshot.of("empty", Empty(), 0.0, 0.01, 0.6))  # type: ignore[arg-type]
    recording.close()
    [(_, update)] = read_recording(tmp_path / "a.mcap")["/scene"]
    assert update["entities"] == [] and update["deletions"][0]["id"] == "estimate/empty"


def test_snapshots_and_poses_follow_the_rate(tmp_path):
    recording = RunRecording(tmp_path / "a.mcap")
    recording.configure_snapshots(5.0)
    assert [recording.snapshot_due(t) for t in (0.0, 0.1, 0.19, 0.2, 0.3, 0.45)] == [
        True, False, False, True, False, True]
    for k in range(100):  # one second of robot steps at 100 Hz
        recording.robot_state("arm", RobotState(0.01 * (k + 1), np.array([0.01 * k, 0.0]),
                                                0.0, 0.02), 0)
    recording.configure_snapshots(0.0)
    assert not recording.snapshot_due(10.0)
    recording.robot_state("arm", RobotState(5.0, np.zeros(2), 0.0, 0.02), 0)
    recording.close()
    poses = read_recording(tmp_path / "a.mcap")["/robot/arm/pose"]
    assert [t / 1e9 for t, _ in poses] == pytest.approx([0.01, 0.21, 0.41, 0.61, 0.81])
    assert poses[1][1]["pose"]["position"] == pytest.approx({"x": 0.2, "y": 0.0, "z": -0.02})


def test_the_scene_is_written_once_at_time_zero(tmp_path):
    scene = Scene.model_validate({
        "region": {"x_min_m": 0.0, "x_max_m": 0.5, "y_min_m": 0.0, "y_max_m": 0.4},
        "objects": [{"shape": "circle", "center_m": [0.2, 0.2], "radius_m": 0.03}]})
    recording = RunRecording(tmp_path / "a.mcap")
    recording.robot_state("arm", RobotState(2.0, np.zeros(2), 0.0, 0.0), 0)
    recording.scene(scene)
    recording.scene(scene)
    recording.scene(None)
    recording.close()
    [(t, update)] = read_recording(tmp_path / "a.mcap")["/scene"]
    assert t == 0
    _validate(_foxglove.SCHEMAS[_foxglove.SCENE_UPDATE], update)
    circle = np.array([[p["x"], p["y"]] for p in update["entities"][1]["lines"][0]["points"]])
    np.testing.assert_allclose(np.hypot(*(circle - 0.2).T), 0.03)


def test_snapshot_settings_are_validated(tmp_path, capsys):
    model = yaml.safe_load((ROOT / "examples" / "search-ellipse.yaml").read_text())
    model["run"]["snapshot_rate_hz"] = -1
    experiment = tmp_path / "bad.yaml"
    experiment.write_text(yaml.safe_dump(model))
    assert main(["validate", str(experiment)]) == 2
    assert "snapshot_rate_hz" in capsys.readouterr().err
    model["run"].update({"snapshot_rate_hz": 0, "snapshot_spacing_m": 0.02})
    experiment.write_text(yaml.safe_dump(model))
    assert main(["validate", str(experiment)]) == 0


def test_the_dataflow_snapshots_at_the_rate_and_at_the_end(tmp_path):
    flow = object.__new__(Dataflow)  # only the maps and the recording are exercised
    flow.maps, flow.pending = ["ramp"], {"ramp": []}
    flow.components = SimpleNamespace(maps={"ramp": _Ramp()})
    flow._snapshot_rate_hz, flow._snapshot_spacing_m, flow._outline_level = 5.0, 0.05, 0.6
    flow._snapshot_max_cells = 16384
    flow.scene = None
    flow._now_s, flow.counts = 0.0, {}  # what the /loop events of flush_maps read
    recording = RunRecording(tmp_path / "a.mcap")
    flow.recording = recording
    flow.snapshot_maps(final=True)  # nothing changed yet: nothing written
    for t in (1.0, 1.1, 1.25, 1.3):
        recording.robot_state("arm", RobotState(t, np.zeros(2), 0.0, 0.0), 0)
        flow._maps_changed = True
        flow.flush_maps()
    flow.snapshot_maps(final=True)  # the maps changed at 1.3 s, after the last snapshot
    flow.snapshot_maps(final=True)
    flow.recording = None
    flow.flush_maps()
    recording.close()
    times = [t / 1e9 for t, _ in read_recording(tmp_path / "a.mcap")["/map/ramp/grid"]]
    assert times == pytest.approx([1.0, 1.25, 1.3])


def test_a_recorded_run_writes_only_table_channels(short_search):
    """Every topic a real run writes is a channel of the table, with the table's schema."""
    with open(short_search / RECORDING, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    topics = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    for topic, schema in topics.items():
        assert check_topic(topic, schema).schema == schema
    written = {check_topic(t, s) for t, s in topics.items()}
    assert written >= {MOVEMENT, LOOP, METRICS, SCENE, MAP_GRID, SENSOR, ROBOT_STATE}


def test_a_snapshot_grid_is_coarsened_to_at_most_its_cell_budget() -> None:
    """The snapshot's cells, and so its cost, are bounded at every region size."""
    import math

    from hapticframe.run._channels import snapshot_spacing

    assert snapshot_spacing(0.75, 0.5, 0.01, 16384) == 0.01  # the sandbox: unchanged
    for width, height in ((3.0, 2.0), (10.0, 10.0), (100.0, 0.5)):
        spacing = snapshot_spacing(width, height, 0.01, 16384)
        cells = math.ceil(width / spacing) * math.ceil(height / spacing)
        assert spacing > 0.01 and 0.9 * 16384 < cells <= 16384
    assert snapshot_spacing(1.0, 1.0, 0.01, 1) >= 1.0
    with pytest.raises(ValueError, match="max_cells"):
        snapshot_spacing(1.0, 1.0, 0.01, 0)


def test_due_snapshots_are_skipped_while_they_exceed_their_cpu_share(tmp_path) -> None:
    flow = object.__new__(Dataflow)
    flow.maps, flow.pending = ["ramp"], {"ramp": []}
    flow.components = SimpleNamespace(maps={"ramp": _Ramp()})
    flow._snapshot_rate_hz, flow._snapshot_spacing_m, flow._outline_level = 5.0, 0.05, 0.6
    flow._snapshot_max_cells = 16384
    flow.scene, flow._now_s, flow.counts = None, 0.0, {}
    recording = RunRecording(tmp_path / "a.mcap")
    flow.recording = recording
    flow._snapshot_cpu_share, flow._cpu_start_s = 0.01, time.process_time()
    flow._snapshot_cpu_s = 1e6  # as if the snapshots had taken far more than their share
    for t in (1.0, 2.0, 3.0):
        recording.robot_state("arm", RobotState(t, np.zeros(2), 0.0, 0.0), 0)
        flow._maps_changed = True
        flow.flush_maps()
    assert flow._maps_changed  # every due snapshot skipped: over budget
    flow.snapshot_maps(final=True)  # the last state is always written
    assert not flow._maps_changed
    recording.close()
    reader = make_reader(open(tmp_path / "a.mcap", "rb"))
    grids = [m for _, c, m in reader.iter_messages() if c.topic == "/map/ramp/grid"]
    assert len(grids) == 1


def test_poses_are_the_first_steps_of_each_period_however_the_steps_are_taken(tmp_path):
    """The poses are found by bisection in each taken batch of steps; the reference is the
    rule itself applied step by step: a pose at the first step at least one period (less
    the tolerance) after the last pose."""
    rng = np.random.default_rng(11)
    times = np.cumsum(rng.uniform(0.0005, 0.09, size=3000))
    rate_hz = 5.0
    recording = RunRecording(tmp_path / "a.mcap")
    recording.configure_snapshots(rate_hz)
    for t in times:
        recording.robot_state("arm", RobotState(float(t), np.array([t, -t]), 0.0, 0.02), 0)
        if rng.random() < 0.02:
            assert recording.now_s == t  # takes the held steps in: batches of every size
    recording.close()
    expected, due = [], -np.inf
    for t in times:
        if t >= due:
            expected.append(t)
            due = t + 1.0 / rate_hz - 1e-6  # the recording's tolerance, _EPS_S
    poses = read_recording(tmp_path / "a.mcap")["/robot/arm/pose"]
    got = sorted(p["timestamp"]["sec"] + p["timestamp"]["nsec"] * 1e-9 for _, p in poses)
    assert len(got) == len(expected) > 100
    assert got == pytest.approx(expected, abs=1e-9)
