"""Bosch BNO055 IMU: UART protocol, polled driver with bounded recovery, and its emulator.

Registers the sensor ``bno055``. Importing this package is cheap: the protocol core, the
driver and the emulator load on first attribute access.
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import EMULATED_PORT, Bno055SensorConfig

__all__ = [
    "EMULATED_PORT",
    "MODEL_FAULT_KINDS",
    "Bno055Health",
    "Bno055Model",
    "Bno055ProtocolError",
    "Bno055Sensor",
    "Bno055SensorConfig",
    "DataBlock",
    "OperationMode",
    "Register",
    "Reply",
    "ServedRead",
    "Status",
    "decode_data_block",
    "encode_data_block",
    "encode_read",
    "encode_write",
    "parse_reply",
    "standard_faults",
    "status_name",
]

_LAZY = {
    "MODEL_FAULT_KINDS": "._emulator",
    "Bno055Model": "._emulator",
    "ServedRead": "._emulator",
    "standard_faults": "._emulator",
    "Bno055Health": "._sensor",
    "Bno055ProtocolError": "._sensor",
    "Bno055Sensor": "._sensor",
    "DataBlock": "._protocol",
    "OperationMode": "._protocol",
    "Register": "._protocol",
    "Reply": "._protocol",
    "Status": "._protocol",
    "decode_data_block": "._protocol",
    "encode_data_block": "._protocol",
    "encode_read": "._protocol",
    "encode_write": "._protocol",
    "parse_reply": "._protocol",
    "status_name": "._protocol",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
