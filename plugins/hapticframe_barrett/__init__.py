"""Barrett pucks on CAN: the protocol, an emulator on python-can's ``virtual`` interface, and
the host-side helper the ``barrett-hand`` robot and the ``barrett-wam`` backend build on.

The package registers the ``barrett-hand`` and ``barrett-wam`` robots (:mod:`.plugin`).
python-can (``pip install 'hapticframe[hardware]'``) is imported by the emulator, the host
helper and the robots, not by the protocol module or the configs: their names are imported
from this package only when first used.

- :mod:`._protocol` (pure): identifiers, GET/SET payloads, property replies, 22-bit position
  replies, property tables selected by firmware ``VERS``.
- :class:`PuckBus` / :class:`EmulatedPuck`: pucks answering on a virtual channel, with the
  notes' section 4.5 faults from a seeded ``FaultSchedule``.
- :class:`PuckHost` / :class:`BarrettHandHost`: wake, identify, GET/SET with bounded waits
  counted in a ``DeviceHealth``, group position polls that report missing pucks, hand
  commands.
- :class:`CanPort` / :class:`PacedCanPort` / :class:`EmulatedCanPort`: the channel and clock
  a host is handed; the port decides how a wait lets time pass (real or emulated pucks).
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._protocol import (
    CAN_ERR_BUSOFF,
    CAN_ERR_PROT,
    CAN_ERR_RESTARTED,
    COMMON_TABLE,
    HAND_NODES,
    WAM_NODES,
    Cmd,
    Group,
    Mode,
    Node,
    PropertyReply,
    PropertyTable,
    ProtocolError,
    Stat,
    UnsupportedFirmware,
    decode_position,
    decode_property_reply,
    encode_get,
    encode_position,
    encode_property_reply,
    encode_set,
    group_id,
    node_id,
    parse_id,
    property_table,
)

__all__ = [
    "CAN_ERR_BUSOFF",
    "CAN_ERR_PROT",
    "CAN_ERR_RESTARTED",
    "COMMON_TABLE",
    "FAULT_KINDS",
    "HAND_NODES",
    "WAM_NODES",
    "BarrettError",
    "BarrettHandHost",
    "CanPort",
    "Cmd",
    "EmulatedCanPort",
    "EmulatedPuck",
    "Group",
    "MalformedReply",
    "Mode",
    "MoveResult",
    "Node",
    "PacedCanPort",
    "PositionPoll",
    "PropertyReply",
    "PropertyTable",
    "ProtocolError",
    "PuckBus",
    "PuckHost",
    "ReplyTimeout",
    "Stat",
    "UnsupportedFirmware",
    "WakeResult",
    "decode_position",
    "decode_property_reply",
    "encode_get",
    "encode_position",
    "encode_property_reply",
    "encode_set",
    "group_id",
    "hand_pucks",
    "node_id",
    "parse_id",
    "property_table",
    "wam_pucks",
]

_HOMES = {
    **dict.fromkeys(("CanPort", "EmulatedCanPort", "PacedCanPort"), "._bus"),
    **dict.fromkeys(("FAULT_KINDS", "EmulatedPuck", "PuckBus", "hand_pucks", "wam_pucks"),
                    "._emulator"),
    **dict.fromkeys(("BarrettError", "BarrettHandHost", "MalformedReply", "MoveResult",
                     "PositionPoll", "PuckHost", "ReplyTimeout", "WakeResult"), "._host"),
}

__getattr__, __dir__ = lazy_exports(__name__, _HOMES)
