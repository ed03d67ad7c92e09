"""``hapticframe run --foxglove``: the run over Foxglove's WebSocket protocol, read by a client
of our own that speaks it (aiohttp), checked against the run's ``run.mcap``."""

from __future__ import annotations

import asyncio
import importlib.util
import json
import socket
import struct
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from hapticframe.cli._cli import main

ROOT = Path(__file__).resolve().parents[2]
#: The subprotocol the SDK's server speaks (the same messages as ``foxglove.websocket.v1``,
#: renamed in the SDK; Foxglove and Lichtblick offer both).
SUBPROTOCOL = "foxglove.sdk.v1"
#: How long a step may take before the test fails (never a timing assertion: only a bound
#: that stops a broken server from hanging the suite).
PATIENCE_S = 30.0

needs_sdk = pytest.mark.skipif(
    importlib.util.find_spec("foxglove") is None or importlib.util.find_spec("aiohttp") is None,
    reason="the 'foxglove' extra (foxglove-sdk) or aiohttp (the test's client) is not installed")


def _short_experiment(tmp_path: Path) -> Path:
    model = yaml.safe_load((ROOT / "examples" / "search-ellipse.yaml").read_text())
    model["run"].update(figures=False, max_movements=1)
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(model))
    return path


def _recorded(path: Path) -> tuple[dict[str, list[tuple[int, bytes]]], dict[str, dict[str, str]]]:
    """``run.mcap``'s raw messages ``(log time, bytes)`` and each channel's encoding, schema
    name, schema encoding and schema text, per topic."""
    from mcap.reader import make_reader

    messages: dict[str, list[tuple[int, bytes]]] = {}
    channels: dict[str, dict[str, str]] = {}
    with path.open("rb") as stream:
        reader = make_reader(stream)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            messages.setdefault(channel.topic, []).append((message.log_time, message.data))
            assert schema is not None
            channels[channel.topic] = {
                "encoding": channel.message_encoding, "schemaName": schema.name,
                "schemaEncoding": schema.encoding, "schema": schema.data.decode()}
    return messages, channels


class _Client(threading.Thread):
    """A Foxglove WebSocket client: reads ``serverInfo``, subscribes to every channel the
    server advertises and keeps each message data frame (opcode 0x01) it gets."""

    def __init__(self, url: str) -> None:
        super().__init__(daemon=True)
        self.url = url
        self.ready = threading.Event()
        self.server_info: dict[str, Any] | None = None
        self.advertised: dict[int, dict[str, Any]] = {}  # channel id -> advertisement
        self.subscriptions: dict[int, int] = {}  # subscription id -> channel id
        self.frames: list[tuple[int, int, bytes]] = []  # (subscription id, log time, data)
        self.error: BaseException | None = None

    def run(self) -> None:
        try:
            asyncio.run(self._read())
        except BaseException as exc:  # reported by the test, not lost in the thread
            self.error = exc
        finally:
            self.ready.set()

    async def _read(self) -> None:
        import aiohttp

        async with aiohttp.ClientSession() as session, session.ws_connect(
                self.url, protocols=[SUBPROTOCOL]) as ws:
            assert ws.protocol == SUBPROTOCOL
            async for msg in ws:  # until the server closes
                if msg.type == aiohttp.WSMsgType.TEXT:
                    await self._control(ws, json.loads(msg.data))
                elif msg.type == aiohttp.WSMsgType.BINARY:
                    opcode, subscription, log_time = struct.unpack_from("<BIQ", msg.data)
                    assert opcode == 0x01, f"binary opcode {opcode:#x}"
                    self.frames.append((subscription, log_time, bytes(msg.data[13:])))

    async def _control(self, ws: Any, message: Mapping[str, Any]) -> None:
        if message["op"] == "serverInfo":
            self.server_info = dict(message)
            self.ready.set()
        elif message["op"] == "advertise":
            wanted = []
            for channel in message["channels"]:
                self.advertised[channel["id"]] = channel
                subscription = len(self.subscriptions) + 1
                self.subscriptions[subscription] = channel["id"]
                wanted.append({"id": subscription, "channelId": channel["id"]})
            await ws.send_str(json.dumps({"op": "subscribe", "subscriptions": wanted}))

    def received(self) -> dict[str, list[tuple[int, bytes]]]:
        """The frames per topic, in the order they came."""
        out: dict[str, list[tuple[int, bytes]]] = {}
        for subscription, log_time, data in self.frames:
            topic = self.advertised[self.subscriptions[subscription]]["topic"]
            out.setdefault(topic, []).append((log_time, data))
        return out


def _until(condition: Callable[[], bool], what: str) -> None:
    deadline = time.monotonic() + PATIENCE_S
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"no {what} within {PATIENCE_S} s")
        time.sleep(0.005)


@contextmanager
def _connected(bridge: Any) -> Iterator[_Client]:
    client = _Client(bridge.url)
    client.start()
    assert client.ready.wait(PATIENCE_S) and client.error is None, client.error
    try:
        yield client
    finally:
        bridge.close()  # the server closes the connection: the client's loop ends
        client.join(PATIENCE_S)


@needs_sdk
def test_a_subscribed_client_gets_every_message_of_run_mcap(tmp_path: Path) -> None:
    from hapticframe import run_experiment, validate_file
    from hapticframe.live._foxglove import FoxgloveBridge
    from hapticframe.record._foxglove import decode_grid
    from hapticframe.record._recording import listening

    experiment = validate_file(str(_short_experiment(tmp_path)))
    bridge = FoxgloveBridge(port=0, backlog=1_000_000)  # the test keeps every message
    assert bridge.url == f"ws://127.0.0.1:{bridge.port}"
    with _connected(bridge) as client:
        assert client.server_info is not None and client.server_info["name"] == "hapticframe"
        assert client.server_info["capabilities"] == []  # the client reads, nothing more

        def subscribed_first(topic: str, t_s: float, data: Mapping[str, Any],
                             payload: bytes) -> None:
            # Only here does the loop wait: until the client has subscribed to a new topic,
            # so that it gets the topic's first message too and the test can ask for all.
            channel = bridge.advertise(topic)
            _until(channel.has_sinks, f"subscription to {topic}")
            bridge(topic, t_s, data, payload)

        subscribed_first.wants_payload = True  # type: ignore[attr-defined]
        with listening(subscribed_first):
            metrics = run_experiment(experiment, tmp_path / "out", echo=lambda _t: None,
                                     progress=False)
        _until(lambda: len(client.frames) >= bridge.messages_sent, "last frames")
    assert client.error is None, client.error
    recorded, channels = _recorded(tmp_path / "out" / "run.mcap")
    received = client.received()

    # The same channels and schemas as run.mcap, and every message, byte for byte, at its
    # log time, in order.
    advertised = {c["topic"]: {k: c[k] for k in ("encoding", "schemaName", "schemaEncoding",
                                                 "schema")} for c in client.advertised.values()}
    assert advertised == channels
    assert received == recorded
    assert bridge.messages_sent == sum(len(m) for m in recorded.values())

    # The force as a client decodes it: the run's peak |F| is among the samples it got.
    batches = [json.loads(data) for _t, data in received["/sensor/wrist"]]
    forces = np.concatenate([np.asarray(b["channels"]["force_n"], dtype=float)
                             for b in batches])
    assert forces.shape[1] == 2 and len(forces) > 10
    assert np.nanmax(np.linalg.norm(forces, axis=1)) == pytest.approx(
        metrics["max_measured_force_n"], rel=1e-9)
    stamps = np.concatenate([b["timestamps_s"] for b in batches])
    assert np.all(np.diff(stamps) > 0)
    # Each frame's timestamp is its batch's last sample time, in ns.
    assert [t for t, _d in received["/sensor/wrist"]] == [
        round(b["timestamps_s"][-1] * 1e9) for b in batches]

    # The map as a client decodes it: an occupancy grid over the search region.
    for map_id in ("bhm", "grid"):
        (_t, data), *_ = received[f"/map/{map_id}/grid"][-1:]
        grid = decode_grid(json.loads(data))
        assert grid["mean"].shape == grid["std"].shape == (len(grid["ys"]), len(grid["xs"]))
        assert grid["mean"].size > 100 and np.all(np.isfinite(grid["mean"]))
        assert np.all((grid["mean"] >= 0) & (grid["mean"] <= 1))


@needs_sdk
def test_nobody_subscribed_costs_no_encoding() -> None:
    from hapticframe.live._foxglove import FoxgloveBridge

    with FoxgloveBridge(port=0) as bridge:
        bridge("/sensor/wrist", 1.0, {"timestamps_s": [1.0]})
        assert bridge.messages_sent == 0  # advertised, not encoded
        with pytest.raises(ValueError, match="no channel of the table"):
            bridge("/not-a-channel", 1.0, {})
    bridge.close()  # idempotent


@needs_sdk
def test_run_foxglove_serves_the_recording_channels(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    from hapticframe.live import _foxglove

    advertised: list[str] = []
    plain = _foxglove.FoxgloveBridge.advertise

    def advertise(self: Any, topic: str) -> Any:
        advertised.append(topic)
        return plain(self, topic)

    monkeypatch.setattr(_foxglove.FoxgloveBridge, "advertise", advertise)
    assert main(["run", str(_short_experiment(tmp_path)), "--out", str(tmp_path / "out"),
                 "--quiet", "--foxglove", "0"]) == 0
    printed = capsys.readouterr().out
    assert "foxglove: ws://127.0.0.1:" in printed and "the run has ended" in printed
    recorded, _channels = _recorded(tmp_path / "out" / "run.mcap")
    assert sorted(advertised) == sorted(recorded)  # each topic once, the same topics


@needs_sdk
def test_run_foxglove_refuses_a_taken_port_and_the_live_page_s(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    experiment = str(_short_experiment(tmp_path))
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["run", experiment, "--out", str(tmp_path / "a"), "--quiet",
                     "--foxglove", str(port)]) == 2
    message = capsys.readouterr().err
    assert f"cannot serve on 127.0.0.1:{port}" in message and "Traceback" not in message
    assert not (tmp_path / "a").exists()  # refused before the run
    assert main(["run", experiment, "--out", str(tmp_path / "b"), "--quiet", "--live",
                 "--port", "8799", "--foxglove", "8799"]) == 2
    assert "the live page's port too" in capsys.readouterr().err


def test_run_foxglove_without_the_sdk_names_the_extra(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "foxglove", None)  # import foxglove raises ImportError
    experiment = str(_short_experiment(tmp_path))
    assert main(["run", experiment, "--out", str(tmp_path / "out"), "--quiet",
                 "--foxglove"]) == 2
    message = capsys.readouterr().err
    assert "hapticframe[foxglove]" in message and "Traceback" not in message
    assert not (tmp_path / "out").exists()
    # Nothing else needs it.
    assert main(["validate", experiment]) == 0
    assert main(["plugins"]) == 0
