"""Dynamixel Protocol 2.0: packets, the XM430-W350 control table, an emulated bus, and the
``dynamixel`` robot.

:mod:`.plugin` registers the robot (:class:`DynamixelRobot`, a Cartesian gantry or a planar
two-link arm on a vertical axis, driven by ``dynamixel_sdk``, imported only when the robot is
asked for; its transaction layer is :mod:`._bus`). :mod:`._kinematics` is pure numpy: the
:class:`Gantry` and :class:`TwoLink` mechanisms over the arm's analytic kinematics
(:func:`arm_forward`, :func:`arm_inverse`, :func:`arm_jacobian`) and :func:`line_problem`,
which checks a whole straight line against the reach and the joint limits.
:mod:`._protocol` is pure (CRC-16/BUYPASS, byte stuffing, instruction and status packets,
an incremental parser that resynchronises as ``dynamixel_sdk`` does);
:mod:`._control_table` holds the XM430-W350 table (model number 1020) and unit conversions;
:class:`DynamixelBus` is a :class:`hapticframe.devices.DeviceModel` of several XM430 servos
with first-order dynamics, external loads, overload and the fault matrix of the hardware
notes (§3.4): put it behind a :class:`~hapticframe.devices.PtyEmulator` and the unmodified
``dynamixel_sdk.PortHandler`` opens it by name (at 1 000 000 baud: the SDK accepts only a
fixed list of rates, and a pty does not enforce any).
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import AxisConfig, DynamixelRobotConfig, GantryConfig, JointConfig, TwoLinkConfig
from ._control_table import (
    CURRENT_UNIT_A,
    EEPROM_END,
    PULSES_PER_REV,
    VELOCITY_UNIT_RPM,
    XM430_W350,
    XM430_W350_MODEL_NUMBER,
    ControlTable,
    Field,
    amps_to_current,
    current_to_amps,
    pulses_to_rad,
    rad_to_pulses,
    rpm_to_velocity,
    to_signed,
    velocity_to_rpm,
)
from ._emulator import (
    FAULT_KINDS,
    HW_ERROR_ELECTRICAL_SHOCK,
    HW_ERROR_ENCODER,
    HW_ERROR_INPUT_VOLTAGE,
    HW_ERROR_OVERHEATING,
    HW_ERROR_OVERLOAD,
    DynamixelBus,
    EmulatedServo,
    SentStatus,
)
from ._kinematics import (
    Axis,
    Gantry,
    Joint,
    TwoLink,
    arm_forward,
    arm_inverse,
    arm_jacobian,
    line_problem,
    segment_distances,
)
from ._protocol import (
    BROADCAST_ID,
    ERR_ACCESS,
    ERR_ALERT,
    ERR_CRC,
    ERR_DATA_LENGTH,
    ERR_DATA_LIMIT,
    ERR_DATA_RANGE,
    ERR_INSTRUCTION,
    ERR_RESULT_FAIL,
    ERROR_NAMES,
    INST_BULK_READ,
    INST_PING,
    INST_READ,
    INST_REBOOT,
    INST_STATUS,
    INST_SYNC_READ,
    INST_SYNC_WRITE,
    INST_WRITE,
    InstructionPacket,
    PacketParser,
    ParserCounters,
    ProtocolError,
    StatusPacket,
    bulk_read_packet,
    crc16_dxl,
    decode_instruction,
    decode_status,
    encode_instruction,
    encode_status,
    error_name,
    ping_packet,
    read_packet,
    reboot_packet,
    stuff,
    sync_read_packet,
    sync_write_packet,
    unstuff,
    write_packet,
)

__all__ = [
    "Axis",
    "AxisConfig",
    "DynamixelRobot",
    "DynamixelRobotConfig",
    "Gantry",
    "GantryConfig",
    "Joint",
    "JointConfig",
    "TwoLink",
    "TwoLinkConfig",
    "arm_forward",
    "arm_inverse",
    "arm_jacobian",
    "line_problem",
    "segment_distances",
    "BROADCAST_ID",
    "CURRENT_UNIT_A",
    "EEPROM_END",
    "ERROR_NAMES",
    "ERR_ACCESS",
    "ERR_ALERT",
    "ERR_CRC",
    "ERR_DATA_LENGTH",
    "ERR_DATA_LIMIT",
    "ERR_DATA_RANGE",
    "ERR_INSTRUCTION",
    "ERR_RESULT_FAIL",
    "FAULT_KINDS",
    "HW_ERROR_ELECTRICAL_SHOCK",
    "HW_ERROR_ENCODER",
    "HW_ERROR_INPUT_VOLTAGE",
    "HW_ERROR_OVERHEATING",
    "HW_ERROR_OVERLOAD",
    "INST_PING",
    "INST_READ",
    "INST_REBOOT",
    "INST_STATUS",
    "INST_SYNC_READ",
    "INST_SYNC_WRITE",
    "INST_BULK_READ",
    "INST_WRITE",
    "PULSES_PER_REV",
    "VELOCITY_UNIT_RPM",
    "XM430_W350",
    "XM430_W350_MODEL_NUMBER",
    "ControlTable",
    "DynamixelBus",
    "EmulatedServo",
    "Field",
    "InstructionPacket",
    "PacketParser",
    "ParserCounters",
    "ProtocolError",
    "SentStatus",
    "StatusPacket",
    "amps_to_current",
    "crc16_dxl",
    "current_to_amps",
    "decode_instruction",
    "decode_status",
    "encode_instruction",
    "encode_status",
    "error_name",
    "ping_packet",
    "pulses_to_rad",
    "rad_to_pulses",
    "read_packet",
    "reboot_packet",
    "rpm_to_velocity",
    "stuff",
    "sync_read_packet",
    "bulk_read_packet",
    "sync_write_packet",
    "to_signed",
    "unstuff",
    "velocity_to_rpm",
    "write_packet",
]

#: Public names that load on first use, and their modules (the robot imports dynamixel_sdk:
#: only when asked for).
_LAZY = {
    "DynamixelRobot": "._robot",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
