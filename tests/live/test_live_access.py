"""The live page belongs to the person who started it (issue 26 §5): Host, Origin and the
session's token on every request; no page, stuck or hostile, slows the run or moves another
page's time; frames are strict JSON; the std image is scaled as the report's figure."""

from __future__ import annotations

import asyncio
import json
import math
import socket
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe.live import LiveFeed, LiveServer, LiveState, RecordingTimeline, TimelineFeed
from hapticframe.live._access import AccessPolicy
from hapticframe.live._overhead import stuck_clients
from hapticframe.live._server import strict_json
from hapticframe.record._foxglove import grid_message
from hapticframe.record._recording import RunRecording, read_recording

pytest.importorskip("aiohttp")

#: Generous bounds for a loaded 2-core machine.
BOUND_S = 30.0


def _strict(text: str) -> Any:
    """JSON as a strict parser reads it (NaN and Infinity are not JSON)."""
    def refuse(name: str) -> Any:
        raise ValueError(f"not JSON: {name}")
    return json.loads(text, parse_constant=refuse)


def _request(url: str, headers: dict[str, str] | None = None) -> tuple[int, str]:
    request = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=10) as response:  # the local page only
            return response.status, response.read().decode()
    except urllib.error.HTTPError as error:
        return error.code, error.read().decode()


def _split(url: str) -> tuple[str, str]:
    """``(http://127.0.0.1:PORT/, token)`` of a page's address."""
    base, _, query = url.partition("?token=")
    return base, query


def _push_path(feed: LiveFeed, n: int) -> None:
    feed.listener("/robot/arm/state", n * 0.1, {
        "timestamps_s": [n * 0.1], "positions_m": [[n * 0.01, 0.0]], "headings_rad": [0],
        "depths_m": [0.04], "movement_index": [0]})


# --- who may read it -----------------------------------------------------------------------------


def test_a_request_needs_this_host_this_origin_and_the_token() -> None:
    feed = LiveFeed()
    _push_path(feed, 1)
    with LiveServer(feed, port=0) as server:
        base, token = _split(server.url)
        assert len(token) >= 40 and server.url.startswith("http://127.0.0.1:")
        port = server.port
        ok, body = _request(f"{base}frame?token={token}")
        assert ok == 200 and _strict(body)["counts"]["path_points"] == 1
        assert _request(f"{base}?token={token}")[0] == 200  # the page itself
        # The same token in a header, as Jupyter takes it.
        assert _request(f"{base}frame", {"Authorization": f"token {token}"})[0] == 200
        assert _request(f"http://localhost:{port}/frame?token={token}")[0] == 200

        refused = {
            "no token": _request(f"{base}frame"),
            "no token, the page": _request(base),
            "a wrong token": _request(f"{base}frame?token={token[:-1]}x"),
            "an empty token": _request(f"{base}frame?token="),
            "a foreign Host": _request(f"{base}frame?token={token}",
                                       {"Host": f"evil.example:{port}"}),
            "another port in Host": _request(f"{base}frame?token={token}",
                                             {"Host": f"127.0.0.1:{port + 1}"}),
            "a foreign Origin": _request(f"{base}frame?token={token}",
                                         {"Origin": "http://evil.example"}),
            "a null Origin": _request(f"{base}frame?token={token}", {"Origin": "null"}),
        }
        for case, (status, body) in refused.items():
            assert status == 403, case
            assert "path_points" not in body, case
        assert "token" in refused["no token"][1] and "Host" in refused["a foreign Host"][1]
        assert "evil.example" in refused["a foreign Origin"][1]
        assert server.refused == len(refused)
        # The page's own files hold no data: no token needed, but Host still checked.
        assert _request(f"{base}static/live.js")[0] == 200
        assert _request(f"{base}static/live.js", {"Host": "evil.example"})[0] == 403
        # The same origin's page may ask.
        assert _request(f"{base}frame?token={token}",
                        {"Origin": f"http://127.0.0.1:{port}"})[0] == 200


async def _ws_status(url: str, headers: dict[str, str] | None = None) -> int | dict[str, Any]:
    """The first frame a websocket at ``url`` gets, or the HTTP status it was refused with."""
    import aiohttp

    async with aiohttp.ClientSession() as session:
        try:
            async with session.ws_connect(url, headers=headers or {}) as ws:
                return dict(_strict((await ws.receive(timeout=10)).data))
        except aiohttp.WSServerHandshakeError as error:
            return error.status


def test_the_websocket_refuses_other_origins_and_missing_tokens() -> None:
    feed = LiveFeed()
    _push_path(feed, 1)
    with LiveServer(feed, port=0) as server:
        base, token = _split(server.url)
        ws = base.replace("http://", "ws://") + "ws"
        own = {"Origin": f"http://127.0.0.1:{server.port}"}
        frame = asyncio.run(_ws_status(f"{ws}?token={token}", own))
        assert isinstance(frame, dict) and frame["counts"]["path_points"] == 1
        assert asyncio.run(_ws_status(f"{ws}?token={token}",
                                      {"Origin": "http://evil.example"})) == 403
        assert asyncio.run(_ws_status(f"{ws}", own)) == 403
        assert asyncio.run(_ws_status(f"{ws}?token=guessed", own)) == 403


def test_the_access_policy_compares_tokens_whole() -> None:
    policy = AccessPolicy("127.0.0.1", 8765, "secret")
    headers = {"Host": "127.0.0.1:8765"}
    assert policy.refusal("/frame", {"token": "secret"}, headers) is None
    for wrong in ("", "secre", "secret2", "SECRET", "sécret"):
        assert policy.refusal("/frame", {"token": wrong}, headers), wrong
    assert policy.refusal("/frame", {"token": "secret"}, {}) == "the request names no Host"
    assert policy.refusal("/static/live.css", {}, {"Host": "LOCALHOST:8765"}) is None


# --- frames: strict JSON, the std's scale ---------------------------------------------------------


def test_frames_are_strict_json_even_with_nan_metrics() -> None:
    assert strict_json({"a": math.nan, "b": [1.0, math.inf], "c": {"d": -math.inf}}) == \
        '{"a":null,"b":[1.0,null],"c":{"d":null}}'
    feed = LiveFeed()
    feed.end("ok", {"centroid_error_m": math.nan, "movements": 3, "max_force_n": math.inf})
    with LiveServer(feed, port=0) as server:
        status, body = _request(server.url.replace("/?", "/frame?"))
    frame = _strict(body)
    assert status == 200 and frame["status"] == "ok"
    assert frame["metrics"]["centroid_error_m"] is None
    assert frame["metrics"]["max_force_n"] is None and frame["metrics"]["movements"] == 3


def test_the_std_image_runs_to_the_maps_largest_std() -> None:
    import base64

    state = LiveState()
    y, x = np.mgrid[0:20, 0:30]
    mean = np.exp(-(((x - 15) / 5.0) ** 2 + ((y - 10) / 4.0) ** 2))
    std = 0.08 * (1 - mean)  # at most 0.08, as a trained BHM's
    state.fold("/map/bhm/grid", 0.2, grid_message(0.2, (0.0, 0.0), (0.01, 0.01), mean, std))
    frame = state.frame()["maps"]["bhm"]
    assert frame["std_scale"] == pytest.approx(float(std.astype(np.float32).max()))
    cells = np.frombuffer(base64.b64decode(frame["std"]), dtype=np.uint8)
    assert cells.max() == 255  # the full colour range, not the bottom sixth of it
    state.fold("/map/bhm/grid", 0.4, grid_message(0.4, (0.0, 0.0), (0.01, 0.01), mean,
                                                  np.zeros_like(std)))
    flat = state.frame()["maps"]["bhm"]
    assert flat["std_scale"] == 0.5 and set(base64.b64decode(flat["std"])) == {0}


def test_a_browsers_favicon_request_gets_204_and_logs_nothing(caplog) -> None:
    # A browser asks for /favicon.ico by itself, without the page's ?token=: it gets an
    # empty 204, is not counted as refused and leaves no warning; a foreign Host is still
    # refused there.
    import logging

    feed = LiveFeed()
    with LiveServer(feed, port=0) as server:
        base, _ = _split(server.url)
        with caplog.at_level(logging.DEBUG):
            for _ in range(2):
                request = urllib.request.Request(f"{base}favicon.ico", headers={
                    "Accept": "image/avif,image/webp,image/png,image/*;q=0.8",
                    "Referer": f"{base}", "Sec-Fetch-Dest": "image"})
                with urllib.request.urlopen(request, timeout=10) as response:
                    assert response.status == 204 and response.read() == b""
                    assert response.headers["X-Content-Type-Options"] == "nosniff"
        assert server.refused == 0
        assert not [r for r in caplog.records if r.levelno >= logging.WARNING], caplog.text
        assert _request(f"{base}favicon.ico", {"Host": "evil.example"})[0] == 403
        assert server.refused == 1


# --- view: each page at its own time, bad times refused -------------------------------------------


def _timeline(tmp_path: Path) -> TimelineFeed:
    recording = RunRecording(tmp_path / "run.mcap")
    for i in range(1, 4):
        recording.event("/movement", "hapticframe.MovementResult", {
            "index": i - 1, "start_m": [0, 0], "end_m": [1, 0], "halted": False,
            "halt_reason": "", "phase": f"phase{i}"}, t_s=float(i))
    recording.close()
    return TimelineFeed(RecordingTimeline.from_recording(read_recording(tmp_path / "run.mcap")))


async def _two_pages(url: str) -> dict[str, list[Any]]:
    """Page A asks for 1 s, page B for 2 s; then A sends bad times; what each then gets."""
    import aiohttp

    ws_url = url.replace("/?", "/ws?")
    seen: dict[str, list[Any]] = {"a": [], "b": []}
    async with aiohttp.ClientSession() as session:
        async with session.ws_connect(ws_url) as a, session.ws_connect(ws_url) as b:
            await a.receive(timeout=10)  # the end first
            await b.receive(timeout=10)
            await a.send_str(json.dumps({"t_s": 1.0}))
            await b.send_str(json.dumps({"t_s": 2.0}))
            seen["a"].append(_strict((await a.receive(timeout=10)).data))
            seen["b"].append(_strict((await b.receive(timeout=10)).data))
            for bad in ("NaN", "Infinity", "1e9", "-5", '"soon"', "true"):
                await a.send_str('{"t_s": ' + bad + '}')
                seen["a"].append(_strict((await a.receive(timeout=10)).data))
            await a.send_str("not json")
            seen["a"].append(_strict((await a.receive(timeout=10)).data))
            await b.send_str(json.dumps({"t_s": 3.0}))
            seen["b"].append(_strict((await b.receive(timeout=10)).data))
            await a.send_str(json.dumps({"t_s": 1.5}))
            seen["a"].append(_strict((await a.receive(timeout=10)).data))
    return seen


def test_each_page_has_its_own_time_and_bad_times_are_refused(tmp_path: Path) -> None:
    feed = _timeline(tmp_path)
    with LiveServer(feed, port=0) as server:
        seen = asyncio.run(_two_pages(server.url))
        frame_url = server.url.replace("/?", "/frame?")
        answers = {bad: _request(f"{frame_url}&t_s={bad}") for bad in ("nan", "inf", "1e9",
                                                                       "abc", "-1")}
        good = _request(f"{frame_url}&t_s=2")
    a, b = seen["a"], seen["b"]
    assert a[0]["timeline"]["t_s"] == 1.0 and b[0]["timeline"]["t_s"] == 2.0
    # Each bad time is answered with an error to that page alone; its time stays.
    errors = [message["error"] for message in a[1:7]]
    assert "t_s=nan is not a finite number" in errors[0]
    assert "not a finite number" in errors[1]
    assert "outside the recording" in errors[2] and "outside the recording" in errors[3]
    assert "not a number" in errors[4] and "not a number" in errors[5]
    assert "not JSON" in a[7]["error"]
    assert b[1]["timeline"]["t_s"] == 3.0 and b[1]["metrics"]["movements"] == 3
    assert a[8]["timeline"]["t_s"] == 1.5 and a[8]["metrics"]["movements"] == 1
    assert server.refused == 6 + len(answers)
    for bad, (status, body) in answers.items():
        assert status == 400 and "t_s" in body, bad
    assert good[0] == 200 and _strict(good[1])["timeline"]["t_s"] == 2.0


# --- stuck pages ----------------------------------------------------------------------------------


def test_a_stuck_page_misses_frames_and_is_disconnected_while_others_go_on() -> None:
    """Pages that never read: each picture is encoded once however many pages there are, a
    page that reads keeps getting frames, and the stuck ones miss frames and are dropped
    after ``stuck_s``."""
    import aiohttp

    feed = LiveFeed()
    rng = np.random.default_rng(0)
    stop = threading.Event()

    def run() -> None:  # the run's thread: big map snapshots, as fast as it can
        n = 0
        while not stop.is_set():
            n += 1
            mean = rng.random((150, 150))
            feed.listener("/map/bhm/grid", n * 0.01, grid_message(
                n * 0.01, (0.0, 0.0), (0.01, 0.01), mean, 0.5 * mean))
            _push_path(feed, n)
            time.sleep(0.01)

    async def read_while_stuck(server: LiveServer) -> list[int]:
        versions: list[int] = []
        async with aiohttp.ClientSession() as session:
            async with session.ws_connect(server.url.replace("/?", "/ws?")) as ws:
                deadline = time.monotonic() + BOUND_S
                while server.pages_dropped < 4 and time.monotonic() < deadline:
                    message = await ws.receive(timeout=10)
                    versions.append(_strict(message.data)["counts"]["map_versions"])
        return versions

    writer = threading.Thread(target=run, name="the run")
    with LiveServer(feed, port=0, rate_hz=30, stuck_s=1.0) as server:
        stuck: list[socket.socket] = []
        try:
            stuck = stuck_clients(server.url, 4, receive_buffer=4096)
            writer.start()
            versions = asyncio.run(read_while_stuck(server))
        finally:
            stop.set()
            writer.join(10)
            for client in stuck:
                client.close()
        assert server.pages_dropped == 4, (server.pages_dropped, server.frames_skipped)
        assert server.frames_skipped >= 4
        # The reading page kept getting newer pictures while the others were stuck.
        assert len(versions) >= 5 and versions[-1] > versions[0]
        assert versions == sorted(versions)
        # Encoded once per picture, not once per page.
        assert server.frames_encoded <= feed.state.version


def test_view_prints_its_token_and_answers_only_with_it(
        tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch) -> None:
    import re

    from hapticframe.cli import _view
    from hapticframe.cli._cli import main

    _timeline(tmp_path)  # writes tmp_path / "run.mcap"
    seen: dict[str, Any] = {}

    def look() -> None:  # stands in for waiting for Ctrl-C
        printed = capsys.readouterr().out
        found = re.search(r"at (http://127\.0\.0\.1:\d+/)\?token=([\w-]+)", printed)
        assert found is not None, printed
        base, token = found.groups()
        seen["bare"] = _request(f"{base}frame")
        seen["nan"] = _request(f"{base}frame?token={token}&t_s=nan")
        seen["ok"] = _request(f"{base}frame?token={token}&t_s=2")

    monkeypatch.setattr(_view, "wait_for_interrupt", look)
    assert main(["view", str(tmp_path / "run.mcap"), "--port", "0"]) == 0
    assert seen["bare"][0] == 403 and seen["nan"][0] == 400
    assert seen["ok"][0] == 200 and _strict(seen["ok"][1])["metrics"]["movements"] == 2
