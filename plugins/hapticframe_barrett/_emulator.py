"""Barrett pucks emulated on python-can's ``virtual`` interface, in the host's process.

A :class:`PuckBus` opens its own ``can.Bus(interface="virtual", channel=...)`` and answers the
host's frames from a :class:`can.Notifier` listener (the canopen project's pattern: the
device under test on one bus, the peer on another bus of the same channel). Each
:class:`EmulatedPuck` holds a motor puck's state: ``STAT`` (pucks start in RESET and then
answer only ``STAT`` and ``VERS``), ``MODE``, the position in encoder counts moving toward the
target ``M`` at a configured speed, and the other properties as plain values.

Time comes from the emulator's clock (a :class:`hapticframe.devices.Clock`). Motion is a
function of that clock: with a :class:`~hapticframe.devices.FakeClock`, fingers move only as
the clock is advanced, and late replies, E-stops, error frames and bus-off happen in the
clock's listener, in the caller's thread — deterministic tests. Before every advance the
listener waits until the reader thread has handled every frame already sent (:meth:`PuckBus.sync`),
so a request is handled at the fake time it was sent, and a host that calls ``clock.sleep(0)``
finds the replies in its queue. With any other clock a daemon thread ticks every millisecond.

Faults (``FaultEvent`` kinds, from a seeded :class:`~hapticframe.devices.FaultSchedule`; the
notes' section 4.5):

``never_wakes`` (params ``node``, ``absent``)
    From its time on, the puck stays in RESET (``absent: 1``: it answers nothing at all).
``late_reply`` (``delay_s``, default 1.5; ``node``)
    The next property reply (from ``node``, if given) is sent ``delay_s`` later.
``malformed_reply`` (``how``: ``bit7``, ``byte1``, ``short``, ``wrong_property``; ``node``)
    The next property reply is corrupted that way.
``duplicate_reply`` (``count``, default 3)
    The next property reply is sent ``1 + count`` times.
``missing_position`` (``node``)
    In the next group position poll, that puck (default: one drawn at random) does not answer.
``estop`` (at a time)
    The safety system forces ``MODE`` to IDLE on every motor puck; motion stops where it is.
``error_frame`` (``count``, default 1)
    ``count`` CAN error frames (``is_error_frame=True``, SocketCAN's protocol-violation flag).
``bus_off`` (``duration_s``)
    An error frame with the bus-off flag, then no puck answers for ``duration_s``, then an
    error frame with the restarted flag.

Simplifications (unverified against hardware): a ``GET P`` is answered in the position format
on group 3 whether it was sent to a puck or to a group; hand pucks move toward ``M`` in
TRAPEZOIDAL mode and end in IDLE (PID with ``HOLD`` set); ``HI`` drives a hand puck to 0
counts and marks it initialised (motion commands before it are ignored); WAM pucks follow
``M`` only while the safety system has them in PID (:meth:`PuckBus.activate_wam`).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import can

from hapticframe.devices import Clock, FakeClock, FaultEvent, FaultSchedule

from ._protocol import (
    CAN_ERR_BUSOFF,
    CAN_ERR_PROT,
    CAN_ERR_RESTARTED,
    HAND_NODES,
    WAM_NODES,
    Cmd,
    Group,
    Mode,
    PropertyTable,
    Stat,
    encode_position,
    encode_property_reply,
    group_id,
    parse_id,
    property_table,
)

__all__ = [
    "FAULT_KINDS",
    "EmulatedPuck",
    "PuckBus",
    "hand_pucks",
    "wam_pucks",
]

#: The emulator's fault kinds.
FAULT_KINDS = (
    "never_wakes",
    "late_reply",
    "malformed_reply",
    "duplicate_reply",
    "missing_position",
    "estop",
    "error_frame",
    "bus_off",
)

#: Groups a puck belongs to (for broadcasts).
_GROUPS_OF_HAND = (int(Group.ALL), int(Group.HAND))
_GROUPS_OF_WAM = (int(Group.ALL), int(Group.WAM))


@dataclass
class EmulatedPuck:
    """One motor puck's state.

    Parameters
    ----------
    node : int
        Its node id.
    vers : int
        Firmware version (selects its property table).
    position : int
        Encoder counts at power-on.
    speed : float
        Counts per second toward a target.
    closed : int
        The counts ``CMD CLOSE`` drives a hand puck to.
    secondary : bool
        Answers position polls with 6 bytes (a secondary encoder, as the hand's fingers).
    reply_length : int
        Property replies of 6 bytes (32-bit values) or 4 (16-bit).
    hand : bool
        A BarrettHand puck (CMD, M moves) rather than a WAM puck.
    """

    node: int
    vers: int = 160
    position: int = 0
    speed: float = 50_000.0
    closed: int = 195_000
    secondary: bool = False
    reply_length: int = 6
    hand: bool = True
    stat: int = int(Stat.RESET)
    mode: int = int(Mode.IDLE)
    target: int | None = None
    initialised: bool = False
    wake_at: float | None = None
    values: dict[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.table: PropertyTable = property_table(self.vers)
        defaults = {"ROLE": 0, "SN": 1000 + self.node, "ID": self.node, "ERROR": 0, "TEMP": 30,
                    "CTS": 4096, "IPNM": 2700, "HOLD": 0, "TSTOP": 50, "V": 0, "PIDX": 1,
                    "MT": 3300, "OT": 0, "CT": self.closed}
        for name, value in defaults.items():
            self.values.setdefault(name, value)
        self._position = float(self.position)

    @property
    def groups(self) -> tuple[int, ...]:
        return _GROUPS_OF_HAND if self.hand else _GROUPS_OF_WAM

    def counts(self) -> int:
        return round(self._position)

    def advance(self, dt: float) -> None:
        """Move toward the target for ``dt`` seconds; arriving ends the move."""
        if self.target is None or dt <= 0:
            return
        moving = self.mode in (int(Mode.TRAPEZOIDAL), int(Mode.PID))
        if not moving:
            return
        step = self.speed * dt
        error = self.target - self._position
        if abs(error) <= step:
            self._position = float(self.target)
            self.target = None
            if self.hand:
                self.mode = int(Mode.PID) if self.values.get("HOLD", 0) else int(Mode.IDLE)
        else:
            self._position += step if error > 0 else -step
        self.position = self.counts()

    def read(self, name: str) -> int:
        if name == "STAT":
            return self.stat
        if name == "VERS":
            return self.vers
        if name == "MODE":
            return self.mode
        if name in ("P", "JP"):
            return self.counts()
        if name == "M":
            return self.counts() if self.target is None else self.target
        return self.values.get(name, 0)


def hand_pucks(
    vers: int = 160, *, speed: float = 50_000.0, start: int = 20_000
) -> list[EmulatedPuck]:
    """A BarrettHand's pucks 11-14 (fingers with a secondary encoder, then the spread)."""
    return [
        EmulatedPuck(node, vers=vers, position=start, speed=speed, secondary=node != 14,
                     closed=195_000 if node != 14 else 35_950, hand=True)
        for node in HAND_NODES
    ]


def wam_pucks(vers: int = 160, *, speed: float = 20_000.0, n: int = 7) -> list[EmulatedPuck]:
    """A WAM's pucks 1-``n`` (4 or 7), in IDLE until the safety system activates them."""
    return [EmulatedPuck(node, vers=vers, speed=speed, hand=False) for node in WAM_NODES[:n]]


class _Listener(can.Listener):
    def __init__(self, owner: PuckBus) -> None:
        self.owner = owner

    def on_message_received(self, msg: can.Message) -> None:
        try:
            self.owner._on_frame(msg)
        finally:
            self.owner._frame_done()

    def on_error(self, exc: Exception) -> None:  # keep the reader thread alive, and say so
        self.owner.errors.append(exc)


class PuckBus:
    """Emulated pucks on one virtual CAN channel.

    Parameters
    ----------
    channel : str
        The ``virtual`` channel the host's bus opens too.
    pucks : iterable of EmulatedPuck
    clock : Clock
        The emulator's time base (a FakeClock for deterministic tests).
    faults : FaultSchedule or None
        Protocol faults (see the module docstring).
    wake_delay_s : float
        Time from ``SET STAT=2`` until the puck reads READY.

    Attributes
    ----------
    stats : dict of str to int
        What happened: ``frames_in``, ``replies``, ``ignored`` (frames a puck in RESET or an
        absent puck did not answer), ``mode_set_on_arm`` (a host that set MODE on a WAM puck,
        which the safety system owns), ``late``, ``malformed``, ``duplicates``,
        ``missing_positions``, ``estops``, ``error_frames``, ``bus_offs``.
    errors : list of Exception
        Exceptions raised in the listener (a test asserts it stays empty).
    """

    def __init__(
        self,
        channel: str,
        pucks: Iterable[EmulatedPuck],
        *,
        clock: Clock,
        faults: FaultSchedule | None = None,
        wake_delay_s: float = 0.2,
    ) -> None:
        self.channel = channel
        self.pucks: dict[int, EmulatedPuck] = {p.node: p for p in pucks}
        self.clock = clock
        self.faults = faults
        self.wake_delay_s = wake_delay_s
        self.stats: dict[str, int] = dict.fromkeys(
            ("frames_in", "replies", "ignored", "mode_set_on_arm", "late", "malformed",
             "duplicates", "missing_positions", "estops", "error_frames", "bus_offs",
             "sync_timeouts"), 0)
        self.errors: list[Exception] = []
        self._lock = threading.RLock()
        self._last_s = clock.now()
        self._pending: list[tuple[float, can.Message]] = []  # (due, frame), late replies
        self._dead: set[int] = set()  # never wake
        self._absent: set[int] = set()  # answer nothing
        self._bus_off_until: float | None = None
        self._armed: dict[str, list[FaultEvent]] = {}
        self._bus: can.BusABC | None = None
        self._notifier: can.Notifier | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._fake = isinstance(clock, FakeClock)

    # ------------------------------------------------------------------------------- lifecycle

    def start(self) -> PuckBus:
        """Open the emulator's bus and start answering."""
        if self._bus is not None:
            return self
        self._bus = can.Bus(interface="virtual", channel=self.channel)
        self._notifier = can.Notifier(self._bus, [_Listener(self)], timeout=0.05)
        if isinstance(self.clock, FakeClock):
            self.clock.add_listener(self._on_clock)
        else:
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name="puck-bus", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop answering and close the emulator's bus (what a bus-off that lasts looks like)."""
        if isinstance(self.clock, FakeClock):
            self.clock.remove_listener(self._on_clock)
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
            self._thread = None
        if self._notifier is not None:
            self._notifier.stop(timeout=1.0)
            self._notifier = None
        if self._bus is not None:
            self._bus.shutdown()
            self._bus = None

    def __enter__(self) -> PuckBus:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def notifier_exception(self) -> BaseException | None:
        """What killed the Notifier's reader thread, if anything."""
        return None if self._notifier is None else self._notifier.exception

    # ----------------------------------------------------------------------- the safety system

    def activate_wam(self) -> None:
        """The pendant's activate: the safety system puts the WAM pucks in PID."""
        with self._lock:
            self._tick(self.clock.now())
            for puck in self.pucks.values():
                if not puck.hand and puck.stat == int(Stat.READY):
                    puck.mode = int(Mode.PID)

    def estop(self) -> None:
        """The E-stop (or shift-idle): MODE forced to IDLE on every puck, motion stops."""
        with self._lock:
            self._tick(self.clock.now())
            self._estop()

    def _estop(self) -> None:
        self.stats["estops"] += 1
        for puck in self.pucks.values():
            puck.mode = int(Mode.IDLE)
            puck.target = None

    # ------------------------------------------------------------------------------ time base

    def _run(self) -> None:
        while not self._stop.wait(0.001):
            self.tick()

    def _on_clock(self, now: float) -> None:
        self.sync()
        self.tick()

    def _rx_queue(self) -> queue.Queue[can.Message] | None:
        q = getattr(self._bus, "queue", None)  # VirtualBus's receive queue
        return q if isinstance(q, queue.Queue) else None

    def _frame_done(self) -> None:
        q = self._rx_queue()
        if q is not None:
            try:
                q.task_done()
            except ValueError:  # more frames handled than queued: not a VirtualBus queue
                pass

    def sync(self, timeout_s: float = 1.0) -> bool:
        """Wait (real time, bounded) until the reader thread has handled every frame the host
        has sent so far; False when it did not in ``timeout_s`` (counted: ``sync_timeouts``).

        On a FakeClock this runs before every advance, so a frame the host sent before
        sleeping is handled at the time it was sent, and its reply is in the host's queue
        when the host's ``clock.sleep(0)`` returns: no real-time waits, no races. It relies
        on the virtual bus's ``queue`` counting unfinished frames (``Queue.task_done``).
        """
        q = self._rx_queue()
        if q is None:
            return True
        deadline = time.monotonic() + timeout_s
        while q.unfinished_tasks > 0:
            if time.monotonic() >= deadline:
                self.stats["sync_timeouts"] += 1
                return False
            time.sleep(0.0002)
        return True

    def tick(self) -> None:
        """Advance the pucks and the faults to the clock's time, and send what is due."""
        with self._lock:
            self._tick(self.clock.now())

    def _tick(self, now: float) -> None:
        dt = now - self._last_s
        if dt > 0:
            for puck in self.pucks.values():
                puck.advance(dt)
            self._last_s = now
        faults = self.faults
        if faults is not None:
            while (event := faults.fires("never_wakes", now)) is not None:
                node = int(event.params.get("node", min(self.pucks)))
                self._dead.add(node)
                if int(event.params.get("absent", 0)):
                    self._absent.add(node)
            while faults.fires("estop", now) is not None:
                self._estop()
            while (event := faults.fires("error_frame", now)) is not None:
                for _ in range(int(event.params.get("count", 1))):
                    self._send_error(CAN_ERR_PROT)
            while (event := faults.fires("bus_off", now)) is not None:
                self.stats["bus_offs"] += 1
                self._send_error(CAN_ERR_BUSOFF)
                self._bus_off_until = now + event.duration_s
        for puck in self.pucks.values():
            if puck.wake_at is not None and now >= puck.wake_at:
                puck.wake_at = None
                if puck.node not in self._dead:
                    puck.stat = int(Stat.READY)
        if self._bus_off_until is not None and now >= self._bus_off_until:
            self._bus_off_until = None
            self._send_error(CAN_ERR_RESTARTED)
        due = [item for item in self._pending if item[0] <= now]
        if due:
            self._pending = [item for item in self._pending if item[0] > now]
            for _, msg in sorted(due, key=lambda item: item[0]):
                self._send(msg)

    # -------------------------------------------------------------------------------- sending

    def _send(self, msg: can.Message) -> None:
        bus = self._bus
        if bus is None:
            return
        try:
            bus.send(msg)
        except can.CanError as exc:
            self.errors.append(exc)

    def _send_error(self, flags: int) -> None:
        self.stats["error_frames"] += 1
        self._send(can.Message(arbitration_id=flags, is_error_frame=True, is_extended_id=False,
                               data=bytes(8)))

    def _reply_property(self, puck: EmulatedPuck, prop: int, value: int, now: float) -> None:
        data = bytearray(encode_property_reply(prop, _fit(value, puck.reply_length),
                                               puck.reply_length))
        delay = 0.0
        copies = 1
        faults = self.faults
        if faults is not None:
            event = self._armed_for("malformed_reply", now, puck.node)
            if event is not None:
                self.stats["malformed"] += 1
                how = str(event.params.get("how", "bit7"))
                if how == "bit7":
                    data[0] &= 0x7F
                elif how == "byte1":
                    data[1] = 0x5A
                elif how == "short":
                    data = data[:2]
                elif how == "wrong_property":
                    data[0] = 0x80 | ((prop + 1) & 0x7F)
                else:
                    raise ValueError(f"malformed_reply: unknown how {how!r}")
            event = self._armed_for("late_reply", now, puck.node)
            if event is not None:
                self.stats["late"] += 1
                delay = float(event.params.get("delay_s", 1.5))
            event = faults.fires("duplicate_reply", now)
            if event is not None:
                count = int(event.params.get("count", 3))
                self.stats["duplicates"] += count
                copies += count
        msg = can.Message(arbitration_id=group_id(puck.node, int(Group.PROPERTY)),
                          data=bytes(data), is_extended_id=False)
        self.stats["replies"] += copies
        for _ in range(copies):
            if delay > 0:
                self._pending.append((now + delay, msg))
            else:
                self._send(msg)

    def _armed_for(self, kind: str, now: float, node: int) -> FaultEvent | None:
        """An occurrence of ``kind`` that applies to ``node``'s reply: one without a ``node``
        applies to the next reply of any puck; one with a node waits for that puck's."""
        assert self.faults is not None
        armed = self._armed.setdefault(kind, [])
        while (event := self.faults.fires(kind, now)) is not None:
            armed.append(event)
        for index, event in enumerate(armed):
            if "node" not in event.params or int(event.params["node"]) == node:
                return armed.pop(index)
        return None

    def _reply_position(self, puck: EmulatedPuck) -> None:
        counts = puck.counts()
        data = encode_position(counts, counts if puck.secondary else None)
        self.stats["replies"] += 1
        self._send(can.Message(arbitration_id=group_id(puck.node, int(Group.POSITION)),
                               data=data, is_extended_id=False))

    # ------------------------------------------------------------------------------ receiving

    def _on_frame(self, msg: can.Message) -> None:
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            return
        with self._lock:
            if self._fake:
                # Handled at the time it was sent: the clock only moves after sync(), which
                # waits for this frame, so the last tick's time is the time of sending.
                now = self._last_s
                self._tick(now)  # faults due by then (the pucks do not move: dt = 0)
            else:
                now = self.clock.now()
                self._tick(now)
            self.stats["frames_in"] += 1
            is_group, sender, to = parse_id(msg.arbitration_id)
            if sender != 0 or self._bus_off_until is not None:
                return
            if is_group:
                targets = [p for p in self.pucks.values() if to in p.groups]
            else:
                targets = [self.pucks[to]] if to in self.pucks else []
            data = bytes(msg.data)
            if not data:
                return
            prop = data[0] & 0x7F
            is_set = bool(data[0] & 0x80)
            if not is_set and is_group and targets and _is_position_get(targets[0], prop):
                self._poll(targets, now)
                return
            for puck in targets:
                if is_set:
                    self._set(puck, prop, data, now)
                else:
                    self._get(puck, prop, now)

    def _answers(self, puck: EmulatedPuck, name: str | None) -> bool:
        if puck.node in self._absent:
            return False
        return puck.stat == int(Stat.READY) or name in ("STAT", "VERS")

    def _poll(self, targets: Sequence[EmulatedPuck], now: float) -> None:
        answering = [p for p in targets if self._answers(p, "P")]
        skip: int | None = None
        faults = self.faults
        if faults is not None and answering:
            event = faults.fires("missing_position", now)
            if event is not None:
                self.stats["missing_positions"] += 1
                if "node" in event.params:
                    skip = int(event.params["node"])
                else:
                    skip = answering[int(faults.rng.integers(len(answering)))].node
        for puck in targets:
            if puck not in answering or puck.node == skip:
                self.stats["ignored"] += 1
                continue
            self._reply_position(puck)

    def _get(self, puck: EmulatedPuck, prop: int, now: float) -> None:
        name = puck.table.name_of(prop)
        if not self._answers(puck, name) or name is None:
            self.stats["ignored"] += 1
            return
        if name == "P":
            self._reply_position(puck)
            return
        self._reply_property(puck, prop, puck.read(name), now)

    def _set(self, puck: EmulatedPuck, prop: int, data: bytes, now: float) -> None:
        name = puck.table.name_of(prop)
        if len(data) < 3 or data[1] != 0 or name is None:
            self.stats["ignored"] += 1
            return
        value = int.from_bytes(data[2:], "little", signed=True)
        if puck.node in self._absent:
            self.stats["ignored"] += 1
            return
        if name == "STAT":
            if value == int(Stat.READY) and puck.stat != int(Stat.READY):
                puck.wake_at = now + self.wake_delay_s
            elif value == int(Stat.RESET):
                puck.stat = int(Stat.RESET)
            return
        if puck.stat != int(Stat.READY):
            self.stats["ignored"] += 1
            return
        if name == "MODE":
            if not puck.hand:
                self.stats["mode_set_on_arm"] += 1
            puck.mode = value
            if value == int(Mode.IDLE):
                puck.target = None
            return
        if name == "CMD":
            self._command(puck, value)
            return
        if name == "M":
            if puck.hand:
                if not puck.initialised:
                    self.stats["ignored"] += 1
                    return
                puck.mode = int(Mode.TRAPEZOIDAL)
                puck.target = value
            elif puck.mode == int(Mode.PID):
                puck.target = value
            else:
                self.stats["ignored"] += 1
            return
        puck.values[name] = value

    def _command(self, puck: EmulatedPuck, cmd: int) -> None:
        if not puck.hand:
            self.stats["ignored"] += 1
            return
        if cmd == int(Cmd.HI):
            puck.initialised = True
            target = 0
        elif cmd in (int(Cmd.OPEN), int(Cmd.CLOSE)) and puck.initialised:
            target = 0 if cmd == int(Cmd.OPEN) else puck.closed
        else:
            self.stats["ignored"] += 1
            return
        puck.mode = int(Mode.TRAPEZOIDAL)
        puck.target = target

    # ----------------------------------------------------------------------------- inspection

    def puck(self, node: int) -> EmulatedPuck:
        """The state of one puck (brought up to the clock's time)."""
        with self._lock:
            self._tick(self.clock.now())
            return self.pucks[node]

    def describe(self) -> dict[str, Any]:
        """A summary for diagnostics."""
        with self._lock:
            return {"channel": self.channel, "stats": dict(self.stats),
                    "pucks": {n: (p.stat, p.mode, p.counts()) for n, p in self.pucks.items()}}


def _fit(value: int, length: int) -> int:
    bits = 8 * (length - 2)
    value &= (1 << bits) - 1
    return value - (1 << bits) if value & (1 << (bits - 1)) else value


def _is_position_get(puck: EmulatedPuck, prop: int) -> bool:
    return puck.table.name_of(prop) == "P"
