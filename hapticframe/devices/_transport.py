"""Byte-stream transports: the one seam between a driver and a serial link.

A driver talks to a :class:`ByteTransport`; production uses :class:`SerialTransport` (pyserial:
a device path, a pseudo-terminal or any pyserial URL), tests use an emulator. pyserial is
imported only when a port is opened.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import dataclass
from types import TracebackType
from typing import Any

from hapticframe.devices import _ptysync

__all__ = ["Backoff", "ByteTransport", "SerialTransport", "TransportError", "open_transport"]


class TransportError(OSError):
    """The link failed: the device was unplugged, a write failed, or the port did not open."""


class ByteTransport(ABC):
    """A byte stream to one device, read without ever waiting.

    Implementations raise :class:`TransportError` for any link failure. Use as a context
    manager to open and close it.
    """

    @abstractmethod
    def open(self) -> None:
        """Open the link (a no-op when it is open)."""

    @abstractmethod
    def close(self) -> None:
        """Close the link; never raises, also when it is closed or the device is gone."""

    @property
    @abstractmethod
    def is_open(self) -> bool:
        """Whether :meth:`open` succeeded and :meth:`close` has not been called since."""

    @abstractmethod
    def read_available(self, max_bytes: int = 4096) -> bytes:
        """Up to ``max_bytes`` bytes that have arrived; ``b""`` at once when none have."""

    @abstractmethod
    def write(self, data: bytes) -> None:
        """Send ``data`` (all of it, or raise :class:`TransportError`)."""

    @abstractmethod
    def reset_input(self) -> None:
        """Discard bytes received and not yet read (before a request/response exchange)."""

    def __enter__(self) -> ByteTransport:
        self.open()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()


class SerialTransport(ByteTransport):
    """A serial port through pyserial: ``serial.serial_for_url(url, timeout=0)``.

    Parameters
    ----------
    url : str
        A device path (``/dev/ttyUSB0``, ``/dev/serial/by-id/...``), a pseudo-terminal path
        (an emulator's) or any pyserial URL (``loop://``, ``socket://host:port``).
    baudrate : int
        Bits per second (a pseudo-terminal accepts any value and ignores it).
    **serial_kwargs
        Passed to pyserial (``bytesize``, ``parity``, ``stopbits``, ``write_timeout``: default
        0.5 s, so a stuck adapter raises instead of blocking the loop).
    """

    def __init__(self, url: str, *, baudrate: int, **serial_kwargs: Any) -> None:
        self.url = url
        self.baudrate = baudrate
        self.serial_kwargs = {"write_timeout": 0.5, **serial_kwargs}
        self._port: Any = None

    @property
    def port(self) -> Any:
        """The open ``serial.Serial`` object (control lines, settings), or None."""
        return self._port

    @property
    def is_open(self) -> bool:
        return self._port is not None and bool(self._port.is_open)

    def open(self) -> None:
        if self.is_open:
            return
        try:
            import serial
        except ImportError as exc:
            raise ModuleNotFoundError(
                "pyserial is needed to open a serial port: pip install 'hapticframe[hardware]'"
            ) from exc
        try:
            # timeout=0: read() returns at once with what has arrived.
            self._port = serial.serial_for_url(
                self.url, baudrate=self.baudrate, timeout=0, **self.serial_kwargs
            )
        except (serial.SerialException, OSError, ValueError) as exc:
            self._port = None
            raise TransportError(f"cannot open {self.url}: {exc}") from exc

    def close(self) -> None:
        port, self._port = self._port, None
        if port is not None:
            try:
                port.close()
            except Exception:  # closing a port whose device is gone: nothing left to release
                pass

    def _require_open(self) -> Any:
        if self._port is None:
            raise TransportError(f"{self.url} is not open")
        return self._port

    def read_available(self, max_bytes: int = 4096) -> bytes:
        port = self._require_open()
        import serial

        try:
            # With timeout=0 pyserial reads what is there; a port whose device vanished
            # reports readiness with no data, which pyserial raises as SerialException.
            return bytes(port.read(max_bytes))
        except (serial.SerialException, OSError) as exc:
            raise TransportError(f"read from {self.url} failed: {exc}") from exc

    def write(self, data: bytes) -> None:
        port = self._require_open()
        import serial

        try:
            written = port.write(data)
        except (serial.SerialException, OSError) as exc:
            raise TransportError(f"write to {self.url} failed: {exc}") from exc
        if written is not None and written != len(data):
            raise TransportError(f"write to {self.url} sent {written} of {len(data)} bytes")
        if "://" not in self.url:
            _ptysync.notify_host_write(self.url, len(data))

    def reset_input(self) -> None:
        port = self._require_open()
        import serial

        try:
            port.reset_input_buffer()
        except (serial.SerialException, OSError) as exc:
            raise TransportError(f"flushing {self.url} failed: {exc}") from exc


def open_transport(url: str, *, baudrate: int, **serial_kwargs: Any) -> ByteTransport:
    """An opened transport for ``url`` (today always a :class:`SerialTransport`).

    Raises
    ------
    TransportError
        When the port cannot be opened.
    """
    transport = SerialTransport(url, baudrate=baudrate, **serial_kwargs)
    transport.open()
    return transport


@dataclass(frozen=True)
class Backoff:
    """Bounded, growing delays between reconnect attempts.

    Iterating yields exactly ``attempts`` delays: ``initial_s``, ``initial_s * factor``, ...,
    each capped at ``max_s``. A driver sleeps each delay on its clock and retries; when the
    delays run out it gives up (and its lifecycle raises :class:`DeviceError`).

    Examples
    --------
    >>> list(Backoff(0.05, 2.0, 0.15, attempts=4))
    [0.05, 0.1, 0.15, 0.15]
    """

    initial_s: float = 0.05
    factor: float = 2.0
    max_s: float = 1.0
    attempts: int = 5

    def __post_init__(self) -> None:
        if self.initial_s < 0 or self.max_s < 0:
            raise ValueError("delays must be non-negative")
        if self.factor < 1:
            raise ValueError("factor must be at least 1")
        if self.attempts < 1:
            raise ValueError("attempts must be at least 1")

    def __iter__(self) -> Iterator[float]:
        delay = self.initial_s
        for _ in range(self.attempts):
            yield min(delay, self.max_s)
            delay *= self.factor

    def __len__(self) -> int:
        return self.attempts

    @property
    def total_s(self) -> float:
        """The longest a full retry sequence waits."""
        return float(sum(self))
