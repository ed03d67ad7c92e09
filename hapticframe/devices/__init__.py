"""The device toolkit: what a driver for a serial device needs, and how to test it.

- Transports (:class:`ByteTransport`, :class:`SerialTransport`): a non-blocking byte stream
  over any pyserial URL or device path; pyserial is imported only when a port is opened.
- Framing (:class:`FixedFrameParser`, :class:`LineFramer`) and CRC-16/Modbus: incremental
  parsers that resynchronise by one byte after a bad check.
- Lifecycle (:class:`DeviceLifecycle`): configure → activate → deactivate → cleanup, with an
  error state and bounded recovery; :class:`DeviceError` ends a run.
- Health (:class:`DeviceHealth`): counters written to ``metrics.json``.
- Time (:class:`Clock`, :class:`MonotonicClock`, :class:`FakeClock`, :class:`ClockSync`):
  every sample carries host time from its device's clock.
- Emulators (:class:`DeviceModel`, :class:`PtyEmulator`, :class:`EmulatedTransport`) with
  seeded fault schedules (:class:`FaultSchedule`).

The guide is ``docs/devices.md``.
"""

from hapticframe.devices._clock import Clock, ClockSync, FakeClock, MonotonicClock
from hapticframe.devices._crc import append_crc16, check_crc16, crc16_modbus
from hapticframe.devices._emulator import DeviceModel, EmulatedTransport, PtyEmulator
from hapticframe.devices._faults import FaultEvent, FaultSchedule, FaultSetting, InjectedFault
from hapticframe.devices._framing import FixedFrameParser, LineFramer, ParserStats
from hapticframe.devices._health import DeviceHealth
from hapticframe.devices._lifecycle import DeviceError, DeviceLifecycle, LifecycleState
from hapticframe.devices._transport import (
    Backoff,
    ByteTransport,
    SerialTransport,
    TransportError,
    open_transport,
)

__all__ = [
    "Backoff",
    "ByteTransport",
    "Clock",
    "ClockSync",
    "DeviceError",
    "DeviceHealth",
    "DeviceLifecycle",
    "DeviceModel",
    "EmulatedTransport",
    "FakeClock",
    "FaultEvent",
    "FaultSchedule",
    "FaultSetting",
    "FixedFrameParser",
    "InjectedFault",
    "LifecycleState",
    "LineFramer",
    "MonotonicClock",
    "ParserStats",
    "PtyEmulator",
    "SerialTransport",
    "TransportError",
    "append_crc16",
    "check_crc16",
    "crc16_modbus",
    "open_transport",
]
