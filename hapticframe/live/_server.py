"""The live page's server: aiohttp on 127.0.0.1, in a daemon thread with its own event loop.

The page (``static/``: plain HTML, CSS and JavaScript, nothing fetched from elsewhere) opens
a websocket on ``/ws`` and gets a frame (see :class:`~hapticframe.live._state.LiveState`)
whenever the picture has changed, at most :attr:`LiveServer.rate_hz` times a second. A
live feed drains the run's :class:`~hapticframe.live._state.MessageQueue` in the server's
thread; a recording's feed answers the slider's ``{"t_s": ...}`` messages, each page at its
own time.

Only the person who started it may read it (:mod:`hapticframe.live._access`: Host, Origin
and the session's token on every request), and no page slows the run: a frame is encoded
once for every page, a page that has not taken the last frame yet misses the next ones, and
one that takes nothing for :attr:`LiveServer.stuck_s` is disconnected. Frames are strict
JSON (a non-finite number is ``null``).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import math
import socket
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from hapticframe._defaults import LIVE_PORT
from hapticframe._errors import UsageError
from hapticframe.live._access import AccessPolicy, new_token
from hapticframe.live._state import LiveState, MessageQueue, RecordingTimeline

if TYPE_CHECKING:
    from aiohttp import web

__all__ = ["LiveFeed", "LiveServer", "TimelineFeed", "strict_json"]

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
#: The kernel's send buffer of a page's connection (Linux doubles it): about one frame.
SEND_BUFFER_BYTES = 64 * 1024
#: Headers on every answer: no other site may frame the page, and its address (with the
#: token) goes nowhere as a referrer.
SECURITY_HEADERS = {
    "Cache-Control": "no-store",
    "Content-Security-Policy": "frame-ancestors 'none'",
    "Referrer-Policy": "no-referrer",
    "X-Content-Type-Options": "nosniff",
    "X-Frame-Options": "DENY",
}


def _finite(value: Any) -> Any:
    """``value`` with every non-finite float as None (JSON has no NaN)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def strict_json(value: Any) -> str:
    """``value`` as compact, strict JSON: NaN and infinities become ``null``."""
    try:
        return json.dumps(value, separators=(",", ":"), allow_nan=False)
    except ValueError:  # rare: walk it only then
        return json.dumps(_finite(value), separators=(",", ":"), allow_nan=False)


class Cursor(Protocol):
    """One page's view of a feed."""

    def frame(self, t_s: float | None) -> tuple[int, dict[str, Any]]:
        """``(key, frame)``: the picture at ``t_s`` (None: now, or the end); the same key
        means the same picture."""
        ...

    def key(self, t_s: float | None) -> int:
        """The key :meth:`frame` would give, without drawing the picture."""
        ...


class Feed(Cursor, Protocol):
    """Where a page's frames come from."""

    mode: str

    def cursor(self) -> Cursor:
        """A position of its own for one page (its slider moves no one else's)."""
        ...

    def time_error(self, t_s: float) -> str | None:
        """Why a page may not ask for time ``t_s`` (finite, a float), or None."""
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

    def key(self, t_s: float | None) -> int:
        self.pump()
        return self.state.version

    def cursor(self) -> LiveFeed:
        """Every page sees the run now: one picture for all."""
        return self

    def time_error(self, t_s: float) -> str | None:
        return None  # a live page has no slider: a time is ignored


class _TimelineCursor:
    """One page's position on a recording's timeline."""

    def __init__(self, feed: TimelineFeed) -> None:
        self.feed = feed
        self.timeline = RecordingTimeline(feed.timeline.messages)

    def frame(self, t_s: float | None) -> tuple[int, dict[str, Any]]:
        when = self.timeline.end_s if t_s is None else float(t_s)
        frame = self.timeline.frame_at(when)
        frame["name"] = self.feed.name
        return self.key(when), frame

    def key(self, t_s: float | None) -> int:
        when = self.timeline.end_s if t_s is None else float(t_s)
        # A new time is a new frame even when nothing happened between the two times.
        return hash((self.timeline.state_at(when).version, when)) & 0x7FFFFFFF


class TimelineFeed:
    """A recording's picture at the slider's time; each page has its own time
    (:meth:`cursor`)."""

    mode = "view"

    def __init__(self, timeline: RecordingTimeline, name: str = "") -> None:
        self.timeline = timeline
        self.name = name
        self._default = _TimelineCursor(self)

    def cursor(self) -> _TimelineCursor:
        return _TimelineCursor(self)

    def frame(self, t_s: float | None) -> tuple[int, dict[str, Any]]:
        """The picture at ``t_s`` (for one-off requests: ``GET /frame``)."""
        return self._default.frame(t_s)

    def key(self, t_s: float | None) -> int:
        return self._default.key(t_s)

    def time_error(self, t_s: float) -> str | None:
        start, end = self.timeline.start_s, self.timeline.end_s
        slack = 1e-9 * max(1.0, abs(start), abs(end))
        if not start - slack <= t_s <= end + slack:
            return f"t_s={t_s!r} is outside the recording ({start:.6g} ... {end:.6g} s)"
        return None


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
    token : str, optional
        The session's token, which every request but the page's files must carry (default:
        a fresh random one; :attr:`url` holds it).
    stuck_s : float
        A page that has not taken a frame sent this long ago is disconnected (until then
        it misses the frames that come meanwhile).
    """

    def __init__(self, feed: Feed, host: str = "127.0.0.1", port: int = DEFAULT_PORT,
                 rate_hz: float = 15.0, *, token: str | None = None,
                 stuck_s: float = 30.0) -> None:
        self.feed = feed
        self.host = host
        self.port = port
        self.rate_hz = rate_hz
        self.token = token or new_token()
        self.stuck_s = stuck_s
        self.frames_sent = 0
        #: Pictures encoded as JSON (once each, however many pages get them).
        self.frames_encoded = 0
        #: Frames a page missed because it had not taken the one before yet.
        self.frames_skipped = 0
        #: Pages disconnected for taking nothing for ``stuck_s``.
        self.pages_dropped = 0
        #: Requests refused (Host, Origin or token), and time values refused.
        self.refused = 0
        self._access: AccessPolicy | None = None
        self._encoded: OrderedDict[int, str] = OrderedDict()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._runner: web.AppRunner | None = None
        self._thread: threading.Thread | None = None
        self._started = threading.Event()
        self._error: BaseException | None = None
        self._stopping: asyncio.Event | None = None
        self._pages: list[_Page] = []

    @property
    def url(self) -> str:
        """The page's address, with the session's token (what the command prints)."""
        return f"http://{self.host}:{self.port}/?token={self.token}"

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

        @web.middleware
        async def guard(request: web.Request, handler: Any) -> web.StreamResponse:
            return await self._guard_request(request, handler)

        app = web.Application(middlewares=[guard])
        app.router.add_get("/", self._index)
        app.router.add_get("/frame", self._frame)
        app.router.add_get("/ws", self._websocket)
        app.router.add_get("/favicon.ico", self._favicon)
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
        self._access = AccessPolicy(self.host, self.port, self.token)
        self._started.set()
        pump = getattr(self.feed, "pump", None)
        try:
            while not self._stopping.is_set():
                if pump is not None:
                    pump()
                self._broadcast()
                try:  # one wake-up a period for all pages, not one per page
                    await asyncio.wait_for(self._stopping.wait(),
                                           1.0 / self.rate_hz if self._pages else 0.2)
                except asyncio.TimeoutError:
                    pass
        finally:
            for page in list(self._pages):  # open pages would hold the shutdown up
                await self._close(page)
            await runner.cleanup()

    # --- sending -----------------------------------------------------------------------------

    def _broadcast(self) -> None:
        """Offer every page what is new for it (:meth:`_offer`)."""
        now = time.monotonic()
        for page in list(self._pages):
            self._offer(page, now)

    def _offer(self, page: _Page, now: float) -> None:
        """Start sending ``page`` what is new for it, unless it has not taken the last frame
        yet (then it misses this one; after ``stuck_s`` of that it is dropped)."""
        transport = page.transport
        if page.ws.closed or transport is None or transport.is_closing():
            return
        sending = page.sending is not None and not page.sending.done()
        if sending or transport.get_write_buffer_size() > 0:
            page.waiting_since = page.waiting_since or now
            if now - page.waiting_since > self.stuck_s:
                self._drop(page)
                return
            key = page.cursor.key(page.wanted)  # no picture drawn for a page that waits
            if key != page.sent and key != page.skipped:
                page.skipped = key
                self.frames_skipped += 1
            return
        page.waiting_since = None
        if page.replies:
            text = strict_json({"error": page.replies.pop(0)})
        else:
            key, frame = page.cursor.frame(page.wanted)
            if key == page.sent:
                return
            text, page.sent = self._encode(key, frame), key
            self.frames_sent += 1
        page.sending = asyncio.ensure_future(self._deliver(page.ws, text))

    @staticmethod
    async def _deliver(ws: web.WebSocketResponse, text: str) -> None:
        try:
            await ws.send_str(text)
        except (ConnectionError, RuntimeError):
            pass  # the page went away: its handler ends

    def _drop(self, page: _Page) -> None:
        """Disconnect a page that takes nothing (it would not answer a closing handshake
        either)."""
        self.pages_dropped += 1
        _log.warning("live view: a page took no frame for %g s; disconnected it", self.stuck_s)
        if page.sending is not None:
            page.sending.cancel()
        if page.transport is not None:
            page.transport.abort()

    async def _close(self, page: _Page) -> None:
        if page.sending is not None:
            page.sending.cancel()
        if page.transport is None or page.transport.is_closing():
            return
        try:
            await asyncio.wait_for(page.ws.close(), 2.0)
        except (asyncio.TimeoutError, ConnectionError, RuntimeError):
            page.transport.abort()

    # --- handlers ----------------------------------------------------------------------------

    async def _guard_request(self, request: web.Request, handler: Any) -> web.StreamResponse:
        from aiohttp import web

        access = self._access
        refusal = "the server is starting" if access is None else access.refusal(
            request.path, request.query, request.headers)
        if refusal is not None:
            self.refused += 1
            _log.warning("live view: refused %s %s: %s", request.method, request.path, refusal)
            return web.Response(status=403, text=refusal + "\n", headers=SECURITY_HEADERS)
        response: web.StreamResponse = await handler(request)
        if not response.prepared:  # a websocket has sent its headers already
            response.headers.update(SECURITY_HEADERS)
        return response

    def _parse_time(self, raw: Any) -> tuple[float | None, str | None]:
        """``(t_s, None)`` for a time a page may ask for (None: now), else ``(None, why)``."""
        if raw is None:
            return None, None
        if isinstance(raw, bool) or not isinstance(raw, (int, float, str)):
            return None, f"t_s={raw!r} is not a number"
        try:
            value = float(raw)
        except ValueError:
            return None, f"t_s={raw!r} is not a number"
        if not math.isfinite(value):
            return None, f"t_s={raw!r} is not a finite number"
        error = self.feed.time_error(value)
        return (None, error) if error else (value, None)

    def _encode(self, key: int, frame: dict[str, Any]) -> str:
        """The frame as the JSON text every page gets, encoded once per picture."""
        text = self._encoded.get(key)
        if text is None:
            text = strict_json({"mode": self.feed.mode, **frame})
            self.frames_encoded += 1
            self._encoded[key] = text
            while len(self._encoded) > 16:
                self._encoded.popitem(last=False)
        else:
            self._encoded.move_to_end(key)
        return text

    async def _favicon(self, request: web.Request) -> web.StreamResponse:
        """No icon: 204, so that a browser's own request is neither refused nor logged."""
        from aiohttp import web

        return web.Response(status=204)

    async def _index(self, request: web.Request) -> web.StreamResponse:
        from aiohttp import web

        return web.FileResponse(STATIC / "index.html")

    async def _frame(self, request: web.Request) -> web.StreamResponse:
        """One frame as JSON (``?t_s=`` for a recording): for scripts and tests."""
        from aiohttp import web

        t_s, error = self._parse_time(request.query.get("t_s"))
        if error is not None:
            self.refused += 1
            raise web.HTTPBadRequest(text=error + "\n")
        key, frame = self.feed.frame(t_s)
        return web.Response(text=self._encode(key, frame), content_type="application/json")

    async def _websocket(self, request: web.Request) -> web.StreamResponse:
        """A page's websocket: frames go out from :meth:`_broadcast`; this reads what the
        page asks (``{"t_s": ...}``) until it goes."""
        from aiohttp import WSMsgType, web

        # No compression: on 127.0.0.1 it would only cost the run's CPU, once per page.
        ws = web.WebSocketResponse(heartbeat=10.0, compress=False)
        await ws.prepare(request)
        transport = request.transport
        connection = None if transport is None else transport.get_extra_info("socket")
        if connection is not None:
            # A bounded send buffer: a page that stops reading shows within a frame or two
            # (and costs the kernel little) instead of after megabytes.
            with contextlib.suppress(OSError):
                connection.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER_BYTES)
        page = _Page(ws, transport, self.feed.cursor())
        self._pages.append(page)
        self._offer(page, time.monotonic())  # the picture now, before anything is asked
        try:
            async for message in ws:
                if message.type == WSMsgType.TEXT:
                    self._asked(page, message.data)
        except (ConnectionError, RuntimeError):
            pass  # the page went away
        finally:
            if page in self._pages:
                self._pages.remove(page)
            await self._close(page)
        return ws

    def _asked(self, page: _Page, data: str) -> None:
        """A page's message: a time to show (refused ones are answered to that page)."""
        try:
            asked = json.loads(data)
        except ValueError:
            page.replies.append("a message that is not JSON")
            return
        if not isinstance(asked, dict) or "t_s" not in asked:
            page.replies.append('a message without "t_s"')
            return
        value, error = self._parse_time(asked["t_s"])
        if error is not None:  # this page's time stays where it was
            self.refused += 1
            page.replies.append(error)
        else:
            page.wanted = value


@dataclass(eq=False)
class _Page:
    """One open page: its websocket, its position, what it was sent."""

    ws: web.WebSocketResponse
    transport: asyncio.Transport | None
    cursor: Cursor
    wanted: float | None = None
    sent: int | None = None
    skipped: int | None = None
    sending: asyncio.Future[None] | None = None
    waiting_since: float | None = None
    replies: list[str] = field(default_factory=list)
