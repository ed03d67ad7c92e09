"""The host side of the puck protocol: what the ``barrett-hand`` robot and the ``barrett-wam``
backend are built on.

:class:`PuckHost` talks to pucks over any python-can bus: it wakes them (``STAT``), reads
``VERS`` and selects each puck's property table, gets and sets properties by name with a
bounded wait per reply, and polls positions by group, reporting the pucks that did not
answer. :class:`BarrettHandHost` adds the BarrettHand's commands.

Every wait is bounded on the host's clock (``reply_timeout_s`` per reply, ``attempts`` per
request), and everything that went wrong is counted in a :class:`DeviceHealth`:

============================  ===================================================
``timeouts``                  a property reply that did not come in time
``invalid_samples``           a malformed reply (bit 7 clear, byte 1 not 0, bad length)
``dropped_samples``           a puck missing from a group position poll
``resyncs``                   frames discarded: late, duplicated or unexpected replies
``crc_errors``                CAN error frames (protocol errors on the wire)
``stalls`` / ``reconnects``   the bus went off / came back (error-frame flags)
``overflows``                 a wait ended because too many unrelated frames arrived
``frames`` / ``bytes``        replies accepted
============================  ===================================================

Stale input is discarded before each request (a reply that arrives after its timeout is
never taken as the answer to a later request that has already been answered), and a puck
that answers a position poll twice is reported missing rather than trusted: the protocol
has no sequence numbers, so one of the two values could be old.

Pacing: the host is handed a :class:`~._bus.CanPort`, which decides how a wait lets time
pass (a real ``bus.recv`` up to the deadline on a live channel; staged fake-clock steps on an
emulated one, so that no real time is spent). The host's code path is the same for both.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import can

from hapticframe.devices import DeviceError, DeviceHealth

from ._bus import CanPort
from ._protocol import (
    CAN_ERR_BUSOFF,
    CAN_ERR_RESTARTED,
    COMMON_TABLE,
    HAND_NODES,
    Cmd,
    Group,
    Mode,
    PropertyTable,
    ProtocolError,
    Stat,
    UnsupportedFirmware,
    decode_position,
    decode_property_reply,
    encode_get,
    encode_set,
    group_id,
    node_id,
    parse_id,
    property_table,
)

__all__ = [
    "BarrettError",
    "BarrettHandHost",
    "MalformedReply",
    "MoveResult",
    "PositionPoll",
    "PuckHost",
    "ReplyTimeout",
    "WakeResult",
]


class BarrettError(DeviceError):
    """The pucks cannot go on (a bus failure, pucks that did not wake, a move that did not
    end in time)."""


class ReplyTimeout(BarrettError):
    """A property reply that did not come within its bound, on every attempt."""


class MalformedReply(BarrettError):
    """A property reply that does not decode, on every attempt."""


@dataclass(frozen=True)
class WakeResult:
    """Which pucks woke (``STAT`` read READY) and which did not."""

    awake: tuple[int, ...]
    failed: tuple[int, ...]

    @property
    def ok(self) -> bool:
        return not self.failed


@dataclass(frozen=True)
class PositionPoll:
    """One group position poll.

    Attributes
    ----------
    time_s : float
        Host clock time of the request.
    positions : mapping of int to int
        Counts of the pucks that answered this poll (and only those).
    secondary : mapping of int to int
        Secondary-encoder counts, for pucks that sent them.
    missing : tuple of int
        Pucks that did not answer, answered twice, or answered garbage: no value for them.
    """

    time_s: float
    positions: Mapping[int, int]
    secondary: Mapping[int, int]
    missing: tuple[int, ...]

    @property
    def complete(self) -> bool:
        return not self.missing


@dataclass(frozen=True)
class MoveResult:
    """How a hand move ended.

    Attributes
    ----------
    modes : mapping of int to int
        Each puck's last MODE.
    poll : PositionPoll
        Positions read after the move.
    reached : mapping of int to bool
        Within tolerance of its target (False when its position is missing).
    stopped_early : tuple of int
        Pucks that reported done-moving away from their target (an E-stop, an obstacle).
    """

    modes: Mapping[int, int]
    poll: PositionPoll
    reached: Mapping[int, bool]
    stopped_early: tuple[int, ...] = field(default=())

    @property
    def ok(self) -> bool:
        return all(self.reached.values())


class _Reply:
    __slots__ = ("error", "value")

    def __init__(self) -> None:
        self.value: int | None = None
        self.error: ProtocolError | None = None

    def answered(self) -> bool:
        return self.value is not None or self.error is not None


class PuckHost:
    """Property access and position polls over one CAN bus.

    Parameters
    ----------
    bus : can.BusABC
        The host's bus (``can.Bus(interface="socketcan", channel="can0")`` on a real WAM;
        ``interface="virtual"`` with a :class:`PuckBus` on the same channel in tests).
    port : CanPort
        The channel's port: its clock is the host's time base, and it decides how a wait
        lets time pass (:class:`~._bus.PacedCanPort` for emulated pucks).
    health : DeviceHealth or None
        Where the counters go (a new one by default).
    reply_timeout_s : float
        Bound on the wait for each reply (libbarrett waits 1 s).
    attempts : int
        Requests per property read before giving up.
    wake_time_s : float
        Time given to pucks after ``STAT=READY`` (libbarrett's WAKE_UP_TIME, 1 s).
    max_frames_per_wait : int
        Frames one wait may consume before it gives up (a flooded bus).
    device_id : str
        Named in errors.

    Attributes
    ----------
    tables : dict of int to PropertyTable
        Each identified puck's table.
    stats : dict of str to int
        Finer counts than ``health``: ``timeouts``, ``malformed``, ``stale``,
        ``missing_positions``, ``error_frames``, ``bus_off``, ``restarted``, ``overflows``.
    bus_off : bool
        An error frame said the bus went off and none has said it came back.
    """

    def __init__(
        self,
        bus: can.BusABC,
        *,
        port: CanPort,
        health: DeviceHealth | None = None,
        reply_timeout_s: float = 0.1,
        attempts: int = 2,
        wake_time_s: float = 1.0,
        max_frames_per_wait: int = 256,
        device_id: str = "barrett",
    ) -> None:
        if attempts < 1:
            raise ValueError("attempts must be at least 1")
        if not reply_timeout_s > 0:
            raise ValueError("reply_timeout_s must be positive")
        self.bus = bus
        self.port = port
        self.clock = port.clock
        self.health = health if health is not None else DeviceHealth()
        self.reply_timeout_s = reply_timeout_s
        self.attempts = attempts
        self.wake_time_s = wake_time_s
        self.max_frames_per_wait = max_frames_per_wait
        self.device_id = device_id
        self.tables: dict[int, PropertyTable] = {}
        self.stats: dict[str, int] = dict.fromkeys(
            ("timeouts", "malformed", "stale", "missing_positions", "error_frames", "bus_off",
             "restarted", "overflows"), 0)
        self.bus_off = False

    # ----------------------------------------------------------------------------- raw frames

    def _error(self, message: str) -> BarrettError:
        return BarrettError(f"{self.device_id}: {message}", device_id=self.device_id)

    def _send(self, arbitration_id: int, data: bytes) -> None:
        try:
            self.bus.send(can.Message(arbitration_id=arbitration_id, data=data,
                                      is_extended_id=False))
        except can.CanError as exc:
            raise self._error(f"CAN send failed: {exc}") from exc

    def _recv(self, timeout_s: float) -> can.Message | None:
        try:
            return self.bus.recv(timeout=max(0.0, timeout_s))
        except can.CanError as exc:
            raise self._error(f"CAN receive failed: {exc}") from exc

    def _on_error_frame(self, msg: can.Message) -> None:
        self.stats["error_frames"] += 1
        flags = msg.arbitration_id
        if flags & CAN_ERR_BUSOFF:
            self.stats["bus_off"] += 1
            self.health.stalls += 1
            self.bus_off = True
        elif flags & CAN_ERR_RESTARTED:
            self.stats["restarted"] += 1
            self.health.reconnects += 1
            self.bus_off = False
        else:
            self.health.crc_errors += 1

    def _dispatch(self, msg: can.Message, accept: Callable[[can.Message], bool] | None) -> None:
        if msg.is_error_frame:
            self._on_error_frame(msg)
            return
        if accept is not None and accept(msg):
            self.health.frames += 1
            self.health.bytes += len(msg.data)
            return
        self.stats["stale"] += 1
        self.health.resyncs += 1

    def _drain(self) -> None:
        """Discard what arrived before a request (late or duplicated replies), counting it."""
        for _ in range(self.max_frames_per_wait):
            msg = self._recv(0.0)
            if msg is None:
                return
            self._dispatch(msg, None)
        self.stats["overflows"] += 1
        self.health.overflows += 1

    def _collect(
        self, accept: Callable[[can.Message], bool], done: Callable[[], bool], timeout_s: float
    ) -> bool:
        """Feed frames to ``accept`` until ``done()`` or the deadline; True when done."""
        if done():
            return True
        frames = 0
        for msg in self.port.frames(self._recv, self.clock.now() + timeout_s):
            frames += 1
            if frames > self.max_frames_per_wait:
                self.stats["overflows"] += 1
                self.health.overflows += 1
                return done()
            self._dispatch(msg, accept)
            if done():
                return True
        return done()

    # ----------------------------------------------------------------------------- properties

    def table_for(self, node: int, name: str) -> PropertyTable:
        """The table that gives ``name``'s number on ``node``.

        Raises
        ------
        BarrettError
            When the puck's VERS has not been read and ``name`` is not one of the properties
            common to every firmware.
        """
        table = self.tables.get(node)
        if table is not None:
            return table
        if name in COMMON_TABLE:
            return COMMON_TABLE
        raise self._error(f"puck {node}: read VERS (identify) before using {name}")

    def _number(self, nodes: Iterable[int], name: str) -> int:
        numbers = {self.table_for(node, name)[name] for node in nodes}
        if len(numbers) != 1:
            raise self._error(f"property {name} has different numbers on these pucks: {numbers}")
        return numbers.pop()

    def get(self, node: int, name: str, *, timeout_s: float | None = None,
            attempts: int | None = None) -> int:
        """Read a property of one puck.

        Raises
        ------
        ReplyTimeout, MalformedReply
            When no attempt got a valid reply in time (each failure is counted).
        """
        if name in ("P", "JP"):
            raise ValueError("positions come in the position format: use poll_positions()")
        prop = self._number((node,), name)
        timeout = self.reply_timeout_s if timeout_s is None else timeout_s
        last: BarrettError | None = None
        reply_id = group_id(node, int(Group.PROPERTY))
        for _ in range(self.attempts if attempts is None else attempts):
            self._drain()
            self._send(node_id(0, node), encode_get(prop))
            reply = _Reply()

            def accept(msg: can.Message, reply: _Reply = reply) -> bool:
                if msg.arbitration_id != reply_id:
                    return False
                try:
                    decoded = decode_property_reply(msg.data)
                except ProtocolError as exc:
                    reply.error = exc
                    return True
                if decoded.prop != prop:  # an old reply to another request
                    return False
                reply.value = decoded.value
                return True

            self._collect(accept, reply.answered, timeout)
            if reply.value is not None:
                return reply.value
            if reply.error is not None:
                self.stats["malformed"] += 1
                self.health.invalid_samples += 1
                last = MalformedReply(f"{self.device_id}: puck {node} {name}: {reply.error}",
                                      device_id=self.device_id)
            else:
                self.stats["timeouts"] += 1
                self.health.timeouts += 1
                last = ReplyTimeout(f"{self.device_id}: puck {node} did not answer GET {name} "
                                    f"within {timeout:g} s", device_id=self.device_id)
        assert last is not None
        raise last

    def try_get(self, node: int, name: str, **kwargs: float | int | None) -> int | None:
        """:meth:`get`, or None when no valid reply came (the failure is still counted)."""
        try:
            return self.get(node, name, **kwargs)  # type: ignore[arg-type]
        except (ReplyTimeout, MalformedReply):
            return None

    def set(self, node: int, name: str, value: int) -> None:
        """Set a property of one puck (pucks do not acknowledge a SET)."""
        self._send(node_id(0, node), encode_set(self._number((node,), name), value))

    def set_group(self, group: int, nodes: Sequence[int], name: str, value: int) -> None:
        """Set a property on every puck of a group (``nodes``: its members, whose tables must
        agree on the property's number)."""
        self._send(group_id(0, group), encode_set(self._number(nodes, name), value))

    # ------------------------------------------------------------------- waking, identifying

    def wake(self, nodes: Sequence[int], *, attempts: int = 2) -> WakeResult:
        """Set ``STAT=READY`` on each puck, wait ``wake_time_s``, confirm ``STAT``; pucks that
        did not wake are tried again, ``attempts`` times in all."""
        pending = list(nodes)
        awake: list[int] = []
        for _ in range(attempts):
            for node in pending:
                self.set(node, "STAT", int(Stat.READY))
            self.port.elapse(self.wake_time_s)
            still: list[int] = []
            for node in pending:
                stat = self.try_get(node, "STAT", attempts=1)
                (awake if stat == int(Stat.READY) else still).append(node)
            pending = still
            if not pending:
                break
        return WakeResult(tuple(sorted(awake)), tuple(pending))

    def identify(self, nodes: Sequence[int]) -> dict[int, PropertyTable]:
        """Read each puck's VERS and select its property table.

        Raises
        ------
        BarrettError
            For a puck that does not answer or runs firmware without a table here.
        """
        for node in nodes:
            try:
                vers = self.get(node, "VERS")
                self.tables[node] = property_table(vers)
            except UnsupportedFirmware as exc:
                raise self._error(f"puck {node}: {exc}") from exc
        return {node: self.tables[node] for node in nodes}

    # ------------------------------------------------------------------------------ positions

    def poll_positions(self, group: int, nodes: Sequence[int], *,
                       timeout_s: float | None = None) -> PositionPoll:
        """``GET P`` to a group, and the replies of ``nodes`` on the position group.

        A puck that does not answer within the bound is in ``missing`` and counted in
        ``health.dropped_samples``; no value is ever carried over from an earlier poll.
        """
        expected = set(nodes)
        prop = self._number(nodes, "P")
        timeout = self.reply_timeout_s if timeout_s is None else timeout_s
        got: dict[int, int] = {}
        secondary: dict[int, int] = {}
        bad: set[int] = set()
        self._drain()
        time_s = self.clock.now()
        self._send(group_id(0, group), encode_get(prop))

        def accept(msg: can.Message) -> bool:
            is_group, sender, to = parse_id(msg.arbitration_id)
            if not is_group or to != int(Group.POSITION) or sender not in expected:
                return False
            if sender in got or sender in bad:  # twice: one of them may be old
                bad.add(sender)
                return False
            try:
                primary, second = decode_position(msg.data)
            except ProtocolError:
                self.stats["malformed"] += 1
                self.health.invalid_samples += 1
                bad.add(sender)
                return True
            got[sender] = primary
            if second is not None:
                secondary[sender] = second
            return True

        self._collect(accept, lambda: expected <= set(got) | bad, timeout)
        for node in bad:
            got.pop(node, None)
            secondary.pop(node, None)
        missing = tuple(sorted(expected - set(got)))
        self.stats["missing_positions"] += len(missing)
        self.health.dropped_samples += len(missing)
        return PositionPoll(time_s, dict(got), dict(secondary), missing)


class BarrettHandHost:
    """The BarrettHand's commands over a :class:`PuckHost`: pucks 11-13 are the fingers,
    14 the spread.

    Parameters
    ----------
    host : PuckHost
    nodes : sequence of int
        The hand's pucks.
    poll_s : float
        Period of the MODE polls while waiting for a move to end.
    tolerance : int
        Counts within which a target counts as reached.
    """

    def __init__(self, host: PuckHost, nodes: Sequence[int] = HAND_NODES, *,
                 poll_s: float = 0.05, tolerance: int = 500) -> None:
        self.host = host
        self.nodes = tuple(nodes)
        self.fingers = tuple(n for n in self.nodes if n != 14)
        self.spread = tuple(n for n in self.nodes if n == 14)
        self.poll_s = poll_s
        self.tolerance = tolerance
        self.hold: dict[int, int] = {}

    def initialize(self, *, timeout_s: float = 10.0) -> None:
        """Wake and identify the pucks, then ``CMD HI`` the fingers and then the spread,
        waiting for each to end (MODE back to IDLE).

        Raises
        ------
        BarrettError
            For pucks that do not wake or answer, or a homing that does not end in time.
        """
        host = self.host
        woke = host.wake(self.nodes)
        if not woke.ok:
            raise host._error(f"hand pucks {list(woke.failed)} did not wake")
        host.identify(self.nodes)
        for node in self.nodes:
            self.hold[node] = host.get(node, "HOLD")
        for part in (self.fingers, self.spread):
            if not part:
                continue
            for node in part:
                host.set(node, "CMD", int(Cmd.HI))
            self.wait_done(part, timeout_s=timeout_s)

    def _command(self, cmd: Cmd, nodes: Sequence[int] | None, wait: bool,
                 timeout_s: float) -> dict[int, int] | None:
        targets = self.fingers if nodes is None else tuple(nodes)
        for node in targets:
            self.host.set(node, "CMD", int(cmd))
        return self.wait_done(targets, timeout_s=timeout_s) if wait else None

    def open(self, nodes: Sequence[int] | None = None, *, wait: bool = True,
             timeout_s: float = 10.0) -> dict[int, int] | None:
        """``CMD OPEN`` (the fingers by default); with ``wait``, the MODEs at the end."""
        return self._command(Cmd.OPEN, nodes, wait, timeout_s)

    def close(self, nodes: Sequence[int] | None = None, *, wait: bool = True,
              timeout_s: float = 10.0) -> dict[int, int] | None:
        """``CMD CLOSE`` (the fingers by default); with ``wait``, the MODEs at the end."""
        return self._command(Cmd.CLOSE, nodes, wait, timeout_s)

    def is_done(self, node: int, mode: int | None) -> bool:
        """Done moving: MODE is IDLE, or PID with HOLD set (libbarrett's test)."""
        if mode is None:
            return False
        return mode == int(Mode.IDLE) or (mode == int(Mode.PID) and bool(self.hold.get(node)))

    def wait_done(self, nodes: Sequence[int], *, timeout_s: float = 10.0) -> dict[int, int]:
        """Poll MODE until every puck is done moving; the MODEs.

        Raises
        ------
        BarrettError
            When they are not all done within ``timeout_s`` (a MODE that cannot be read
            counts as not done).
        """
        host = self.host
        deadline = host.clock.now() + timeout_s
        while True:
            modes = {node: host.try_get(node, "MODE") for node in nodes}
            if all(self.is_done(node, mode) for node, mode in modes.items()):
                return {node: int(mode) for node, mode in modes.items() if mode is not None}
            remaining = deadline - host.clock.now()
            if remaining <= 0:
                raise host._error(f"hand pucks {list(nodes)} still moving after {timeout_s:g} s "
                                  f"(MODE {modes})")
            host.port.elapse(min(self.poll_s, remaining))

    def move_to(self, targets: Mapping[int, int], *, timeout_s: float = 10.0) -> MoveResult:
        """Set ``M`` on each puck, wait until done, and read where they ended."""
        host = self.host
        for node, target in targets.items():
            host.set(node, "M", int(target))
        modes = self.wait_done(tuple(targets), timeout_s=timeout_s)
        poll = host.poll_positions(int(Group.HAND), self.nodes)
        reached = {
            node: node in poll.positions and abs(poll.positions[node] - target) <= self.tolerance
            for node, target in targets.items()
        }
        stopped = tuple(node for node, ok in reached.items() if not ok and node in poll.positions)
        return MoveResult(modes, poll, reached, stopped)
