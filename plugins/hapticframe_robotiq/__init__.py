"""Robotiq FT 300 wrist force/torque sensor: wire protocol, driver and emulator.

Registers the sensor ``robotiq-ft300``. Public beyond the sensor: the protocol core (pure
Modbus RTU and stream-frame encoding and decoding), the emulated device
(:class:`Ft300Model`, a :class:`hapticframe.devices.DeviceModel` with the FT 300's fault
matrix) and its physics. Importing this package is cheap; the implementation modules load
on first attribute access.
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import EMULATED_PORT, Ft300Config

__all__ = [
    "EMULATED_PORT",
    "FAULT_KINDS",
    "STANDARD_FAULTS",
    "DeviceInfo",
    "Ft300Config",
    "Ft300Model",
    "Ft300Physics",
    "Ft300Sensor",
    "ModbusException",
    "ProtocolError",
    "SentFrame",
    "decode_firmware",
    "decode_serial_number",
    "decode_stream_frame",
    "encode_stream_frame",
    "parse_read_reply",
    "parse_write_reply",
    "quantise",
    "read_request",
    "standard_schedule",
    "wrench_from_truth",
    "write_request",
]

_LAZY = {
    "Ft300Sensor": "._sensor",
    "FAULT_KINDS": "._emulator",
    "STANDARD_FAULTS": "._emulator",
    "Ft300Model": "._emulator",
    "Ft300Physics": "._emulator",
    "SentFrame": "._emulator",
    "standard_schedule": "._emulator",
    "wrench_from_truth": "._emulator",
    "DeviceInfo": "._protocol",
    "ModbusException": "._protocol",
    "ProtocolError": "._protocol",
    "decode_firmware": "._protocol",
    "decode_serial_number": "._protocol",
    "decode_stream_frame": "._protocol",
    "encode_stream_frame": "._protocol",
    "parse_read_reply": "._protocol",
    "parse_write_reply": "._protocol",
    "quantise": "._protocol",
    "read_request": "._protocol",
    "write_request": "._protocol",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
