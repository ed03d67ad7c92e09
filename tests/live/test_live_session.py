"""``run --live`` however the run ends: the page keeps the last picture with the status (and
why) until the person is done with it, then the run's error goes on to the command."""

from __future__ import annotations

import json
import re
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe._config import load_file, validate_data
from hapticframe._errors import RunError, RunInterrupted
from hapticframe.kinds import SampleBatch
from hapticframe.live import evaluated_map, run_live
from hapticframe.record._recording import RunRecording

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def experiment() -> Any:
    return validate_data(load_file(str(ROOT / "examples" / "search-ellipse.yaml")))


def _get(url: str) -> Any:
    with urllib.request.urlopen(url, timeout=10) as response:  # the local page only
        return json.loads(response.read())


class _Page:
    """``say`` and ``wait`` of :func:`run_live`: notes what is printed, and while "waiting
    for Ctrl-C" reads the page's frame, as a person's browser would."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.frames: list[dict[str, Any]] = []

    @property
    def url(self) -> str:
        found = re.search(r"(http://127\.0\.0\.1:\d+/\?token=[\w-]+)", self.lines[0])
        assert found is not None, self.lines
        return found.group(1)

    def wait(self) -> None:
        self.frames.append(_get(self.url.replace("/?", "/frame?")))


def _failing_run(tmp_path: Path, error: BaseException) -> Any:
    def run() -> dict[str, Any]:  # writes a little, as a run would, then fails
        recording = RunRecording(tmp_path / "run.mcap")
        recording.samples("sensor", "wrist", SampleBatch(
            np.array([0.1, 0.2]), {"force_n": np.array([[1.0, 0.0], [2.0, 0.0]])}),
            {"force_n": "N"})
        recording.close()
        raise error
    return run


@pytest.mark.parametrize(("error", "status", "reason"), [
    (RunError("the robot 'arm' stopped answering"), "failed", "stopped answering"),
    (RunInterrupted("SIGINT"), "interrupted", "Ctrl-C (SIGINT)"),
    (ValueError("a bug"), "failed", "ValueError: a bug"),
])
def test_the_page_stays_up_after_a_run_that_did_not_finish(
        tmp_path: Path, experiment: Any, error: BaseException, status: str,
        reason: str) -> None:
    pytest.importorskip("aiohttp")
    page = _Page()
    with pytest.raises(type(error)):
        run_live(experiment, _failing_run(tmp_path, error), port=0, say=page.lines.append,
                 wait=page.wait)
    [frame] = page.frames
    assert frame["status"] == status and reason in frame["reason"]
    assert frame["forces"]["wrist.force_n"]["values"] == [1.0, 2.0]  # the last picture
    assert f"the run {status}" in page.lines[-1] and "until Ctrl-C" in page.lines[-1]
    with pytest.raises(OSError):  # once the person is done, the page goes
        _get(page.url.replace("/?", "/frame?"))


def test_sigterm_takes_the_page_down_at_once(tmp_path: Path, experiment: Any) -> None:
    pytest.importorskip("aiohttp")
    page = _Page()
    with pytest.raises(RunInterrupted):
        run_live(experiment, _failing_run(tmp_path, RunInterrupted("SIGTERM")), port=0,
                 say=page.lines.append, wait=page.wait)
    assert page.frames == [] and len(page.lines) == 1


def test_a_finished_run_shows_its_metrics_and_the_evaluated_map_first(
        tmp_path: Path, experiment: Any) -> None:
    pytest.importorskip("aiohttp")
    page = _Page()
    summaries: list[Any] = []
    metrics = run_live(experiment, lambda: {"object_found": True}, port=0,
                       say=page.lines.append, wait=page.wait, finished=summaries.append)
    assert metrics == {"object_found": True} and summaries == [metrics]
    [frame] = page.frames
    assert frame["status"] == "ok" and frame["reason"] == ""
    assert frame["metrics"]["object_found"] is True
    # search-ellipse.yaml: the planner reads the BHM, which the run scores.
    assert evaluated_map(experiment) == "bhm" == frame["preferred_map"]
