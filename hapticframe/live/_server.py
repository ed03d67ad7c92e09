"""The live page's server: aiohttp on 127.0.0.1, in a daemon thread with its own event loop.

The page (``static/``: plain HTML, CSS and JavaScript, nothing fetched from elsewhere) opens
a websocket on ``/ws`` and gets a frame (see :class:`~hapticframe.live._state.LiveState`)
whenever the picture has changed, at most :attr:`LiveServer.rate_hz` times a second. A
live feed drains the run's :class:`~hapticframe.live._state.MessageQueue` in the server's
thread; a recording's feed answers the slider's ``{"t_s": ...}`` messages.
"""

from __future__ import annotations

import asyncio
import json
import logging
import math
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from hapticframe._defaults import LIVE_PORT
from hapticframe._errors import UsageError
from hapticframe.live._state import LiveState, MessageQueue, RecordingTimeline

if TYPE_CHECKING:
    from aiohttp import web

__all__ = ["LiveFeed", "LiveServer", "TimelineFeed"]

_log = logging.getLogger("hapticframe.live")

STATIC = Path(__file__).parent / "static"


class _MalformedRequests(logging.Filter):
    """Drops aiohttp's record of a malformed request (a bad request line, version or
    header): the client has its 400 already, and the person at the terminal must not get
    a traceback for whatever a port scanner sends. A handler's own error still shows."""

    def filter(self, record: logging.LogRecord) -> bool:
        from aiohttp.http_exceptions import HttpProcessingError

        error = record.exc_info[1] if record.exc_info else None
        return not isinstance(error, HttpProcessingError)


_MALFORMED = _MalformedRequests()
#: The default port of ``--live`` and ``view`` (its home: hapticframe._defaults).
DEFAULT_PORT = LIVE_PORT


class Feed(Protocol):
    """Where a page's frames come from."""

    mode: str

    def frame(self, t_s: float | None) -> tuple[int, dict[str, Any]]:
        """``(version, frame)``: the picture at ``t_s`` (None: now, or the start)."""
        ...


class LiveFeed:
    """A running run's picture: its recording's listener is :meth:`listener`."""

    mode = "live"

    def __init__(self, maxlen: int = 20000, preferred_map: str | None = None) -> None:
        self.queue = MessageQueue(maxlen)
        self.state = LiveState()
        self.state.preferred_map = preferred_map

    @property
    def listener(self) -> Any:
        """The recording listener (``fn(topic, t_s, data)``); put it on the run's recording."""
        return self.queue.put

    def end(self, status: str, metrics: Any = None, reason: str = "") -> None:
        """Tell the page that the run has ended (from any thread): ``status`` ``ok``,
        ``failed`` or ``interrupted``, the final ``metrics``, and why when it failed."""
        from hapticframe.live._state import END_TOPIC

        self.queue.put(END_TOPIC, math.nan, {"status": status, "metrics": metrics,
                                             "reason": reason})

    def pump(self) -> None:
        """Fold what the run has written since (the server does so even with no page open,
        so that the queue does not overflow)."""
        messages = self.queue.drain()
        if messages:
            self.state.fold_all(messages)
        if self.queue.dropped != self.state.dropped:
            self.state.dropped = self.queue.dropped
            self.state.version += 1

    def frame(self, t_s: float | None) -> tuple[int, dict[str, Any]]:
        self.pump()
        return self.state.version, self.state.frame()


class TimelineFeed:
    """A recording's picture at the slider's time."""

    mode = "view"

    def __init__(self, timeline: RecordingTimeline, name: str = "") -> None:
        self.timeline = timeline
        self.name = name
        self._versions: dict[float, int] = {}

    def frame(self, t_s: float | None) -> tuple[int, dict[str, Any]]:
        when = self.timeline.end_s if t_s is None else float(t_s)
        state = self.timeline.state_at(when)
        frame = self.timeline.frame_at(when)
        frame["name"] = self.name
        # A new time is a new frame even when nothing happened between the two times.
        return hash((state.version, when)) & 0x7FFFFFFF, frame


class LiveServer:
    """Serves the page for ``feed`` on ``http://host:port/`` from a daemon thread.

    Parameters
    ----------
    feed : LiveFeed or TimelineFeed
    host : str
        127.0.0.1 unless asked otherwise: the page is for the person at the machine.
    port : int
        0 picks a free port (see :attr:`port` once started).
    rate_hz : float
        The most frames a second each page gets (a frame goes only when it changed). 15
        asked gives the page 5-8 while the run's thread holds the GIL most of the time, and
        keeps a page rendering on the same 2 cores within the loop's 10 % (20 cost it 10-11 %;
        measured: docs/benchmarks.md, "The live view").
    """

    def __init__(self, feed: Feed, host: str = "127.0.0.1", port: int = DEFAULT_PORT,
                 rate_hz: float = 15.0) -> None:
        self.feed = feed
        self.host = host
        self.port = port
        self.rate_hz = rate_hz
        self.frames_sent = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._runner: web.AppRunner | None = None
        self._thread: threading.Thread | None = None
        self._started = threading.Event()
        self._error: BaseException | None = None
        self._stopping: asyncio.Event | None = None
        self._sockets: set[web.WebSocketResponse] = set()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}/"

    # --- life cycle --------------------------------------------------------------------------

    def start(self, timeout_s: float = 10.0) -> str:
        """Start serving; returns the page's address.

        Raises
        ------
        UsageError
            When aiohttp is missing or the port cannot be bound (exit status 2).
        """
        try:
            import aiohttp  # noqa: F401
        except ImportError as exc:
            raise UsageError("the live view needs aiohttp: pip install 'hapticframe[live]'") \
                from exc
        self._thread = threading.Thread(target=self._serve, name="hapticframe-live",
                                        daemon=True)
        self._thread.start()
        if not self._started.wait(timeout_s):
            raise UsageError(f"the live view did not start within {timeout_s:g} s")
        if self._error is not None:
            error = self._error
            raise UsageError(f"the live view cannot listen on {self.host}:{self.port}: "
                             f"{getattr(error, 'strerror', None) or error}; choose another "
                             "--port (0 picks a free one)") from error
        return self.url

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop serving (idempotent)."""
        loop, stopping = self._loop, self._stopping
        if loop is not None and stopping is not None and not loop.is_closed():
            try:
                loop.call_soon_threadsafe(stopping.set)
            except RuntimeError:  # the loop has closed meanwhile
                pass
        if self._thread is not None:
            self._thread.join(timeout_s)
            self._thread = None

    def __enter__(self) -> LiveServer:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _serve(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._main())
        except BaseException as exc:  # reported by start() when it happens while starting
            if not self._started.is_set():
                self._error = exc
                self._started.set()
            else:
                _log.warning("the live view stopped: %s: %s", type(exc).__name__, exc)
        finally:
            loop.close()

    async def _main(self) -> None:
        from aiohttp import web

        self._stopping = asyncio.Event()
        logging.getLogger("aiohttp.server").addFilter(_MALFORMED)  # once: a set of filters
        app = web.Application()
        app.router.add_get("/", self._index)
        app.router.add_get("/frame", self._frame)
        app.router.add_get("/ws", self._websocket)
        app.router.add_static("/static/", STATIC, show_index=False)
        runner = web.AppRunner(app, access_log=None, handle_signals=False)
        await runner.setup()
        self._runner = runner
        site = web.TCPSite(runner, self.host, self.port)
        try:
            await site.start()
        except BaseException:
            await runner.cleanup()
            raise
        server = getattr(site, "_server", None)
        sockets = getattr(server, "sockets", None) or []
        if sockets:
            self.port = int(sockets[0].getsockname()[1])
        self._started.set()
        pump = getattr(self.feed, "pump", None)
        try:
            while not self._stopping.is_set():
                if pump is not None:
                    pump()
                try:
                    await asyncio.wait_for(self._stopping.wait(), 0.2)
                except asyncio.TimeoutError:
                    pass
        finally:
            for ws in list(self._sockets):  # open pages would hold the shutdown up
                await ws.close()
            await runner.cleanup()

    # --- handlers ----------------------------------------------------------------------------

    async def _index(self, request: web.Request) -> web.StreamResponse:
        from aiohttp import web

        return web.FileResponse(STATIC / "index.html",
                                headers={"Cache-Control": "no-store"})

    async def _frame(self, request: web.Request) -> web.StreamResponse:
        """One frame as JSON (``?t_s=`` for a recording): for scripts and tests."""
        from aiohttp import web

        raw = request.query.get("t_s")
        try:
            t_s = None if raw is None else float(raw)
        except ValueError:
            raise web.HTTPBadRequest(text=f"t_s={raw!r} is not a number") from None
        _, frame = self.feed.frame(t_s)
        return web.json_response({"mode": self.feed.mode, **frame})

    async def _websocket(self, request: web.Request) -> web.StreamResponse:
        from aiohttp import WSMsgType, web

        ws = web.WebSocketResponse(heartbeat=10.0)
        await ws.prepare(request)
        self._sockets.add(ws)
        wanted: list[float | None] = [None]

        async def receive() -> None:
            async for message in ws:
                if message.type == WSMsgType.TEXT:
                    try:
                        value = json.loads(message.data).get("t_s")
                        wanted[0] = None if value is None else float(value)
                    except (ValueError, TypeError, AttributeError):
                        continue

        reader = asyncio.ensure_future(receive())
        sent = None
        period = 1.0 / self.rate_hz
        try:
            while not ws.closed and not reader.done():
                key, frame = self.feed.frame(wanted[0])
                if key != sent:
                    await ws.send_str(json.dumps({"mode": self.feed.mode, **frame},
                                                 separators=(",", ":")))
                    self.frames_sent += 1
                    sent = key
                await asyncio.sleep(period)
        except (ConnectionError, RuntimeError):
            pass  # the page went away
        finally:
            self._sockets.discard(ws)
            reader.cancel()
            await ws.close()
        return ws
