"""The live view: a local page that shows a run as it runs (``hapticframe run --live``) or
a recording at any time (``hapticframe view DIR``).

The run's recording (:class:`~hapticframe.record._recording.RunRecording`) tells a listener every
message it writes; the listener only appends to a bounded queue that drops its oldest
message when full, so the run never waits for the page. An aiohttp server in a daemon thread
folds the queue into the latest picture and sends it over a websocket to the page (plain
HTML, CSS and JavaScript served from this package; nothing is fetched from elsewhere).
See docs/recording.md, "Live view", and docs/architecture.md for why aiohttp.
"""

from __future__ import annotations

from hapticframe.live._server import DEFAULT_PORT, LiveFeed, LiveServer, TimelineFeed
from hapticframe.live._session import evaluated_map, run_live
from hapticframe.live._state import LiveState, MessageQueue, RecordingTimeline, decode_grid

__all__ = [
    "DEFAULT_PORT",
    "LiveFeed",
    "LiveServer",
    "LiveState",
    "MessageQueue",
    "RecordingTimeline",
    "TimelineFeed",
    "decode_grid",
    "evaluated_map",
    "run_live",
]
