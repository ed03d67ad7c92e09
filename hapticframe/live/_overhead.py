"""What serving the live page costs a run, with and without stuck clients (issue 26 §5).

``python -m hapticframe.live._overhead [EXPERIMENT] [--repeats N] [--stuck N]`` runs the
experiment (figures off) in this process, interleaving three settings: no live view; the
live view's listener and server with no page open; the same with ``--stuck`` websocket
clients that finish the handshake and then never read a byte (as a hung tab or a
malicious local script would). It prints each run's wall time and the process's CPU time
during it (the loop's and the server thread's together: less sensitive to other jobs on
the machine than wall time), and their medians. The clients connect before the run starts.
"""

from __future__ import annotations

import argparse
import base64
import os
import re
import socket
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

__all__ = ["stuck_clients", "main"]


def stuck_clients(url: str, count: int, timeout_s: float = 10.0,
                  receive_buffer: int | None = None) -> list[socket.socket]:
    """``count`` websocket clients of the page at ``url`` (its token included) that have
    been answered ``101 Switching Protocols`` and will never read again (``receive_buffer``:
    their sockets' ``SO_RCVBUF`` in bytes, small to fill them sooner)."""
    parts = urlsplit(url)
    host, port = parts.hostname or "127.0.0.1", parts.port or 80
    target = "/ws" + (f"?{parts.query}" if parts.query else "")
    clients: list[socket.socket] = []
    for _ in range(count):
        client = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        if receive_buffer is not None:  # before connecting: it sizes the TCP window
            client.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
        client.settimeout(timeout_s)
        client.connect((host, port))
        key = base64.b64encode(os.urandom(16)).decode("ascii")
        client.sendall((f"GET {target} HTTP/1.1\r\nHost: {host}:{port}\r\n"
                        "Upgrade: websocket\r\nConnection: Upgrade\r\n"
                        f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n")
                       .encode("ascii"))
        answer = b""
        while b"\r\n\r\n" not in answer:
            chunk = client.recv(1)  # one byte at a time: read nothing past the answer
            if not chunk:
                raise ConnectionError(f"the server closed the connection: {answer!r}")
            answer += chunk
        if not answer.startswith(b"HTTP/1.1 101"):
            raise ConnectionError(f"the server refused the websocket: {answer[:200]!r}")
        clients.append(client)
    return clients


def _one_run(experiment: Any, out: Path, setting: str, stuck: int) -> tuple[float, float]:
    from hapticframe.live import run_live
    from hapticframe.record._recorded import run_experiment

    timed: dict[str, float] = {}

    def run() -> Any:
        start, cpu = time.perf_counter(), time.process_time()
        metrics = run_experiment(experiment, out, overwrite=True, echo=lambda _t: None,
                                 progress=False)
        timed["wall_s"] = time.perf_counter() - start
        timed["cpu_s"] = time.process_time() - cpu
        return metrics

    if setting == "no live view":
        run()
        return timed["wall_s"], timed["cpu_s"]
    lines: list[str] = []
    clients: list[socket.socket] = []

    def run_with_clients() -> Any:
        if stuck:
            found = re.search(r"(http://\S+)", lines[0])
            assert found is not None, lines
            clients.extend(stuck_clients(found.group(1), stuck))
        return run()

    try:
        run_live(experiment, run_with_clients if setting != "server, no page" else run,
                 port=0, say=lines.append, wait=lambda: None)
    finally:
        for client in clients:
            client.close()
    return timed["wall_s"], timed["cpu_s"]


def main(argv: list[str] | None = None) -> int:
    from hapticframe._config import validate_data
    from hapticframe._config._load import load_file

    parser = argparse.ArgumentParser(prog="python -m hapticframe.live._overhead")
    parser.add_argument("experiment", nargs="?", default="examples/search-ellipse.yaml")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--stuck", type=int, default=50)
    args = parser.parse_args(argv)
    import yaml

    model = yaml.safe_load(Path(args.experiment).read_text(encoding="utf-8"))
    model.setdefault("run", {})["figures"] = False
    with tempfile.TemporaryDirectory() as scratch:
        (Path(scratch) / "experiment.yaml").write_text(yaml.safe_dump(model), encoding="utf-8")
        experiment = validate_data(load_file(str(Path(scratch) / "experiment.yaml")))
        settings: dict[str, Callable[[], tuple[float, float]]] = {
            "no live view": lambda: _one_run(experiment, Path(scratch) / "a", "no live view", 0),
            "server, no page": lambda: _one_run(experiment, Path(scratch) / "b",
                                                "server, no page", 0),
            f"{args.stuck} stuck clients": lambda: _one_run(experiment, Path(scratch) / "c",
                                                            "stuck", args.stuck),
        }
        times: dict[str, list[tuple[float, float]]] = {name: [] for name in settings}
        settings["no live view"]()  # imports and first calls fall on no setting
        for repeat in range(args.repeats):
            for name, measure in settings.items():
                times[name].append(measure())
                wall, cpu = times[name][-1]
                print(f"repeat {repeat + 1}: {name}: {wall:.3f} s wall, {cpu:.3f} s CPU",
                      flush=True)
    for column, label in ((0, "wall"), (1, "CPU")):
        base = statistics.median(t[column] for t in times["no live view"])
        for name, pairs in times.items():
            values = [t[column] for t in pairs]
            median = statistics.median(values)
            print(f"{label}: {name}: median {median:.3f} s ({100 * (median / base - 1):+.1f} %)"
                  f", range {min(values):.3f}-{max(values):.3f} s over {len(values)} runs")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
