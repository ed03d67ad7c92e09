"""The live page in a real browser: headless Chromium (Debian's ``chromium``, driven by
Playwright) opens the page before a short search starts and sees the map image, the path
and the force plot change while the run runs; a screenshot is kept as a test artifact
(``tmp_path``, and ``$HAPTICFRAME_TEST_ARTIFACTS`` when set)."""

from __future__ import annotations

import os
import shutil
import threading
from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe._config import load_file, validate_data
from hapticframe._live import LiveFeed, LiveServer
from hapticframe._recording import RunRecording, listening
from hapticframe._run import run_experiment
from tests.live._grid import SyntheticSnapshots

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]

pytestmark = pytest.mark.browser


def _sync_playwright() -> Any:
    if not Path(CHROMIUM).is_file():
        if os.environ.get("HAPTICFRAME_REQUIRE_BROWSER"):  # CI installed it: never skip there
            pytest.fail(f"HAPTICFRAME_REQUIRE_BROWSER is set but {CHROMIUM} is missing")
        pytest.skip("no chromium (Debian's `chromium`; .ci/run installs it)")
    module = pytest.importorskip("playwright.sync_api", reason="playwright is not installed")
    pytest.importorskip("aiohttp", reason="aiohttp (hapticframe[live]) is not installed")
    return module.sync_playwright


def test_the_page_follows_a_short_run(tmp_path: Path) -> None:
    sync_playwright = _sync_playwright()
    model = yaml.safe_load((ROOT / "examples" / "search-ellipse.yaml").read_text())
    model["run"].update(figures=False, max_movements=3)
    (tmp_path / "search.yaml").write_text(yaml.safe_dump(model))
    experiment = validate_data(load_file(str(tmp_path / "search.yaml")))

    feed = LiveFeed()
    listeners = [feed.listener]
    if not hasattr(RunRecording, "map_snapshot"):
        # Until the recording writes map snapshots itself (contract B), make them from the
        # run's observations, as the contract describes them.
        region = model["scene"]["region"]
        listeners.append(SyntheticSnapshots(feed.listener, (
            region["x_min_m"], region["y_min_m"], region["x_max_m"], region["y_max_m"])))
    samples: list[dict[str, Any]] = []
    done = threading.Event()
    failure: list[BaseException] = []

    def run() -> None:
        try:
            metrics = run_experiment(experiment, tmp_path / "out", echo=lambda _t: None,
                                     progress=False)
            feed.end("ok", dict(metrics))
        except BaseException as exc:  # reported by the test's thread
            failure.append(exc)
            feed.end("failed")
        finally:
            done.set()

    with LiveServer(feed, port=0) as server, sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": 1280, "height": 1100})
        page.goto(server.url)
        page.wait_for_function("window.hfLive && window.hfLive.frames > 0", timeout=20000)
        with _listening_all(listeners):
            worker = threading.Thread(target=run, name="the run")
            worker.start()
            while not done.is_set():
                samples.append(page.evaluate("({...window.hfLive})"))
                page.wait_for_timeout(50)
            worker.join()
        assert not failure, failure
        page.wait_for_function("window.hfLive.status === 'ok'", timeout=10000)
        final = page.evaluate("({...window.hfLive})")
        # The run has ended: the page still answers and shows its final metrics.
        assert "object_found" in page.inner_text("#metrics")
        shot = tmp_path / "live-page.png"
        page.screenshot(path=str(shot), full_page=True)
        browser.close()
    artifacts = os.environ.get("HAPTICFRAME_TEST_ARTIFACTS")
    if artifacts:
        Path(artifacts).mkdir(parents=True, exist_ok=True)
        shutil.copy(shot, Path(artifacts) / shot.name)
    assert shot.stat().st_size > 10_000

    during = [s for s in samples if s["status"] == "running"]
    assert len(during) >= 3, f"the page saw too little of the run: {samples}"
    for key in ("mapDraws", "pathPoints", "forceSamples"):
        values = [s[key] for s in during]
        assert len(set(values)) >= 2, f"{key} did not change during the run: {values}"
    assert final["mapDraws"] > during[0]["mapDraws"]
    assert final["frames"] >= len({s["frames"] for s in during})


class _listening_all:
    """``listening`` for several listeners at once."""

    def __init__(self, listeners: list[Any]) -> None:
        self._contexts = [listening(fn) for fn in listeners]

    def __enter__(self) -> None:
        for context in self._contexts:
            context.__enter__()

    def __exit__(self, *exc: Any) -> None:
        for context in reversed(self._contexts):
            context.__exit__(*exc)
