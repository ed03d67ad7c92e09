"""Device emulators: a device's protocol core behind a real pseudo-terminal or in-process.

A :class:`DeviceModel` is the device's protocol, pure and driven by time: it receives what the
host wrote and emits what the device sends by a given time. :class:`PtyEmulator` puts it
behind a pseudo-terminal path that any serial library can open (pyserial, minimalmodbus,
dynamixel-sdk), exactly as a USB adapter; :class:`EmulatedTransport` runs it in-process for
fast unit tests. Both apply the byte-level faults of a :class:`FaultSchedule` to the
device→host stream; protocol faults are the model's own business.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import select
import struct
import termios
import threading
import time
import tty
from abc import ABC, abstractmethod
from pathlib import Path
from types import TracebackType

import numpy as np

from hapticframe.devices import _ptysync
from hapticframe.devices._clock import Clock, FakeClock
from hapticframe.devices._faults import FaultSchedule
from hapticframe.devices._transport import ByteTransport, TransportError

__all__ = ["DeviceModel", "EmulatedTransport", "PtyEmulator"]

#: The longest a synchronous emulator waits, in real time, for the kernel to move bytes
#: across its pty (it takes microseconds; seconds only on a machine that is stalled).
_DELIVERY_WAIT_S = 2.0
#: Bytes a pty's line discipline holds for its reader (N_TTY_BUF_SIZE is 4096), less one.
_LINE_BUFFER_FULL = 4095


def _queued(fd: int) -> int:
    """Bytes waiting to be read on ``fd`` (FIONREAD)."""
    return int(struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0])


class DeviceModel(ABC):
    """A device's protocol core: pure, clock-driven, no I/O.

    A model that injects protocol faults (bad CRC, out-of-range values, missing replies)
    takes a :class:`FaultSchedule` in its own constructor and asks ``faults.fires(kind, now)``.
    """

    @abstractmethod
    def receive(self, data: bytes, now_s: float) -> None:
        """Bytes the host wrote (any split: requests may arrive in pieces)."""

    @abstractmethod
    def emit(self, now_s: float) -> bytes:
        """Every byte the device has sent by ``now_s`` and not yet emitted."""

    def power_cycle(self) -> None:
        """Return to the power-on state (after a replug). Default: nothing to reset."""


class _ByteFaults:
    """Applies drop_bytes, garbage, fragment and stall to the device→host stream."""

    def __init__(self, faults: FaultSchedule | None, rng: np.random.Generator | None) -> None:
        self.faults = faults
        self.rng = rng if rng is not None else (
            faults.rng if faults is not None else np.random.default_rng(0)
        )
        self.held = bytearray()  # due but not yet delivered (a stall, a fragmented write)
        self.dropped = 0

    def clear(self) -> None:
        self.held.clear()

    def process(self, data: bytes, now_s: float) -> bytes:
        """The bytes to deliver now, given the bytes the device emitted now."""
        faults = self.faults
        if faults is None:
            if not self.held:
                return data
            self.held += data
            out = bytes(self.held)
            self.held.clear()
            return out
        rng = self.rng
        chunk = bytearray(data)
        # drop_bytes and garbage act on data the device sends, so they wait for some.
        if chunk and (event := faults.fires("drop_bytes", now_s)) is not None:
            count = min(int(event.params.get("count", 1)), len(chunk))
            start = int(rng.integers(0, len(chunk) - count + 1))
            del chunk[start : start + count]
            self.dropped += count
        if (event := faults.fires("garbage", now_s)) is not None:
            count = int(event.params.get("count", 1))
            noise = rng.integers(0, 256, size=count, dtype=np.uint8).tobytes()
            where = int(rng.integers(0, len(chunk) + 1))
            chunk[where:where] = noise
        self.held += chunk
        stall = faults.active("stall", now_s)
        if stall is not None:
            if int(stall.params.get("drop", 0)):
                self.dropped += len(self.held)
                self.held.clear()
            return b""
        if self.held and faults.active("fragment", now_s) is not None:
            size = int(rng.integers(1, len(self.held) + 1))
            out = bytes(self.held[:size])
            del self.held[:size]
            return out
        out = bytes(self.held)
        self.held.clear()
        return out


class EmulatedTransport(ByteTransport):
    """A :class:`ByteTransport` wired straight to a device model: no pty, no threads.

    The model is serviced on every call, at ``clock.now()``. A ``disconnect`` fault makes the
    open link fail with :class:`TransportError` (as an unplugged adapter does); opening fails
    until the fault's ``duration_s`` has passed, then the device is back, power-cycled.

    Parameters
    ----------
    model : DeviceModel
    clock : Clock
        The device's clock (a :class:`FakeClock` in tests).
    faults : FaultSchedule or None, optional
        Byte-level faults for the device→host stream.
    """

    def __init__(
        self, model: DeviceModel, clock: Clock, faults: FaultSchedule | None = None
    ) -> None:
        self.model = model
        self.clock = clock
        self.faults = faults
        self._bytes = _ByteFaults(faults, None)
        self._inbox = bytearray()
        self._open = False
        self._stale = False  # the open handle belongs to a link that was unplugged
        self._plugged = True
        self._replug_at_s: float | None = None
        self.stats = {"bytes_out": 0, "bytes_in": 0, "disconnects": 0}

    def _service(self) -> None:
        now = self.clock.now()
        if not self._plugged:
            if self._replug_at_s is not None and now >= self._replug_at_s:
                self._plugged, self._replug_at_s = True, None
                self.model.power_cycle()
            return
        if self.faults is not None and (event := self.faults.fires("disconnect", now)):
            self._plugged, self._replug_at_s = False, now + event.duration_s
            self._stale = self._open
            self._inbox.clear()
            self._bytes.clear()
            self.stats["disconnects"] += 1
            return
        out = self._bytes.process(self.model.emit(now), now)
        self.stats["bytes_out"] += len(out)
        if self._open:
            self._inbox += out  # bytes sent while the port is closed are lost, as on a line

    @property
    def is_open(self) -> bool:
        return self._open

    def open(self) -> None:
        if self._open and not self._stale:
            return
        self._service()
        if not self._plugged:
            raise TransportError("emulated device: no such device (unplugged)")
        self._open, self._stale = True, False
        self._inbox.clear()

    def close(self) -> None:
        self._open = self._stale = False
        self._inbox.clear()

    def _check(self, what: str) -> None:
        if not self._open:
            raise TransportError(f"emulated device: {what} on a closed port")
        self._service()
        if self._stale or not self._plugged:
            raise TransportError(f"emulated device: {what} failed: device disconnected")

    def read_available(self, max_bytes: int = 4096) -> bytes:
        self._check("read")
        out = bytes(self._inbox[:max_bytes])
        del self._inbox[:max_bytes]
        return out

    def write(self, data: bytes) -> None:
        self._check("write")
        self.stats["bytes_in"] += len(data)
        self.model.receive(bytes(data), self.clock.now())

    def reset_input(self) -> None:
        self._check("reset_input")
        self._inbox.clear()


class PtyEmulator:
    """A device model behind a real pseudo-terminal (POSIX).

    The driver opens :attr:`path` with any serial library, exactly as a device. Paced by a
    :class:`FakeClock`, the emulator services the pty in a clock listener (deterministic:
    every ``clock.sleep``/``advance`` runs one :meth:`pump`, which returns only once the
    bytes it wrote are readable on the host's side and the bytes a
    :class:`SerialTransport` wrote to it have arrived — a pty moves bytes asynchronously);
    paced by any other clock, a daemon thread pumps every millisecond.

    Parameters
    ----------
    model : DeviceModel
    clock : Clock
    faults : FaultSchedule or None, optional
        Byte-level faults (drop_bytes, garbage, fragment, stall, disconnect).
    link_path : path or None, optional
        A symlink to the pty, moved to the new pty on replug (as ``/dev/serial/by-id/...``).
        Without it, :attr:`path` is the pty's own name, which changes on replug.
    fragment_rng : numpy.random.Generator or None, optional
        For the random choices of byte faults (default: the schedule's generator).
    thread : bool or None, optional
        None (default): pump in the clock's listener when the clock is a :class:`FakeClock`,
        in a thread otherwise. True: pump in a daemon thread whatever the clock (for a host
        library that blocks waiting for replies, such as ``dynamixel_sdk``, while the model's
        time is a :class:`FakeClock` that the host advances). False: the listener.

    Attributes
    ----------
    path : str
        What the driver opens.
    stats : dict of str to int
        ``bytes_out`` (device→host), ``bytes_in`` (host→device), ``overruns`` (writes that
        found the pty full and were dropped), ``disconnects``, ``dropped`` (bytes removed by
        faults).
    """

    def __init__(
        self,
        model: DeviceModel,
        *,
        clock: Clock,
        faults: FaultSchedule | None = None,
        link_path: str | os.PathLike[str] | None = None,
        fragment_rng: np.random.Generator | None = None,
        thread: bool | None = None,
    ) -> None:
        self.model = model
        self.clock = clock
        self.faults = faults
        self.link_path = None if link_path is None else Path(link_path)
        self._bytes = _ByteFaults(faults, fragment_rng)
        self._lock = threading.RLock()
        self._master: int | None = None
        self._slave: int | None = None
        self._tty_name = ""
        # thread=None: a FakeClock pumps in its listener, any other clock in a thread;
        # thread=True: a thread whatever the clock (a host that blocks waiting for replies
        # on a FakeClock that only it advances); thread=False: the listener (FakeClock only).
        if thread is False and not isinstance(clock, FakeClock):
            raise ValueError("thread=False (pumping in the clock's listener) needs a FakeClock")
        self._synchronous = isinstance(clock, FakeClock) if thread is None else not thread
        # Bytes a SerialTransport wrote to the host's end, and bytes read here, since plugging.
        self._host_written = 0
        self._host_read = 0
        self._replug_at_s: float | None = None
        self._running = False
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self.stats = {"bytes_out": 0, "bytes_in": 0, "overruns": 0, "disconnects": 0,
                      "dropped": 0}

    @property
    def path(self) -> str:
        """The path a driver opens (the symlink when there is one)."""
        return str(self.link_path) if self.link_path is not None else self._tty_name

    @property
    def connected(self) -> bool:
        """Whether the device is plugged in (a pty exists)."""
        return self._master is not None

    # --- pty management ------------------------------------------------------------------
    def _plug(self) -> None:
        master, slave = os.openpty()
        # Raw at once: a cooked slave would echo the device's bytes back to the master
        # before the host opens the port and sets raw mode itself.
        tty.setraw(slave)
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        self._tty_name = os.ttyname(slave)
        self._host_written = self._host_read = 0
        if self._synchronous:
            _ptysync.register(self._tty_name, self)
        if self.link_path is not None:
            temporary = self.link_path.with_name(self.link_path.name + ".new")
            with contextlib.suppress(FileNotFoundError):
                temporary.unlink()
            os.symlink(self._tty_name, temporary)
            os.replace(temporary, self.link_path)  # atomic: the path never dangles half-moved

    def _unplug(self) -> None:
        if self._synchronous and self._tty_name:
            _ptysync.unregister(self._tty_name)
        for fd in (self._master, self._slave):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = None
        if self.link_path is not None:
            with contextlib.suppress(FileNotFoundError):
                self.link_path.unlink()  # an unplugged device's by-id link disappears

    # --- public control ----------------------------------------------------------------------
    def start(self) -> PtyEmulator:
        """Create the pty and start servicing it; returns self."""
        with self._lock:
            if self._running:
                return self
            self._plug()
            self._running = True
        if self._synchronous:
            assert isinstance(self.clock, FakeClock)
            self.clock.add_listener(self._on_tick)
        else:
            self._stop.clear()
            self._thread = threading.Thread(
                target=self._serve, name=f"pty-emulator {self.path}", daemon=True
            )
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop servicing and remove the pty (and the symlink); idempotent."""
        if self._synchronous and isinstance(self.clock, FakeClock):
            self.clock.remove_listener(self._on_tick)
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        self._thread = None
        with self._lock:
            self._running = False
            self._unplug()

    def disconnect(self) -> None:
        """Unplug: close the pty; the host's next read or write fails. Stays unplugged
        until :meth:`replug` (or, after a ``disconnect`` fault, its duration)."""
        with self._lock:
            if self._master is None:
                return
            self._unplug()
            self._bytes.clear()
            self.stats["disconnects"] += 1

    def replug(self) -> None:
        """Plug in again: a new pty, the symlink moved to it, the model power-cycled."""
        with self._lock:
            if self._master is not None or not self._running:
                return
            self._replug_at_s = None
            self._plug()
            self.model.power_cycle()

    def __enter__(self) -> PtyEmulator:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.stop()

    # --- servicing -------------------------------------------------------------------------
    def _on_tick(self, now_s: float) -> None:
        self.pump()

    def host_wrote(self, count: int) -> None:
        """A :class:`SerialTransport` wrote ``count`` bytes to this pty (the delivery
        barrier of synchronous pumping: the next :meth:`pump` waits for them)."""
        with self._lock:
            self._host_written += count

    def _serve(self) -> None:
        while not self._stop.wait(0.001):
            self.pump()

    def pump(self) -> None:
        """One service pass: the host's bytes to the model, the model's bytes (with faults)
        to the host. Never blocks: bytes that do not fit in the pty are dropped and counted."""
        with self._lock:
            if not self._running:
                return
            now = self.clock.now()
            if self._master is None:
                if self._replug_at_s is not None and now >= self._replug_at_s:
                    self.replug()
                return
            received = self._drain()
            if received:
                self.stats["bytes_in"] += len(received)
                self.model.receive(received, now)
            if self.faults is not None and (event := self.faults.fires("disconnect", now)):
                self.disconnect()
                self._replug_at_s = now + event.duration_s
                return
            out = self._bytes.process(self.model.emit(now), now)
            self.stats["dropped"] = self._bytes.dropped
            if out:
                self._write(out)

    def _drain(self) -> bytes:
        assert self._master is not None
        chunks = []
        deadline: float | None = None
        while True:
            try:
                chunk = os.read(self._master, 4096)
            except BlockingIOError:
                chunk = b""
            except OSError as exc:
                if exc.errno == errno.EIO:  # no slave open: nothing to read
                    break
                raise
            if chunk:
                chunks.append(chunk)
                self._host_read += len(chunk)
                continue
            if not self._synchronous or self._host_read >= self._host_written:
                break
            # Bytes the host wrote are still crossing the pty: wait for them (bounded).
            now = time.monotonic()
            if deadline is None:
                deadline = now + _DELIVERY_WAIT_S
            elif now >= deadline:
                self._host_read = self._host_written  # lost in the kernel: do not wait again
                break
            select.select([self._master], [], [], min(0.01, deadline - now))
        return b"".join(chunks)

    def _await_delivery(self, count: int) -> None:
        """Wait (bounded) until ``count`` bytes written just now are readable by the host."""
        slave = self._slave
        if slave is None:
            return
        deadline = time.monotonic() + _DELIVERY_WAIT_S
        while True:
            queued = _queued(slave)
            # A host that stopped reading fills the line discipline's buffer: what does not
            # fit waits in the kernel, and waiting longer would not change that.
            if queued >= count or queued >= _LINE_BUFFER_FULL or time.monotonic() >= deadline:
                return
            time.sleep(0)

    def _write(self, data: bytes) -> None:
        assert self._master is not None
        # What the host has not read yet plus what is written now is what it must see.
        target = _queued(self._slave) if self._synchronous and self._slave is not None else 0
        view = memoryview(data)
        while view:
            try:
                written = os.write(self._master, view)
            except BlockingIOError:
                written = 0
            if written <= 0:  # the host stopped reading and the pty is full: drop the rest
                self.stats["overruns"] += 1
                break
            self.stats["bytes_out"] += written
            target += written
            view = view[written:]
        if self._synchronous:
            self._await_delivery(target)
