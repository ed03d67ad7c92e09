"""Delivery barriers between a driver and a synchronous pty emulator in the same process.

A pseudo-terminal hands bytes to the other side asynchronously (the kernel moves them in a
work queue): right after one side writes, the other side often reads nothing yet. Paced by
a :class:`~hapticframe.devices.FakeClock`, an emulator runs in the driver's own thread, so
that lag would make a simulated run depend on the machine's load. Two barriers remove it:
the emulator waits until what it wrote is readable on the host's side, and a
:class:`~hapticframe.devices.SerialTransport` that writes to the pty of such an emulator
tells it how many bytes are on their way, so that its next service pass waits for them.
Drivers that open the pty with another library still work; only their timing then depends
on the machine.
"""

from __future__ import annotations

import os
import threading
from typing import Protocol

__all__ = ["HostWriteListener", "notify_host_write", "register", "unregister"]


class HostWriteListener(Protocol):
    def host_wrote(self, count: int) -> None:
        """``count`` bytes were written to the host's end of the pty."""


_lock = threading.Lock()
_listeners: dict[str, HostWriteListener] = {}


def register(tty_name: str, listener: HostWriteListener) -> None:
    with _lock:
        _listeners[os.path.realpath(tty_name)] = listener


def unregister(tty_name: str) -> None:
    with _lock:
        _listeners.pop(os.path.realpath(tty_name), None)


def notify_host_write(path: str, count: int) -> None:
    """Tell the synchronous emulator behind ``path`` (if any) that ``count`` bytes are coming."""
    if not _listeners:
        return
    with _lock:
        listener = _listeners.get(os.path.realpath(path))
    if listener is not None:
        listener.host_wrote(count)
