"""The live page's data path without a browser: the recording's listener tap, the
drop-oldest queue, the folded state and its frames, the recording's timeline, the server."""

from __future__ import annotations

import asyncio
import json
import logging
import socket
from pathlib import Path
from typing import Any, cast

import numpy as np
import pytest
import yaml

from hapticframe._scene import Scene
from hapticframe.kinds import ClassProbabilities, MapEstimate, Region, SampleBatch
from hapticframe.live import (
    LiveFeed,
    LiveServer,
    LiveState,
    MessageQueue,
    RecordingTimeline,
    TimelineFeed,
    decode_grid,
)
from hapticframe.live._state import WINDOW_S
from hapticframe.record._foxglove import grid_message
from hapticframe.record._recording import RunRecording, listening, read_recording
from hapticframe.run._channels import MapSnapshot

ROOT = Path(__file__).resolve().parents[2]


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _blob(rows: int = 20, columns: int = 30, cell: float = 0.01) -> tuple[np.ndarray, ...]:
    y, x = np.mgrid[0:rows, 0:columns]
    mean = np.exp(-(((x - 15) / 5.0) ** 2 + ((y - 10) / 4.0) ** 2))
    std = 0.5 * (1 - mean)
    return mean, std


def _write_some(recording: RunRecording) -> None:
    t = np.arange(1, 31) * 0.01
    recording.samples("sensor", "wrist", SampleBatch(t, {"force_n": np.c_[3 * t, 4 * t]}),
                      {"force_n": "N"})
    recording.probabilities("jam", ClassProbabilities(
        t, np.c_[1 - t, t], ("free", "jamming")))
    recording.event("/safety_halt", "hapticframe.SafetyHalt", {"reason": "force limit"})


# --- contract A: the listener tap ------------------------------------------------------------


def test_listeners_see_every_message_as_written(tmp_path: Path) -> None:
    seen: list[tuple[str, float, Any]] = []
    recording = RunRecording(tmp_path / "run.mcap", clock=FakeClock())
    recording.add_listener(lambda topic, t, data: seen.append((topic, t, json.dumps(data))))
    _write_some(recording)
    recording.close()
    written = read_recording(tmp_path / "run.mcap")
    assert sorted({topic for topic, _, _ in seen}) == sorted(written)
    for topic, messages in written.items():
        mine = [(t, json.loads(data)) for top, t, data in seen if top == topic]
        assert [data for _, data in mine] == [data for _, data in messages]
        assert [round(t * 1e9) for t, _ in mine] == [ns for ns, _ in messages]


def test_a_failing_listener_is_dropped_and_the_run_goes_on(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    calls = []

    def broken(topic: str, t: float, data: Any) -> None:
        calls.append(topic)
        raise RuntimeError("boom")

    recording = RunRecording(tmp_path / "run.mcap", clock=FakeClock())
    recording.add_listener(broken)
    with caplog.at_level(logging.WARNING, logger="hapticframe.recording"):
        _write_some(recording)
    recording.close()
    assert len(calls) == 1
    assert sum("dropped" in r.getMessage() for r in caplog.records) == 1
    assert sum(len(v) for v in read_recording(tmp_path / "run.mcap").values()) == 3


def test_listening_reaches_recordings_opened_inside_the_block_only(tmp_path: Path) -> None:
    queue = MessageQueue()
    with listening(queue.put):
        inside = RunRecording(tmp_path / "a.mcap", clock=FakeClock())
    outside = RunRecording(tmp_path / "b.mcap", clock=FakeClock())
    _write_some(inside)
    _write_some(outside)
    inside.close()
    outside.close()
    assert queue.put_count == 3


# --- the queue and the state -------------------------------------------------------------------


def test_the_queue_drops_the_oldest_when_full() -> None:
    queue = MessageQueue(maxlen=3)
    for i in range(5):
        queue.put("/x", float(i), {})
    assert queue.dropped == 2
    assert [t for _, t, _ in queue.drain()] == [2.0, 3.0, 4.0]
    assert queue.drain() == [] and queue.dropped == 2


def test_a_grid_snapshot_decodes_with_rows_from_the_bottom() -> None:
    mean, std = _blob()
    mean[0, 0] = 0.25  # the lower-left cell
    grid = decode_grid(grid_message(0.0, (0.1, 0.2), (0.01, 0.01), mean, std))
    np.testing.assert_allclose(grid["mean"], mean.astype(np.float32))
    np.testing.assert_allclose(grid["std"], std.astype(np.float32))
    assert grid["origin_m"] == [0.1, 0.2] and grid["cell_m"] == [0.01, 0.01]
    broken = grid_message(0.0, (0, 0), (0.01, 0.01), mean, std)
    broken["row_stride"] = 7
    with pytest.raises(ValueError, match="do not add up"):
        decode_grid(broken)


def test_the_state_folds_a_run_into_one_frame() -> None:
    state = LiveState(clock=FakeClock())
    mean, std = _blob()
    state.fold("/map/bhm/grid", 0.2, grid_message(0.2, (0.0, 0.0), (0.01, 0.01), mean, std))
    state.fold("/robot/arm/state", 0.3, {
        "timestamps_s": [0.1, 0.2, 0.3], "positions_m": [[0, 0.1], [0.01, 0.1], [0.02, 0.1]],
        "headings_rad": [0, 0, 0], "depths_m": [0.04] * 3, "movement_index": [0, 0, 1]})
    t = np.arange(1, 2001) * 0.01  # 20 s: the plot keeps the last WINDOW_S
    state.fold("/sensor/wrist", 20.0, {"timestamps_s": t.tolist(),
               "channels": {"force_n": np.c_[3 * t, 4 * t].tolist(), "pdc": t.tolist()},
               "units": {"force_n": "N", "pdc": "1"}})
    state.fold("/classifier/jam", 20.0, {"timestamps_s": [19.9, 20.0], "classes": ["free", "jam"],
               "probabilities": [[0.9, 0.1], [0.2, 0.8]]})
    state.fold("/movement", 20.0, {"index": 0, "phase": "phase1", "halted": True,
               "final_position_m": [0.02, 0.1], "halt_reason": "interaction"})
    state.fold("/sensor/broken", 20.0, {"channels": {}})  # no timestamps
    frame = state.frame()
    json.dumps(frame, allow_nan=False)  # plain JSON for the page

    bhm = frame["maps"]["bhm"]
    assert (bhm["rows"], bhm["columns"], bhm["version"]) == (20, 30, 1)
    assert len(bhm["outline"]) == 1, "the 0.6 level around the blob is drawn"
    assert bhm["outline_source"] == "grid"  # no /scene estimate: the page finds it
    ring = np.asarray(bhm["outline"][0])
    # The outline runs where the mean crosses 0.6: about (5, 4) cells * sqrt(-ln 0.6) away.
    radius = np.hypot((ring[:, 0] - 0.155) / 0.05, (ring[:, 1] - 0.105) / 0.04)
    np.testing.assert_allclose(radius, np.sqrt(-np.log(0.6)), atol=0.15)
    path = frame["paths"]["arm"]
    assert path["points"] == [[[0, 0.1], [0.01, 0.1]]] and path["current"] == [[0.02, 0.1]]
    assert path["movement"] == 1 and path["position_m"] == [0.02, 0.1]
    assert state.frame() is frame  # nothing changed: the same frame
    state.fold("/robot/arm/state", 0.5, {
        "timestamps_s": [0.4, 0.5], "positions_m": [[0.5, 0.3], [0.51, 0.3]],
        "headings_rad": [0, 0], "depths_m": [0.04] * 2, "movement_index": [2, 2]})
    moved = state.frame()["paths"]["arm"]
    assert moved["points"] == [[[0, 0.1], [0.01, 0.1]], [[0.02, 0.1]]]  # one per movement
    assert moved["current"] == [[0.5, 0.3], [0.51, 0.3]]
    force = frame["forces"]["wrist.force_n"]
    assert list(frame["forces"]) == ["wrist.force_n"]  # only channels in newtons
    assert force["t_s"][0] >= 20.0 - WINDOW_S and force["t_s"][-1] == 20.0
    np.testing.assert_allclose(force["values"], 5 * np.asarray(force["t_s"]), rtol=1e-4)
    assert frame["interaction"] == {"jam": {"class": "jam", "probability": 0.8}}
    assert frame["probabilities"]["jam"]["classes"] == ["free", "jam"]
    assert frame["phase"] == "phase1"
    assert frame["metrics"]["movements"] == 1 and frame["metrics"]["halted_movements"] == 1
    assert frame["metrics"]["max_force_n"] == 100.0
    assert "/sensor/broken" in frame["errors"]

    state.fold("/map/bhm/grid", 0.4, grid_message(0.4, (0.0, 0.0), (0.01, 0.01), 1 - mean, std))
    state.end("ok", {"object_found": True, "centroid_error_m": 0.01, "devices": {}})
    later = state.frame()
    assert later["maps"]["bhm"]["version"] == 2 and later["status"] == "ok"
    assert later["metrics"]["object_found"] is True and "devices" not in later["metrics"]
    assert later["counts"]["map_versions"] == 2


class _Ramp:
    """A map whose mean rises along x: its 0.6 curve is the band x > 0.3 (duck-typed)."""

    region = Region(0.0, 0.5, 0.0, 0.25)

    def query(self, points_m: Any) -> MapEstimate:
        p = np.asarray(points_m, dtype=np.float64)
        return MapEstimate(p[:, 0] / 0.5, 0.5 - p[:, 1])


def test_the_page_draws_the_scene_and_the_recorded_estimate(tmp_path: Path) -> None:
    scene = Scene.model_validate({
        "region": {"x_min_m": 0.0, "x_max_m": 0.5, "y_min_m": 0.0, "y_max_m": 0.25},
        "objects": [{"shape": "circle", "center_m": [0.4, 0.12], "radius_m": 0.05}]})
    state = LiveState(clock=FakeClock())
    recording = RunRecording(tmp_path / "run.mcap", clock=FakeClock())
    recording.add_listener(state.fold)
    recording.configure_snapshots(5.0)
    recording.scene(scene)
    recording.map_snapshot(MapSnapshot.of("ramp", cast(Any, _Ramp()), 0.2, 0.05, 0.6))
    frame = state.frame()
    assert frame["scene"]["region"] == [[0.0, 0.0], [0.5, 0.0], [0.5, 0.25], [0.0, 0.25]]
    [circle] = frame["scene"]["objects"]
    assert circle["shape"] == "circle"
    ring = np.asarray(circle["points"])
    np.testing.assert_allclose(np.hypot(ring[:, 0] - 0.4, ring[:, 1] - 0.12), 0.05, atol=1e-4)
    ramp = frame["maps"]["ramp"]
    # The outline is the recording's own (the evaluation's blob), not one the page makes.
    assert ramp["outline_source"] == "recording" and ramp["outline_level"] == 0.6
    [outline] = ramp["outline"]
    assert min(x for x, _ in outline) == pytest.approx(0.3, abs=0.01)

    class Empty(_Ramp):
        def query(self, points_m: Any) -> MapEstimate:
            n = len(np.asarray(points_m))
            return MapEstimate(np.full(n, 0.5), np.full(n, 0.3))

    # nothing above 0.6: the outline goes
    recording.map_snapshot(MapSnapshot.of("ramp", cast(Any, Empty()), 0.4, 0.05, 0.6))
    recording.close()
    later = state.frame()["maps"]["ramp"]
    assert later["version"] == 2 and later["outline"] == [] and later["outline_source"] == "none"
    assert state.frame()["scene"]["objects"] == frame["scene"]["objects"]
    # view DIR folds the same messages from the file into the same picture.
    timeline = RecordingTimeline.from_recording(read_recording(tmp_path / "run.mcap"))
    assert timeline.frame_at(0.3)["maps"]["ramp"]["outline"] == ramp["outline"]
    assert timeline.frame_at(1.0)["maps"]["ramp"]["outline"] == []


def test_the_timeline_gives_the_picture_at_any_time(tmp_path: Path) -> None:
    recording = RunRecording(tmp_path / "run.mcap", clock=FakeClock())
    _write_some(recording)
    for i in range(1, 4):
        recording.event("/movement", "hapticframe.MovementResult", {
            "index": i - 1, "start_m": [0, 0], "end_m": [1, 0], "halted": False,
            "halt_reason": "", "phase": f"phase{i}"}, t_s=float(i))
    recording.close()
    timeline = RecordingTimeline.from_recording(read_recording(tmp_path / "run.mcap"))
    assert timeline.start_s == pytest.approx(0.3) and timeline.end_s == 3.0
    assert timeline.frame_at(2.5)["phase"] == "phase2"
    assert timeline.frame_at(3.0)["metrics"]["movements"] == 3
    back = timeline.frame_at(1.0)  # back in time: folded again from the start
    assert back["metrics"]["movements"] == 1 and back["timeline"]["t_s"] == 1.0
    assert back["status"] == "recording"
    assert timeline.frame_at(99.0)["status"] == "recording (end)"


# --- the server ----------------------------------------------------------------------------------


async def _frames(url: str, want: int, send: list[dict[str, Any]] | None = None,
                  push: Any = None) -> list[dict[str, Any]]:
    import aiohttp

    frames: list[dict[str, Any]] = []
    async with aiohttp.ClientSession() as session:
        async with session.ws_connect(url.replace("/?", "/ws?")) as ws:
            for message in send or []:
                await ws.send_str(json.dumps(message))
            while len(frames) < want:
                frames.append(json.loads((await ws.receive(timeout=5)).data))
                if push is not None:
                    push(len(frames))
        async with session.get(url) as page:
            assert page.status == 200 and "live.js" in await page.text()
        async with session.get(url.split("?")[0] + "static/live.js") as script:
            assert script.status == 200
            text = await script.text()
            assert "http" not in text.replace("location.host", "")  # nothing from elsewhere
    return frames


def test_the_server_sends_a_frame_when_the_run_writes() -> None:
    pytest.importorskip("aiohttp")
    feed = LiveFeed()
    with LiveServer(feed, port=0, rate_hz=50) as server:
        def push(n: int) -> None:  # the run's thread would do this
            feed.listener("/robot/arm/state", n * 0.1, {
                "timestamps_s": [n * 0.1], "positions_m": [[n * 0.01, 0.0]],
                "headings_rad": [0], "depths_m": [0.04], "movement_index": [0]})
            if n == 3:
                feed.end("ok", {"movements": 0})

        frames = asyncio.run(_frames(server.url, 5, push=push))
    assert [f["mode"] for f in frames] == ["live"] * 5
    assert [f["counts"]["path_points"] for f in frames[:4]] == [0, 1, 2, 3]
    assert frames[-1]["status"] == "ok"


def test_the_view_answers_the_slider(tmp_path: Path) -> None:
    pytest.importorskip("aiohttp")
    recording = RunRecording(tmp_path / "run.mcap", clock=FakeClock())
    _write_some(recording)
    recording.event("/movement", "hapticframe.MovementResult", {
        "index": 0, "start_m": [0, 0], "end_m": [1, 0], "halted": False, "halt_reason": "",
        "phase": "p"}, t_s=2.0)
    recording.close()
    feed = TimelineFeed(RecordingTimeline.from_recording(read_recording(tmp_path / "run.mcap")))
    with LiveServer(feed, port=0) as server:
        frames = asyncio.run(_frames(server.url, 2, send=[{"t_s": 1.0}]))
    assert frames[0]["timeline"]["t_s"] == 2.0  # the end first
    assert frames[1]["timeline"]["t_s"] == 1.0 and frames[1]["metrics"]["movements"] == 0


def test_a_busy_port_is_a_usage_error() -> None:
    pytest.importorskip("aiohttp")
    from hapticframe._errors import UsageError

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(UsageError, match="choose another --port"):
            LiveServer(LiveFeed(), port=port).start()


def test_view_and_live_refuse_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from hapticframe.cli._cli import main

    assert main(["view", str(tmp_path / "nothing")]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["view", str(tmp_path)]) == 2
    assert "holds no recording" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exited:
        main(["run", "x.yaml", "--out", str(tmp_path), "--live", "--port", "70000"])
    assert exited.value.code == 2 and "--port" in capsys.readouterr().err
    model = yaml.safe_load((ROOT / "examples" / "search-ellipse.yaml").read_text())
    model["run"]["record"] = False
    experiment = tmp_path / "unrecorded.yaml"
    experiment.write_text(yaml.safe_dump(model))
    assert main(["run", str(experiment), "--out", str(tmp_path / "out"), "--live"]) == 2
    assert "run.record: false" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
