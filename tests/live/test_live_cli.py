"""``hapticframe run --live``: the page follows the run and stays up after it ends."""

from __future__ import annotations

import json
import re
import urllib.request
from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe.cli import _run as run_command
from hapticframe.cli._cli import main
from hapticframe.live import RecordingTimeline
from hapticframe.record._recording import read_recording

ROOT = Path(__file__).resolve().parents[2]


def _get(url: str) -> Any:
    with urllib.request.urlopen(url, timeout=10) as response:  # the local page only
        return json.loads(response.read())


def test_run_live_serves_the_finished_run_until_ctrl_c(
        tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("aiohttp")
    model = yaml.safe_load((ROOT / "examples" / "search-ellipse.yaml").read_text())
    model["run"].update(figures=False, max_movements=1)
    experiment = tmp_path / "short.yaml"
    experiment.write_text(yaml.safe_dump(model))
    seen: dict[str, Any] = {}

    def after_the_run() -> None:  # stands in for waiting for Ctrl-C
        printed = capsys.readouterr().out
        seen["printed"] = printed
        url = re.search(r"live view: (http://127\.0\.0\.1:\d+/)(\?token=[\w-]+)", printed)
        assert url is not None, printed
        seen["frame"] = _get(url.group(1) + "frame" + url.group(2))

    monkeypatch.setattr(run_command, "wait_for_interrupt", after_the_run)
    assert main(["run", str(experiment), "--out", str(tmp_path / "out"), "--quiet",
                 "--live", "--port", "0"]) == 0
    frame = seen["frame"]
    assert frame["mode"] == "live" and frame["status"] == "ok"
    assert frame["metrics"]["movements"] == 1 and "object_found" in frame["metrics"]
    assert frame["paths"]["arm"]["points"] or frame["paths"]["arm"]["current"]
    assert frame["forces"]["wrist.force_n"]["t_s"]
    assert frame["counts"]["dropped"] == 0
    assert "the page stays at" in seen["printed"]
    # The recording's own map snapshots, scene and estimate; the scored map first.
    assert set(frame["maps"]) == {"bhm", "grid"} and frame["preferred_map"] == "bhm"
    assert frame["maps"]["bhm"]["outline_source"] in ("recording", "none")
    assert frame["scene"]["region"] and len(frame["scene"]["objects"]) == 1

    # view DIR: the same picture from the file, at the end of its time slider.
    timeline = RecordingTimeline.from_recording(read_recording(tmp_path / "out" / "run.mcap"))
    viewed = timeline.frame_at(timeline.end_s)
    assert viewed["maps"]["bhm"]["version"] == frame["maps"]["bhm"]["version"] >= 1
    assert viewed["maps"]["bhm"]["mean"] == frame["maps"]["bhm"]["mean"]
    assert viewed["scene"] == frame["scene"] and viewed["preferred_map"] == "bhm"
