"""The XM430-W350 control table (model number 1020) and its unit conversions.

Addresses from ``dynamixel_easy_sdk/control_table/xm430_w350.model`` (in the dynamixel-sdk
4.1.0 wheel), units and defaults from the ROBOTIS e-manual's X-series table. The EEPROM area
(addresses below 64) is write-protected while Torque Enable is 1.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

__all__ = [
    "CURRENT_UNIT_A",
    "EEPROM_END",
    "PULSES_PER_REV",
    "VELOCITY_UNIT_RPM",
    "XM430_W350",
    "XM430_W350_MODEL_NUMBER",
    "ControlTable",
    "Field",
    "amps_to_current",
    "encode",
    "current_to_amps",
    "pulses_to_rad",
    "rad_to_pulses",
    "rpm_to_velocity",
    "to_signed",
    "velocity_to_rpm",
]

XM430_W350_MODEL_NUMBER = 1020
#: Encoder pulses per revolution (0.088° per pulse).
PULSES_PER_REV = 4096
#: One unit of Present/Goal Current, in amperes (2.69 mA).
CURRENT_UNIT_A = 2.69e-3
#: One unit of Present/Goal Velocity, in rev/min.
VELOCITY_UNIT_RPM = 0.229
#: Addresses below this are EEPROM.
EEPROM_END = 64


@dataclass(frozen=True)
class Field:
    """One control-table item.

    ``area`` is ``"EEPROM"`` or ``"RAM"``; ``access`` is ``"R"`` or ``"RW"``; ``signed``
    says how to read the little-endian bytes; ``default`` is the power-on value.
    """

    address: int
    size: int
    name: str
    unit: str
    area: str
    access: str
    signed: bool = False
    default: int = 0

    @property
    def writable(self) -> bool:
        return self.access == "RW"

    @property
    def end(self) -> int:
        return self.address + self.size


@dataclass(frozen=True)
class ControlTable:
    """A servo model's control table: fields by name and address."""

    model_number: int
    model_name: str
    fields: tuple[Field, ...]

    def __post_init__(self) -> None:
        previous_end = 0
        for item in self.fields:
            if item.address < previous_end:
                raise ValueError(f"{self.model_name}: {item.name} overlaps the previous item")
            expected = "EEPROM" if item.address < EEPROM_END else "RAM"
            if item.area != expected:
                raise ValueError(f"{self.model_name}: {item.name} is in {expected}")
            previous_end = item.end

    @property
    def by_name(self) -> Mapping[str, Field]:
        return MappingProxyType({item.name: item for item in self.fields})

    def __getitem__(self, name: str) -> Field:
        for item in self.fields:
            if item.name == name:
                return item
        raise KeyError(f"{self.model_name} has no item {name!r}")

    def at(self, address: int) -> Field | None:
        """The item that holds ``address`` (None in a gap)."""
        for item in self.fields:
            if item.address <= address < item.end:
                return item
        return None

    @property
    def size(self) -> int:
        """Bytes from address 0 to the end of the last item."""
        return max(item.end for item in self.fields)

    def defaults(self) -> bytearray:
        """The power-on memory image (gaps are zero)."""
        memory = bytearray(self.size)
        for item in self.fields:
            memory[item.address : item.end] = encode(item, item.default)
        return memory


def encode(item: Field, value: int) -> bytes:
    """``value`` as ``item``'s little-endian bytes (negative values as two's complement)."""
    return int(value).to_bytes(item.size, "little", signed=item.signed and value < 0)


def to_signed(value: int, size: int) -> int:
    """An unsigned reading (as ``read2ByteTxRx`` returns it) as a signed integer."""
    bits = 8 * size
    value &= (1 << bits) - 1
    return value - (1 << bits) if value >> (bits - 1) else value


def _f(address: int, size: int, name: str, unit: str, access: str = "RW", *,
       signed: bool = False, default: int = 0) -> Field:
    area = "EEPROM" if address < EEPROM_END else "RAM"
    return Field(address, size, name, unit, area, access, signed, default)


#: The XM430-W350 control table (Protocol 2.0). Baud Rate defaults to index 3 (1 Mbit/s,
#: what the SDK and a pty are used at; the factory default is 1 = 57 600).
XM430_W350 = ControlTable(
    XM430_W350_MODEL_NUMBER,
    "XM430-W350",
    (
        _f(0, 2, "Model Number", "", "R", default=XM430_W350_MODEL_NUMBER),
        _f(2, 4, "Model Information", "", "R"),
        _f(6, 1, "Firmware Version", "", "R", default=48),
        _f(7, 1, "ID", "", default=1),
        _f(8, 1, "Baud Rate", "index", default=3),
        _f(9, 1, "Return Delay Time", "2 us", default=250),
        _f(10, 1, "Drive Mode", "", default=0),
        _f(11, 1, "Operating Mode", "", default=3),
        _f(12, 1, "Secondary ID", "", default=255),
        _f(13, 1, "Protocol Type", "", default=2),
        _f(20, 4, "Homing Offset", "pulse", signed=True),
        _f(24, 4, "Moving Threshold", "0.229 rev/min", default=10),
        _f(31, 1, "Temperature Limit", "degC", default=80),
        _f(32, 2, "Max Voltage Limit", "0.1 V", default=160),
        _f(34, 2, "Min Voltage Limit", "0.1 V", default=95),
        _f(36, 2, "PWM Limit", "0.113 %", default=885),
        _f(38, 2, "Current Limit", "2.69 mA", default=1193),
        _f(44, 4, "Velocity Limit", "0.229 rev/min", default=200),
        _f(48, 4, "Max Position Limit", "pulse", default=4095),
        _f(52, 4, "Min Position Limit", "pulse", default=0),
        _f(63, 1, "Shutdown", "bits", default=52),
        _f(64, 1, "Torque Enable", ""),
        _f(65, 1, "LED", ""),
        _f(68, 1, "Status Return Level", "", default=2),
        _f(69, 1, "Registered Instruction", "", "R"),
        _f(70, 1, "Hardware Error Status", "bits", "R"),
        _f(76, 2, "Velocity I Gain", "", default=1920),
        _f(78, 2, "Velocity P Gain", "", default=100),
        _f(80, 2, "Position D Gain", ""),
        _f(82, 2, "Position I Gain", ""),
        _f(84, 2, "Position P Gain", "", default=800),
        _f(88, 2, "Feedforward 2nd Gain", ""),
        _f(90, 2, "Feedforward 1st Gain", ""),
        _f(98, 1, "Bus Watchdog", "20 ms"),
        _f(100, 2, "Goal PWM", "0.113 %", signed=True, default=885),
        _f(102, 2, "Goal Current", "2.69 mA", signed=True, default=1193),
        _f(104, 4, "Goal Velocity", "0.229 rev/min", signed=True),
        _f(108, 4, "Profile Acceleration", ""),
        _f(112, 4, "Profile Velocity", ""),
        _f(116, 4, "Goal Position", "pulse", signed=True),
        _f(120, 2, "Realtime Tick", "ms", "R"),
        _f(122, 1, "Moving", "", "R"),
        _f(123, 1, "Moving Status", "bits", "R"),
        _f(124, 2, "Present PWM", "0.113 %", "R", signed=True),
        _f(126, 2, "Present Current", "2.69 mA", "R", signed=True),
        _f(128, 4, "Present Velocity", "0.229 rev/min", "R", signed=True),
        _f(132, 4, "Present Position", "pulse", "R", signed=True),
        _f(136, 4, "Velocity Trajectory", "0.229 rev/min", "R", signed=True),
        _f(140, 4, "Position Trajectory", "pulse", "R", signed=True),
        _f(144, 2, "Present Input Voltage", "0.1 V", "R", default=120),
        _f(146, 1, "Present Temperature", "degC", "R", default=36),
    ),
)


def pulses_to_rad(pulses: float) -> float:
    """Encoder pulses → radians (4096 per revolution)."""
    return float(pulses) * 2.0 * math.pi / PULSES_PER_REV


def rad_to_pulses(rad: float) -> int:
    """Radians → the nearest encoder pulse."""
    return round(float(rad) * PULSES_PER_REV / (2.0 * math.pi))


def current_to_amps(raw: int) -> float:
    """A Present/Goal Current reading (signed or as the SDK's unsigned 16 bits) → amperes."""
    return to_signed(int(raw), 2) * CURRENT_UNIT_A


def amps_to_current(amps: float) -> int:
    """Amperes → current units (signed, 2.69 mA), clipped to int16."""
    return max(-32768, min(32767, round(float(amps) / CURRENT_UNIT_A)))


def velocity_to_rpm(raw: int) -> float:
    """A Present/Goal Velocity reading (signed or unsigned 32 bits) → rev/min."""
    return to_signed(int(raw), 4) * VELOCITY_UNIT_RPM


def rpm_to_velocity(rpm: float) -> int:
    """rev/min → velocity units (0.229 rev/min)."""
    return round(float(rpm) / VELOCITY_UNIT_RPM)
