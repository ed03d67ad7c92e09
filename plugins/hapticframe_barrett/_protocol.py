"""The Barrett puck protocol on CAN: identifiers, property payloads, position replies, and the
property tables selected by firmware version. Pure functions, no I/O.

Sources are the notes' section 4 (``shared/notes/hardware.md``): the WAM Arm User's Manual
D1001 sections 7.3-7.5 and libbarrett's ``puck.h``, ``puck_group.h``, ``puck.cpp``,
``motor_puck-inl.h``, ``property_list.cpp`` and ``hand.h``.

Identifiers are 11-bit standard ids laid out ``G FFFFF TTTTT``: ``G`` = 1 for a group
broadcast, ``F`` the sending node, ``T`` the destination node, or the group when ``G`` is set.

Property tables
---------------
Property numbers depend on the puck's firmware version (``VERS``). Implemented: the
motor-puck table for ``VERS >= 65`` (the WAM and BarrettHand pucks of the last two decades),
with the version-dependent rows the notes decoded from libbarrett (``V`` 106 for VERS 114-118,
``JP`` from 125, ``HOLD`` 94 up to 131 and 77 from 132, ``TACT`` from 142). ``VERS``, ``ROLE``,
``SN``, ``ID``, ``ERROR`` and ``STAT`` are 0-5 for every puck type and version, so they can be
asked first. Not implemented (``UnsupportedFirmware``): VERS 61-64 (known to differ, e.g. ``M``
96, not fully decoded) and VERS < 61 (an entirely different table). Unverified against hardware:
every number here is taken from the notes' reading of libbarrett; no puck has been queried.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from enum import IntEnum
from types import MappingProxyType

__all__ = [
    "CAN_ERR_BUSOFF",
    "CAN_ERR_PROT",
    "CAN_ERR_RESTARTED",
    "COMMON_TABLE",
    "HAND_NODES",
    "WAM_NODES",
    "FROM_MASK",
    "GROUP_BIT",
    "TO_MASK",
    "Cmd",
    "Group",
    "Mode",
    "Node",
    "PropertyReply",
    "PropertyTable",
    "ProtocolError",
    "Stat",
    "UnsupportedFirmware",
    "decode_position",
    "decode_property_reply",
    "encode_get",
    "encode_position",
    "encode_property_reply",
    "encode_set",
    "group_id",
    "node_id",
    "parse_id",
    "property_table",
]

#: SocketCAN error-frame class flags (``linux/can/error.h``), in an error frame's id.
CAN_ERR_PROT = 0x08
CAN_ERR_BUSOFF = 0x40
CAN_ERR_RESTARTED = 0x100

GROUP_BIT = 0x400
FROM_MASK = 0x3E0
TO_MASK = 0x41F  # libbarrett's mask: the group bit and the destination
_MAX_NODE = 31
_MAX_PROPERTY = 0x7F
POSITION_BITS = 22
_POSITION_MIN = -(1 << (POSITION_BITS - 1))
_POSITION_MAX = (1 << (POSITION_BITS - 1)) - 1


class ProtocolError(ValueError):
    """A frame that does not follow the puck protocol (malformed reply, bad identifier)."""


class UnsupportedFirmware(ProtocolError):
    """A firmware version whose property table is not implemented."""


class Node(IntEnum):
    """Node ids: the host, the WAM's seven pucks, the safety puck, the hand's four pucks."""

    HOST = 0
    WAM1 = 1
    WAM2 = 2
    WAM3 = 3
    WAM4 = 4
    WAM5 = 5
    WAM6 = 6
    WAM7 = 7
    SAFETY = 10
    F1 = 11
    F2 = 12
    F3 = 13
    SPREAD = 14


WAM_NODES: tuple[int, ...] = tuple(range(1, 8))
HAND_NODES: tuple[int, ...] = (11, 12, 13, 14)


class Group(IntEnum):
    """Broadcast groups (host to pucks) and feedback groups (pucks to host)."""

    ALL = 0  # every puck but the safety puck
    LOWER_TORQUE = 1  # pucks 1-4
    UPPER_TORQUE = 2  # pucks 5-7
    POSITION = 3  # feedback: motor positions
    WAM = 4
    HAND = 5
    PROPERTY = 6  # feedback: property replies
    SECONDARY_POSITION = 7  # feedback: secondary encoder


class Stat(IntEnum):
    """Values of the ``STAT`` property."""

    RESET = 0
    READY = 2


class Mode(IntEnum):
    """Values of the ``MODE`` property (``motor_puck.h``)."""

    IDLE = 0
    DUTY = 1
    TORQUE = 2
    PID = 3
    VELOCITY = 4
    TRAPEZOIDAL = 5


class Cmd(IntEnum):
    """BarrettHand ``CMD`` values (``hand.h``)."""

    HI = 13  # home / initialise
    CLOSE = 18
    OPEN = 20


# ---------------------------------------------------------------------------------- identifiers


def _check_node(node: int, what: str) -> None:
    if not 0 <= node <= _MAX_NODE:
        raise ValueError(f"{what} {node} is not a node id (0-{_MAX_NODE})")


def node_id(from_node: int, to_node: int) -> int:
    """The identifier of a frame from one node to another."""
    _check_node(from_node, "sender")
    _check_node(to_node, "destination")
    return (from_node << 5) | to_node


def group_id(from_node: int, group: int) -> int:
    """The identifier of a frame from a node to a group."""
    _check_node(from_node, "sender")
    _check_node(group, "group")
    return GROUP_BIT | (from_node << 5) | group


def parse_id(arbitration_id: int) -> tuple[bool, int, int]:
    """``(is_group, from_node, to)`` of an identifier (``to`` is a node or a group)."""
    if not 0 <= arbitration_id <= 0x7FF:
        raise ProtocolError(f"identifier {arbitration_id:#x} is not an 11-bit id")
    return (
        bool(arbitration_id & GROUP_BIT),
        (arbitration_id & FROM_MASK) >> 5,
        arbitration_id & 0x1F,
    )


# ------------------------------------------------------------------------------------ payloads


def _check_property(prop: int) -> None:
    if not 0 <= prop <= _MAX_PROPERTY:
        raise ValueError(f"property {prop} is out of range (0-{_MAX_PROPERTY})")


def encode_get(prop: int) -> bytes:
    """The payload of a GET: one byte, the property number (bit 7 clear)."""
    _check_property(prop)
    return bytes([prop])


def encode_set(prop: int, value: int, length: int = 6) -> bytes:
    """The payload of a SET (and of a property reply): ``[0x80 | p, 0, value LE...]``.

    ``length`` is 6 (a 32-bit value, what libbarrett always sends) or 4 (16 bits).
    """
    _check_property(prop)
    if length not in (4, 6):
        raise ValueError("a property payload is 4 or 6 bytes")
    bits = 8 * (length - 2)
    if not -(1 << (bits - 1)) <= value < (1 << bits):
        raise ValueError(f"value {value} does not fit in {bits} bits")
    return bytes([0x80 | prop, 0]) + (value & ((1 << bits) - 1)).to_bytes(length - 2, "little")


encode_property_reply = encode_set


@dataclass(frozen=True)
class PropertyReply:
    """A decoded property reply."""

    prop: int
    value: int


def decode_property_reply(data: bytes | bytearray) -> PropertyReply:
    """Decode a property reply as libbarrett does: bit 7 set, byte 1 zero, then the value,
    little-endian and sign-extended from bytes 2 to the end.

    Raises
    ------
    ProtocolError
        For a payload that is too short, has bit 7 clear, or a non-zero byte 1.
    """
    data = bytes(data)
    if len(data) < 3 or len(data) > 8:
        raise ProtocolError(f"property reply of {len(data)} bytes")
    if not data[0] & 0x80:
        raise ProtocolError(f"property reply with bit 7 clear ({data[0]:#04x})")
    if data[1] != 0:
        raise ProtocolError(f"property reply with byte 1 = {data[1]:#04x}")
    return PropertyReply(data[0] & 0x7F, int.from_bytes(data[2:], "little", signed=True))


def encode_position(counts: int, secondary: int | None = None) -> bytes:
    """A position reply: 22-bit two's complement, big-endian in 3 bytes (6 with a secondary
    encoder). Counts outside ±2**21 wrap, as the puck's counter does."""
    out = (counts & 0x3FFFFF).to_bytes(3, "big")
    if secondary is not None:
        out += (secondary & 0x3FFFFF).to_bytes(3, "big")
    return out


def _decode22(data: bytes) -> int:
    if data[0] & 0xC0:
        raise ProtocolError(f"position reply with the top bits set ({data[0]:#04x})")
    raw = int.from_bytes(data, "big")
    return raw - (1 << POSITION_BITS) if raw & (1 << (POSITION_BITS - 1)) else raw


def decode_position(data: bytes | bytearray) -> tuple[int, int | None]:
    """``(primary, secondary or None)`` counts of a 3- or 6-byte position reply.

    Raises
    ------
    ProtocolError
        For another length or a first byte with its top two bits set.
    """
    data = bytes(data)
    if len(data) == 3:
        return _decode22(data), None
    if len(data) == 6:
        return _decode22(data[:3]), _decode22(data[3:])
    raise ProtocolError(f"position reply of {len(data)} bytes")


# ------------------------------------------------------------------------------ property tables

#: Properties at the same number on every puck type and firmware.
_COMMON = {"VERS": 0, "ROLE": 1, "SN": 2, "ID": 3, "ERROR": 4, "STAT": 5}

#: Motor pucks, VERS >= 65 (the rows that do not move with the version).
_MOTOR_65 = {
    **_COMMON,
    "MODE": 8,
    "TEMP": 9,
    "CMD": 29,
    "SAVE": 30,
    "T": 42,
    "MT": 43,
    "V": 44,
    "MOV": 47,
    "P": 48,
    "E": 52,
    "OT": 54,
    "CT": 56,
    "M": 58,
    "CTS": 68,
    "PIDX": 70,
    "TSTOP": 78,
    "IPNM": 86,
}

MIN_SUPPORTED_VERS = 65


@dataclass(frozen=True)
class PropertyTable:
    """Property numbers of one firmware version.

    Attributes
    ----------
    vers : int or None
        The firmware version the table was selected for (None: only the common rows).
    numbers : mapping of str to int
        Property name to number.
    """

    vers: int | None
    numbers: Mapping[str, int]

    def __getitem__(self, name: str) -> int:
        try:
            return self.numbers[name]
        except KeyError:
            raise KeyError(
                f"property {name!r} is not in the table for firmware VERS {self.vers}"
            ) from None

    def __contains__(self, name: object) -> bool:
        return name in self.numbers

    def name_of(self, number: int) -> str | None:
        """The name of a property number, or None."""
        for name, value in self.numbers.items():
            if value == number:
                return name
        return None


#: What may be asked before VERS is known (waking, identifying).
COMMON_TABLE = PropertyTable(None, MappingProxyType(dict(_COMMON)))


def property_table(vers: int) -> PropertyTable:
    """The motor-puck property table for firmware ``vers``.

    Raises
    ------
    UnsupportedFirmware
        For VERS < 65 (tables not implemented; see the module's docstring).
    """
    if vers < MIN_SUPPORTED_VERS:
        raise UnsupportedFirmware(
            f"puck firmware VERS {vers} is not supported (property tables are implemented for "
            f"VERS >= {MIN_SUPPORTED_VERS})"
        )
    numbers = dict(_MOTOR_65)
    if 114 <= vers <= 118:
        numbers["V"] = 106
    if vers >= 125:
        numbers["JP"] = 96
    numbers["HOLD"] = 94 if vers <= 131 else 77
    if vers >= 142:
        numbers["TACT"] = 106
    return PropertyTable(vers, MappingProxyType(numbers))
