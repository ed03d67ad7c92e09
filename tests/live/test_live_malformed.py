"""A malformed request to the live server is answered 400 and leaves no traceback (issue 26
§5; found by ``hapticframe bench fuzz``, family ``live``: aiohttp logged "Error handling
request" with a traceback for every bad request line, on the user's terminal)."""

from __future__ import annotations

import logging
import socket

import pytest

pytest.importorskip("aiohttp")

from hapticframe.live import LiveFeed, LiveServer


def _exchange(port: int, raw: bytes) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
        sock.sendall(raw)
        reply = b""
        while b"\r\n\r\n" not in reply:
            chunk = sock.recv(4096)
            if not chunk:
                break
            reply += chunk
        return reply


@pytest.mark.parametrize("raw", [
    b"GET /frame HTTP/9.9\r\nHost: 127.0.0.1\r\n\r\n",
    b"GET /frame HTTP/1.1\r\nno colon\r\n\r\n",
    b"GET /" + b"a" * 100_000 + b" HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
])
def test_a_malformed_request_is_refused_without_a_traceback(
        raw: bytes, caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.DEBUG), LiveServer(LiveFeed(), port=0) as server:
        assert _exchange(server.port, raw).split(b" ")[1] == b"400"
        token = getattr(server, "token", None)  # the session's token, where the server has one
        query = f"?token={token}" if token else ""
        ok = _exchange(server.port, f"GET /frame{query} HTTP/1.1\r\nHost: 127.0.0.1:"
                       f"{server.port}\r\nConnection: close\r\n\r\n".encode())
        assert ok.startswith(b"HTTP/1.1 200")
    shown = [r for r in caplog.records if r.exc_info or "Error handling" in r.getMessage()]
    assert not shown, [r.getMessage() for r in shown]
