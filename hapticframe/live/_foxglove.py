"""``hapticframe run --foxglove``: the run served over Foxglove's WebSocket protocol.

A :class:`FoxgloveBridge` is a recording listener (:func:`hapticframe.record._recording.
listening`, the hook ``run --live`` uses too): every message the run writes into
``run.mcap`` is logged, as it is written, on a channel of the same topic, schema and
encoding in a WebSocket server of the ``foxglove-sdk`` package on 127.0.0.1. Each topic's
channel and schema come from the channel table (:func:`hapticframe.run._channels.
check_topic`) and the JSON schemas the recording registers
(:data:`hapticframe.record._recording.SCHEMAS`): there is no second list, and Foxglove shows
a live run with the panels and layouts it uses for the recording afterwards.

The run never waits for it: a message is encoded only while some client subscribes to its
channel (``Channel.has_sinks``, a flag read without a lock on the SDK's side), and the SDK's
server sends from its own threads with a bounded backlog per client, dropping a slow
client's oldest messages. A channel is advertised when its topic's first message is written,
so a client sees a topic from then on (the start's ``/scene`` only if it connected before).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

from hapticframe._defaults import FOXGLOVE_PORT
from hapticframe._errors import UsageError

__all__ = ["DEFAULT_FOXGLOVE_PORT", "FOXGLOVE_EXTRA", "FoxgloveBridge"]

#: Foxglove's own default port for a WebSocket connection.
DEFAULT_FOXGLOVE_PORT = FOXGLOVE_PORT
#: What to install for ``--foxglove``.
FOXGLOVE_EXTRA = "pip install 'hapticframe[foxglove]' (the foxglove-sdk package)"


class FoxgloveBridge:
    """A Foxglove WebSocket server on ``host:port`` fed with a run's recording.

    Parameters
    ----------
    port : int
        The server's port; 0 takes any free port (:attr:`port` says which).
    host : str
        127.0.0.1 by default: the run's data stay on this machine.
    backlog : int
        Messages the server keeps per client before it drops the oldest.

    Raises
    ------
    UsageError
        Without the ``foxglove-sdk`` package, or when the port cannot be opened (exit 2).
    """

    def __init__(self, port: int = DEFAULT_FOXGLOVE_PORT, host: str = "127.0.0.1",
                 backlog: int = 1024) -> None:
        try:
            import foxglove
        except ImportError as exc:
            raise UsageError(f"--foxglove needs the foxglove-sdk package: {FOXGLOVE_EXTRA}"
                             ) from exc
        self._foxglove: Any = foxglove
        # A context of our own: nothing else in the process logs to this server, and the
        # SDK's global context (which other code may use) does not see the run.
        self._context = foxglove.Context()
        try:
            self._server = foxglove.start_server(
                name="hapticframe", host=host, port=port, context=self._context,
                message_backlog_size=backlog)
        except Exception as exc:  # the SDK raises RuntimeError("FoxgloveError: ...")
            reason = str(exc).removeprefix("FoxgloveError: ")
            raise UsageError(f"--foxglove: cannot serve on {host}:{port}: {reason} (another "
                             "program has the port? give another one: --foxglove PORT, or 0 "
                             "for any free port)") from exc
        self.host = host
        self._channels: dict[str, Any] = {}
        #: Messages logged to the server (those some client subscribed to).
        self.messages_sent = 0
        self.closed = False

    @property
    def port(self) -> int:
        """The port the server listens on."""
        return int(self._server.port)

    @property
    def url(self) -> str:
        """What Foxglove's "Open connection" → "Foxglove WebSocket" takes."""
        return f"ws://{self.host}:{self.port}"

    #: The recording hands this listener each message's bytes as written (no second
    #: encoding; :meth:`~hapticframe.record._recording.RunRecording.add_listener`).
    wants_payload = True

    def __call__(self, topic: str, t_s: float, data: Mapping[str, Any],
                 payload: bytes | None = None) -> None:
        """The recording listener: log the message (``payload``, the bytes ``run.mcap``
        holds, else ``data`` encoded as the recording encodes it) on ``topic``'s channel,
        advertised on first use, when a client subscribes to it; else return at once."""
        channel = self._channels.get(topic)
        if channel is None:
            channel = self.advertise(topic)
        if not channel.has_sinks():
            return  # nobody subscribes: no encoding, no cost
        if payload is None:
            from hapticframe.record._recording import encode_message

            payload = encode_message(data)
        channel.log(payload, log_time=round(max(t_s, 0.0) * 1e9))
        self.messages_sent += 1

    def advertise(self, topic: str) -> Any:
        """Advertise ``topic``'s channel now (the listener does it at its first message);
        returns the SDK's channel. Raises ``ChannelError`` for a topic outside the table."""
        from hapticframe.record._recording import SCHEMAS
        from hapticframe.run._channels import ChannelError, channel_of

        channel = self._channels.get(topic)
        if channel is not None:
            return channel
        table = channel_of(topic)
        if table is None:
            raise ChannelError(f"topic {topic!r} is in no channel of the table "
                               "(hapticframe.run._channels.CHANNELS)")
        schema = self._foxglove.Schema(name=table.schema, encoding="jsonschema",
                                       data=json.dumps(SCHEMAS[table.schema]).encode())
        channel = self._channels[topic] = self._foxglove.Channel(
            topic, schema=schema, message_encoding=table.encoding, context=self._context)
        return channel

    def close(self) -> None:
        """Stop the server (clients are disconnected; what they received stays with them);
        idempotent."""
        if self.closed:
            return
        self.closed = True
        for channel in self._channels.values():
            channel.close()
        self._server.stop()

    def __enter__(self) -> FoxgloveBridge:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
