"""The ``live`` family of ``hapticframe bench fuzz``: the live page's server, as a hostile
client meets it.

One ``hapticframe view RUN --port 0`` serves a finished run for the whole family, in a
child process whose error output is watched. Each case is one connection:

* ``junk_http``: bytes that are no HTTP request, or a request broken one way (a bad method,
  version or header, a line 100,000 characters long, a request cut short);
* ``frame_query``: ``GET /frame?t_s=`` with values that are no time (NaN, infinity, 1e309,
  text, nothing);
* ``websocket``: a websocket opened properly, then frames no page sends (junk text, JSON
  with NaN or huge times, binary, a 1 MB frame, an unmasked frame, an unknown opcode, a
  close with a junk code);
* ``foreign``: a foreign ``Host`` or ``Origin`` header, or the token missing or wrong.

Every answer must be a refusal (a 4xx status, or the connection closed) or a clean answer
whose JSON is strict; a 5xx, a traceback in the server's output, a JSON frame with NaN, or a
server that stops answering is a finding. The token and Origin checks are asserted only
when the server has them (the URL ``view`` prints carries a token, or
:class:`hapticframe.live.LiveServer` takes one): then a foreign request that is served is a
finding (``served_foreign``); without them it is counted as ``served`` and the report says
that the feature was absent.
"""

from __future__ import annotations

import base64
import contextlib
import inspect
import json
import os
import re
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl, urlencode, urlsplit

import numpy as np

from hapticframe_bench._fuzz_common import Case, Outcome

__all__ = ["KINDS", "LiveTarget", "check_live_case", "generate_live_cases", "start_view",
           "token_feature_present"]

KINDS = ("junk_http", "frame_query", "websocket", "foreign")
_TIMEOUT_S = 1.5
_JUNK_REQUESTS: tuple[bytes, ...] = (
    b"\x00\xff\xfe junk\r\n\r\n", b"GET\r\n\r\n", b"BREW /frame HTTP/1.1\r\nHost: {host}\r\n\r\n",
    b"GET /frame HTTP/9.9\r\nHost: {host}\r\n\r\n", b"GET /frame HTTP/1.1\r\nno colon\r\n\r\n",
    b"GET /" + b"a" * 100_000 + b" HTTP/1.1\r\nHost: {host}\r\n\r\n",
    b"GET /frame HTTP/1.1\r\nHost: {host}\r\nX-Long: " + b"b" * 100_000 + b"\r\n\r\n",
    b"GET /frame HTTP/1.1\r\nHost: {host}\r\nContent-Length: -5\r\n\r\n",
    b"POST /frame HTTP/1.1\r\nHost: {host}\r\nContent-Length: 99999999\r\n\r\nshort",
    b"GET /frame HTTP/1.1\r\nHost: {host}\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n",
    b"GET /frame HTTP/1.1\r\nHo", b"GET /../../../../etc/passwd HTTP/1.1\r\nHost: {host}\r\n\r\n",
    b"GET /static/../../__init__.py HTTP/1.1\r\nHost: {host}\r\n\r\n",
    b"GET /ws HTTP/1.1\r\nHost: {host}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\r\n",
    b"\r\n\r\n\r\n", b"GET /frame HTTP/1.1\r\nHost: {host}\r\n" + b"X: y\r\n" * 500 + b"\r\n")
_QUERIES = ("nan", "NaN", "inf", "-inf", "1e309", "-1e309", "1e9", "-1e9", "", "x", "%00",
            "0x10", "1_0", "9" * 5000, "nan&t_s=1", "[1]")
_WS_PAYLOADS: tuple[Any, ...] = (
    "junk", "{", "[]", "null", '{"t_s": NaN}', '{"t_s": Infinity}', '{"t_s": -Infinity}',
    '{"t_s": 1e308}', '{"t_s": -1e308}', '{"t_s": "x"}', '{"t_s": [1]}', '{"t_s": {}}',
    '{"t_s": 1e9}', '{"t_s": null}', '{"t_s": 3.5}', "9" * 5000)


class LiveTarget:
    """The running ``view`` server: its address, the query its URL carries, its output."""

    def __init__(self, process: subprocess.Popen[str], url: str, stderr: Path) -> None:
        self.process = process
        parts = urlsplit(url)
        self.host = parts.hostname or "127.0.0.1"
        self.port = int(parts.port or 80)
        self.query = dict(parse_qsl(parts.query))
        self.stderr = stderr
        self.read_to = 0

    @property
    def host_header(self) -> str:
        return f"{self.host}:{self.port}"

    @property
    def has_token(self) -> bool:
        return any("token" in key for key in self.query)

    def new_errors(self) -> str:
        text = self.stderr.read_text(encoding="utf-8", errors="replace")
        new, self.read_to = text[self.read_to:], len(text)
        return new

    def stop(self) -> None:
        self.process.terminate()
        try:
            self.process.wait(10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(10)


def token_feature_present(target: LiveTarget | None = None) -> bool:
    """Whether the live server checks a per-session token (seen in the URL it prints, or in
    :class:`hapticframe.live.LiveServer`'s parameters)."""
    if target is not None and target.has_token:
        return True
    from hapticframe.live import LiveServer

    parameters = inspect.signature(LiveServer.__init__).parameters
    return "token" in parameters or hasattr(LiveServer, "token")


def start_view(run_dir: Path, workdir: Path) -> LiveTarget:
    """Start ``hapticframe view run_dir --port 0`` and wait for its address."""
    workdir.mkdir(parents=True, exist_ok=True)
    stderr = workdir / "view.stderr"
    process = subprocess.Popen(
        [sys.executable, "-m", "hapticframe", "view", str(run_dir), "--port", "0"],
        stdout=subprocess.PIPE, stderr=stderr.open("w", encoding="utf-8"), text=True,
        env={**os.environ, "OMP_NUM_THREADS": "1"})
    assert process.stdout is not None
    deadline = time.monotonic() + 60
    line = ""
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        match = re.search(r"(http://\S+)", line)
        if match:
            return LiveTarget(process, match.group(1), stderr)
        if not line and process.poll() is not None:
            break
    process.kill()
    raise RuntimeError(f"hapticframe view did not start: {line!r} "
                       f"{stderr.read_text(encoding='utf-8', errors='replace')[-300:]}")


def generate_live_cases(count: int, seed: int) -> list[Case]:
    """``count`` cases: the kinds in turn, each's payload drawn (seeded)."""
    rng = np.random.default_rng(seed)
    cases = []
    for k in range(count):
        kind = KINDS[k % len(KINDS)]
        data: dict[str, Any] = {"pick": int(rng.integers(1 << 30))}
        if kind == "junk_http":
            raw = _JUNK_REQUESTS[data["pick"] % len(_JUNK_REQUESTS)]
            change = repr(raw[:50])
        elif kind == "frame_query":
            change = f"GET /frame?t_s={_QUERIES[data['pick'] % len(_QUERIES)][:30]}"
        elif kind == "websocket":
            way = ("text", "text", "binary", "huge", "unmasked", "opcode", "close")[
                data["pick"] % 7]
            data["way"] = way
            change = f"websocket {way} frame" + (
                f" {_WS_PAYLOADS[data['pick'] % len(_WS_PAYLOADS)][:30]!r}"
                if way == "text" else "")
        else:
            what = ("host", "origin_frame", "origin_ws", "no_token", "wrong_token",
                    "host_and_origin")[data["pick"] % 6]
            data["what"] = what
            change = f"foreign: {what}"
        cases.append(Case("live", kind, change, data))
    return cases


def _path(target: LiveTarget, path: str, extra: dict[str, str] | None = None,
          *, token: bool = True) -> str:
    query = dict(target.query) if token else {}
    query.update(extra or {})
    return path + ("?" + urlencode(query) if query else "")


def _exchange(target: LiveTarget, raw: bytes, *, wait_s: float = _TIMEOUT_S) -> bytes:
    """Send ``raw`` on a new connection; what came back before it closed or went quiet."""
    with socket.create_connection((target.host, target.port), timeout=wait_s) as sock:
        with contextlib.suppress(OSError):
            sock.sendall(raw)
        chunks = []
        deadline = time.monotonic() + wait_s
        with contextlib.suppress(OSError):
            while time.monotonic() < deadline:
                chunk = sock.recv(65536)
                if not chunk:
                    break
                chunks.append(chunk)
                if _complete(b"".join(chunks)):
                    break
        return b"".join(chunks)


def _complete(reply: bytes) -> bool:
    head, sep, body = reply.partition(b"\r\n\r\n")
    if not sep:
        return False
    if head.startswith(b"HTTP/1.1 101"):
        return True
    match = re.search(rb"(?i)content-length:\s*(\d+)", head)
    return match is not None and len(body) >= int(match.group(1))


def _status(reply: bytes) -> int | None:
    match = re.match(rb"HTTP/\d\.\d (\d{3})", reply)
    return int(match.group(1)) if match else None


def _get(target: LiveTarget, path: str, *, host: str | None = None,
         headers: dict[str, str] | None = None) -> bytes:
    lines = [f"GET {path} HTTP/1.1", f"Host: {host if host is not None else target.host_header}",
             "Connection: close"] + [f"{k}: {v}" for k, v in (headers or {}).items()]
    return _exchange(target, ("\r\n".join(lines) + "\r\n\r\n").encode())


def _strict_json(body: bytes) -> str | None:
    """Why ``body`` is not strict JSON, or None."""
    def refuse(token: str) -> Any:
        raise ValueError(f"non-strict JSON constant {token}")

    try:
        json.loads(body.decode("utf-8"), parse_constant=refuse)
    except (ValueError, UnicodeDecodeError) as exc:
        return str(exc)[:120]
    return None


def _ws_frame(opcode: int, payload: bytes, *, masked: bool = True) -> bytes:
    head = bytearray([0x80 | opcode])
    mask_bit = 0x80 if masked else 0
    n = len(payload)
    if n < 126:
        head.append(mask_bit | n)
    elif n < 1 << 16:
        head.append(mask_bit | 126)
        head += n.to_bytes(2, "big")
    else:
        head.append(mask_bit | 127)
        head += n.to_bytes(8, "big")
    if not masked:
        return bytes(head) + payload
    key = os.urandom(4)
    return bytes(head) + key + bytes(b ^ key[i % 4] for i, b in enumerate(payload))


def _ws_handshake(target: LiveTarget, *, origin: str | None, token: bool = True,
                  host: str | None = None) -> tuple[socket.socket | None, int | None]:
    key = base64.b64encode(os.urandom(16)).decode()
    lines = [f"GET {_path(target, '/ws', token=token)} HTTP/1.1",
             f"Host: {host if host is not None else target.host_header}",
             "Upgrade: websocket", "Connection: Upgrade", f"Sec-WebSocket-Key: {key}",
             "Sec-WebSocket-Version: 13"]
    if origin is not None:
        lines.append(f"Origin: {origin}")
    sock = socket.create_connection((target.host, target.port), timeout=_TIMEOUT_S)
    sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
    reply = b""
    with contextlib.suppress(OSError):
        while b"\r\n\r\n" not in reply:
            chunk = sock.recv(4096)
            if not chunk:
                break
            reply += chunk
    status = _status(reply)
    if status != 101:
        sock.close()
        return None, status
    return sock, status


def _ws_read_text(sock: socket.socket, wait_s: float = 1.5) -> bytes | None:
    """The first text frame the server sends within ``wait_s``, or None."""
    buffer = b""
    deadline = time.monotonic() + wait_s
    sock.settimeout(0.3)
    while time.monotonic() < deadline:
        with contextlib.suppress(TimeoutError, socket.timeout):
            chunk = sock.recv(1 << 20)
            if not chunk:
                return None
            buffer += chunk
        while len(buffer) >= 2:
            opcode, n, at = buffer[0] & 0x0F, buffer[1] & 0x7F, 2
            if n == 126:
                n, at = int.from_bytes(buffer[2:4], "big"), 4
            elif n == 127:
                n, at = int.from_bytes(buffer[2:10], "big"), 10
            if len(buffer) < at + n:
                break
            payload, buffer = buffer[at:at + n], buffer[at + n:]
            if opcode == 1:
                return payload
            if opcode == 8:
                return None
    return None


def _origin_page(target: LiveTarget) -> str:
    return f"http://{target.host_header}"


def _run(case: Case, target: LiveTarget) -> tuple[str, str]:
    """(status, detail) of the exchange alone."""
    pick = case.data["pick"]
    if case.kind == "junk_http":
        raw = _JUNK_REQUESTS[pick % len(_JUNK_REQUESTS)].replace(
            b"{host}", target.host_header.encode())
        status = _status(_exchange(target, raw))
        if status is not None and status >= 500:
            return "internal_error", f"HTTP {status}"
        return ("served" if status is not None and status < 400 else "refused"), \
            f"HTTP {status}"
    if case.kind == "frame_query":
        reply = _get(target, _path(target, "/frame", {"t_s": _QUERIES[pick % len(_QUERIES)]}))
        status = _status(reply)
        if status is not None and status >= 500:
            return "internal_error", f"HTTP {status}"
        if status == 200:
            why = _strict_json(reply.partition(b"\r\n\r\n")[2])
            return ("null_result", f"HTTP 200, {why}") if why else ("served", "HTTP 200")
        return "refused", f"HTTP {status}"
    if case.kind == "websocket":
        return _websocket(case, target)
    return _foreign(case, target)


def _websocket(case: Case, target: LiveTarget) -> tuple[str, str]:
    sock, status = _ws_handshake(target, origin=_origin_page(target))
    if sock is None:
        return "unexpected", f"the page's own websocket was refused (HTTP {status})"
    way, pick = case.data["way"], case.data["pick"]
    with sock:
        _ws_read_text(sock, 1.0)  # the first frame, before the junk
        frame = {"text": _ws_frame(1, str(_WS_PAYLOADS[pick % len(_WS_PAYLOADS)]).encode()),
                 "binary": _ws_frame(2, os.urandom(64)),
                 "huge": _ws_frame(1, b"[" * (1 << 20)),
                 "unmasked": _ws_frame(1, b'{"t_s": 1}', masked=False),
                 "opcode": _ws_frame(0x3, b"x"),
                 "close": _ws_frame(8, (1).to_bytes(2, "big") + b"\xff\xfe")}[way]
        with contextlib.suppress(OSError):
            sock.sendall(frame)
        reply = None
        with contextlib.suppress(OSError):
            reply = _ws_read_text(sock, 1.5)
    if reply is not None:
        why = _strict_json(reply)
        if why:
            return "null_result", f"a frame after it is not strict JSON: {why}"
        return "served", "frames went on"
    return "refused", "no frame after it (closed or unchanged)"


def _foreign(case: Case, target: LiveTarget) -> tuple[str, str]:
    what = case.data["what"]
    evil = "http://evil.example"
    status: int | None
    if what == "host":
        status = _status(_get(target, _path(target, "/frame"), host="evil.example"))
    elif what == "origin_frame":
        status = _status(_get(target, _path(target, "/frame"), headers={"Origin": evil}))
    elif what == "origin_ws":
        sock, status = _ws_handshake(target, origin=evil)
        if sock is not None:
            sock.close()
    elif what == "host_and_origin":
        sock, status = _ws_handshake(target, origin=evil, host="evil.example:80")
        if sock is not None:
            sock.close()
    elif what == "no_token":
        status = _status(_get(target, _path(target, "/frame", token=False)))
    else:
        query = {key: ("0" * 32 if "token" in key else value)
                 for key, value in target.query.items()} or {"token": "0" * 32}
        status = _status(_get(target, "/frame?" + urlencode(query)))
    if status is not None and status >= 500:
        return "internal_error", f"HTTP {status}"
    served = status is not None and status < 400
    if not served:
        return "refused", f"HTTP {status}"
    if target.has_token:
        return "served_foreign", f"{what}: HTTP {status} with the token feature present"
    return "served", f"HTTP {status} (the server has no token feature)"


def check_live_case(case: Case, target: LiveTarget) -> Outcome:
    """Run one case against the running server; then check it still answers and wrote no
    traceback."""
    started = time.perf_counter()
    try:
        status, detail = _run(case, target)
    except OSError as exc:
        status, detail = "refused", f"connection ended: {type(exc).__name__}"
    time.sleep(0.05)  # let the server log what the case did
    alive = _status(_get(target, _path(target, "/frame")))
    errors = target.new_errors()
    seconds = time.perf_counter() - started
    if "Traceback" in errors or "internal error" in errors or "Error handling" in errors:
        lines = [line for line in errors.splitlines() if "Error" in line or "error" in line]
        return Outcome(case, "internal_error", False,
                       f"{detail}; the server wrote: {(lines or [''])[-1][:200]}", seconds)
    if alive != 200:
        return Outcome(case, "unexpected", False,
                       f"{detail}; the server stopped answering (HTTP {alive})", seconds)
    ok = status in ("refused", "served")
    return Outcome(case, status, ok, detail, seconds)
