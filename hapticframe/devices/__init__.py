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
- Ports (:class:`DevicePort`: :class:`SerialPort`, :class:`PacedPort`,
  :class:`EmulatedPort`): what a driver is handed — its link, its clock and how far a read
  goes — so that its code is the same for a real device and an emulated one.
- Emulators (:class:`DeviceModel`, :class:`PtyEmulator`, :class:`EmulatedTransport`) with
  seeded fault schedules (:class:`FaultSchedule`).

The guide is ``docs/devices.md``.
"""

from hapticframe.devices._clock import Clock, ClockSync, FakeClock, MonotonicClock
from hapticframe.devices._crc import append_crc16, check_crc16, crc16_modbus
from hapticframe.devices._emulator import DeviceModel, EmulatedTransport, PtyEmulator
from hapticframe.devices._faults import (
    BYTE_FAULT_KINDS,
    FaultEvent,
    FaultKind,
    FaultKinds,
    FaultParam,
    FaultSchedule,
    FaultSetting,
    FaultValue,
    InjectedFault,
    fault_setting,
)
from hapticframe.devices._framing import FixedFrameParser, LineFramer, ParserStats
from hapticframe.devices._health import DeviceHealth
from hapticframe.devices._lifecycle import DeviceError, DeviceLifecycle, LifecycleState
from hapticframe.devices._port import (
    DevicePort,
    EmulatedPort,
    LinkPort,
    PacedPort,
    SerialPort,
    port_for,
)
from hapticframe.devices._transport import (
    Backoff,
    ByteTransport,
    SerialTransport,
    TransportError,
    open_transport,
)

__all__ = [
    "BYTE_FAULT_KINDS",
    "Backoff",
    "ByteTransport",
    "Clock",
    "ClockSync",
    "DeviceError",
    "DeviceHealth",
    "DeviceLifecycle",
    "DeviceModel",
    "DevicePort",
    "EmulatedPort",
    "EmulatedTransport",
    "FakeClock",
    "FaultEvent",
    "FaultKind",
    "FaultKinds",
    "FaultParam",
    "FaultSchedule",
    "FaultSetting",
    "FaultValue",
    "FixedFrameParser",
    "InjectedFault",
    "LifecycleState",
    "LineFramer",
    "LinkPort",
    "MonotonicClock",
    "PacedPort",
    "ParserStats",
    "PtyEmulator",
    "SerialPort",
    "SerialTransport",
    "TransportError",
    "append_crc16",
    "check_crc16",
    "crc16_modbus",
    "fault_setting",
    "open_transport",
    "port_for",
]
