"""What ``run --foxglove`` costs a run, with and without a subscribed client (issue 35 §3).

``python -m hapticframe.live._foxglove_overhead [EXPERIMENT] [--repeats N]`` runs the
experiment (figures off) in this process, interleaving three settings: no Foxglove server;
the server with no client; the server with one client, in a process of its own, that
subscribes to every channel as it is advertised and reads every message (as Foxglove's
app does with all panels open). It prints each run's wall time and this process's CPU time
during it (the loop's and the SDK server's threads together; the client's own CPU is not
counted: it is the viewer's, not the run's), and their medians, as
:mod:`hapticframe.live._overhead` does for the live page. The client connects before the
run starts.
"""

from __future__ import annotations

import argparse
import asyncio
import functools
import json
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["main", "read_all"]

#: The WebSocket subprotocol of the SDK's server (``foxglove.websocket.v1``'s messages).
SUBPROTOCOL = "foxglove.sdk.v1"


def read_all(url: str) -> int:
    """Subscribe to every channel the server at ``url`` advertises and read until it
    closes; prints ``ready`` once connected and the frames and bytes read at the end."""
    import aiohttp

    async def read() -> tuple[int, int]:
        frames = size = 0
        subscriptions = 0
        async with aiohttp.ClientSession() as session, session.ws_connect(
                url, protocols=[SUBPROTOCOL], max_msg_size=0) as ws:
            async for msg in ws:
                if msg.type == aiohttp.WSMsgType.BINARY:
                    frames, size = frames + 1, size + len(msg.data)
                elif msg.type == aiohttp.WSMsgType.TEXT:
                    message = json.loads(msg.data)
                    if message["op"] == "serverInfo":
                        print("ready", flush=True)
                    elif message["op"] == "advertise":
                        wanted = []
                        for channel in message["channels"]:
                            subscriptions += 1
                            wanted.append({"id": subscriptions, "channelId": channel["id"]})
                        await ws.send_str(json.dumps({"op": "subscribe",
                                                      "subscriptions": wanted}))
        return frames, size

    frames, size = asyncio.run(read())
    print(f"read {frames} frames, {size} bytes", flush=True)
    return 0


def _one_run(experiment: Any, out: Path, setting: str) -> tuple[float, float, str]:
    from hapticframe.live._foxglove import FoxgloveBridge
    from hapticframe.record._recorded import run_experiment
    from hapticframe.record._recording import listening

    def run() -> tuple[float, float]:
        start, cpu = time.perf_counter(), time.process_time()
        run_experiment(experiment, out, overwrite=True, echo=lambda _t: None, progress=False)
        return time.perf_counter() - start, time.process_time() - cpu

    if setting == "no foxglove":
        return (*run(), "")
    bridge = FoxgloveBridge(port=0)
    client, note = None, ""
    try:
        if setting == "subscribed client":
            client = subprocess.Popen(
                [sys.executable, "-m", "hapticframe.live._foxglove_overhead", "--client",
                 bridge.url], stdout=subprocess.PIPE, text=True)
            assert client.stdout is not None
            line = client.stdout.readline()
            if line.strip() != "ready":
                raise RuntimeError(f"the client did not connect: {line!r}")
        with listening(bridge):
            wall, cpu = run()
        note = f"{bridge.messages_sent} messages sent"
    finally:
        bridge.close()
        if client is not None:
            tail, _ = client.communicate(timeout=60)
            note += f", client {tail.strip()}"
    return wall, cpu, note


def main(argv: list[str] | None = None) -> int:
    from hapticframe._config import validate_data
    from hapticframe._config._load import load_file

    parser = argparse.ArgumentParser(prog="python -m hapticframe.live._foxglove_overhead")
    parser.add_argument("experiment", nargs="?", default="examples/search-ellipse.yaml")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--client", metavar="URL", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.client:
        return read_all(args.client)
    import yaml

    model = yaml.safe_load(Path(args.experiment).read_text(encoding="utf-8"))
    model.setdefault("run", {})["figures"] = False
    with tempfile.TemporaryDirectory() as scratch:
        (Path(scratch) / "experiment.yaml").write_text(yaml.safe_dump(model), encoding="utf-8")
        experiment = validate_data(load_file(str(Path(scratch) / "experiment.yaml")))
        names = ("no foxglove", "server, no client", "subscribed client")
        out = Path(scratch) / "out"
        settings: dict[str, Callable[[], tuple[float, float, str]]] = {
            name: functools.partial(_one_run, experiment, out, name) for name in names}
        times: dict[str, list[tuple[float, float]]] = {name: [] for name in settings}
        settings["no foxglove"]()  # imports and first calls fall on no setting
        settings["subscribed client"]()
        for repeat in range(args.repeats):
            for name, measure in settings.items():
                wall, cpu, note = measure()
                times[name].append((wall, cpu))
                print(f"repeat {repeat + 1}: {name}: {wall:.3f} s wall, {cpu:.3f} s CPU"
                      + (f" ({note})" if note else ""), flush=True)
    for column, label in ((0, "wall"), (1, "CPU")):
        base = statistics.median(t[column] for t in times["no foxglove"])
        for name, pairs in times.items():
            values = [t[column] for t in pairs]
            median = statistics.median(values)
            print(f"{label}: {name}: median {median:.3f} s ({100 * (median / base - 1):+.1f} %)"
                  f", range {min(values):.3f}-{max(values):.3f} s over {len(values)} runs")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
