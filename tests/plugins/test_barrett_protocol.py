"""Known answers for the Barrett puck protocol (notes section 4: manual D1001 7.3-7.5 and
libbarrett's puck.h, puck_group.h, puck.cpp, motor_puck-inl.h, property_list.cpp, hand.h)."""

from __future__ import annotations

import pytest

from hapticframe_barrett import (
    COMMON_TABLE,
    Cmd,
    Group,
    Mode,
    ProtocolError,
    Stat,
    UnsupportedFirmware,
    decode_position,
    decode_property_reply,
    encode_get,
    encode_position,
    encode_set,
    group_id,
    node_id,
    parse_id,
    property_table,
)
from hapticframe_barrett._protocol import FROM_MASK, GROUP_BIT, TO_MASK


def test_identifier_layout_and_masks():
    assert (GROUP_BIT, FROM_MASK, TO_MASK) == (0x400, 0x3E0, 0x41F)
    # Verified replies in the notes: VERS from puck 1 to group 6, a position from puck 1.
    assert group_id(1, Group.PROPERTY) == 0x426
    assert group_id(1, Group.POSITION) == 0x423
    assert node_id(0, 11) == 0x00B
    assert group_id(0, Group.HAND) == 0x405
    assert group_id(0, Group.WAM) == 0x404
    # The safety puck's broadcast id that libbarrett discards: 1344 = safety (10) -> group 0.
    assert parse_id(1344) == (True, 10, 0)
    assert parse_id(0x426) == (True, 1, 6)
    assert parse_id(node_id(0, 14)) == (False, 0, 14)
    for frm in range(32):
        for to in range(32):
            assert parse_id(node_id(frm, to)) == (False, frm, to)
            assert parse_id(group_id(frm, to)) == (True, frm, to)
    with pytest.raises(ValueError):
        node_id(32, 1)
    with pytest.raises(ProtocolError):
        parse_id(0x800)


def test_get_and_set_payloads():
    assert encode_get(5) == b"\x05"
    # SET STAT (5) = READY (2): [0x80 + 5, 0, 2, 0, 0, 0], as libbarrett sends it.
    assert encode_set(5, 2) == bytes([0x85, 0x00, 0x02, 0x00, 0x00, 0x00])
    # SET CMD (29) = CLOSE (18); M (58) = 100000 = 0x000186A0 little-endian.
    assert encode_set(29, Cmd.CLOSE) == bytes([0x9D, 0, 18, 0, 0, 0])
    assert encode_set(58, 100_000) == bytes([0xBA, 0, 0xA0, 0x86, 0x01, 0x00])
    assert encode_set(58, -1) == bytes([0xBA, 0, 0xFF, 0xFF, 0xFF, 0xFF])
    assert encode_set(8, 3, length=4) == bytes([0x88, 0, 3, 0])
    with pytest.raises(ValueError):
        encode_get(0x80)
    with pytest.raises(ValueError):
        encode_set(8, 70_000, length=4)


def test_property_reply_decode_sign_extends():
    reply = decode_property_reply(bytes([0x80, 0, 160, 0, 0, 0]))
    assert (reply.prop, reply.value) == (0, 160)
    assert decode_property_reply(bytes([0x88, 0, 0xFF, 0xFF])).value == -1  # 4 bytes
    assert decode_property_reply(bytes([0xB0, 0, 0xFE, 0xFF, 0xFF, 0xFF])).value == -2
    assert decode_property_reply(bytes([0xB0, 0, 0xFF, 0xFF, 0xFF, 0x7F])).value == 2**31 - 1
    for value in (0, 1, -1, 12345, -98765, 2**31 - 1, -(2**31)):
        assert decode_property_reply(encode_set(58, value)).value == value
    with pytest.raises(ProtocolError, match="bit 7"):
        decode_property_reply(bytes([0x08, 0, 1, 0]))
    with pytest.raises(ProtocolError, match="byte 1"):
        decode_property_reply(bytes([0x88, 1, 1, 0]))
    with pytest.raises(ProtocolError):
        decode_property_reply(bytes([0x88, 0]))


def test_position_replies_22_bit_big_endian():
    cases = {
        0: b"\x00\x00\x00",
        1: b"\x00\x00\x01",
        -1: b"\x3f\xff\xff",
        2**21 - 1: b"\x1f\xff\xff",
        -(2**21): b"\x20\x00\x00",
        0x012345: b"\x01\x23\x45",
    }
    for counts, wire in cases.items():
        assert encode_position(counts) == wire
        assert decode_position(wire) == (counts, None)
    # Six bytes with a secondary encoder (the hand's fingers).
    assert decode_position(b"\x00\x10\x00\x3f\xff\xfe") == (4096, -2)
    assert encode_position(4096, -2) == b"\x00\x10\x00\x3f\xff\xfe"
    # The counter wraps at +-2**21.
    assert decode_position(encode_position(2**21)) == (-(2**21), None)
    with pytest.raises(ProtocolError):
        decode_position(b"\x40\x00\x00")  # the top two bits are always 0
    with pytest.raises(ProtocolError):
        decode_position(b"\x00\x00\x00\x00")


def test_property_tables_by_firmware_version():
    common = {"VERS": 0, "ROLE": 1, "SN": 2, "ID": 3, "ERROR": 4, "STAT": 5}
    assert dict(COMMON_TABLE.numbers) == common
    table = property_table(100)
    expected = {"MODE": 8, "TEMP": 9, "CMD": 29, "SAVE": 30, "T": 42, "MT": 43, "V": 44,
                "MOV": 47, "P": 48, "E": 52, "OT": 54, "CT": 56, "M": 58, "CTS": 68,
                "PIDX": 70, "TSTOP": 78, "IPNM": 86, "HOLD": 94, **common}
    for name, number in expected.items():
        assert table[name] == number, name
    assert "JP" not in table and "TACT" not in table
    assert property_table(116)["V"] == 106 and property_table(119)["V"] == 44
    assert property_table(125)["JP"] == 96 and "JP" not in property_table(124)
    assert property_table(131)["HOLD"] == 94 and property_table(132)["HOLD"] == 77
    assert property_table(142)["TACT"] == 106 and "TACT" not in property_table(141)
    assert property_table(65)["M"] == 58
    assert table.name_of(48) == "P" and table.name_of(127) is None
    with pytest.raises(UnsupportedFirmware):
        property_table(64)  # 61-64 differ (M 96) and are not implemented
    with pytest.raises(UnsupportedFirmware):
        property_table(40)
    with pytest.raises(KeyError, match="VERS 100"):
        table["TACT"]
    # No two names share a number in any implemented version.
    for vers in range(65, 200):
        numbers = list(property_table(vers).numbers.values())
        assert len(numbers) == len(set(numbers)), vers


def test_enumerations_match_libbarrett():
    assert (Stat.RESET, Stat.READY) == (0, 2)
    assert [int(m) for m in Mode] == [0, 1, 2, 3, 4, 5]
    assert (Cmd.HI, Cmd.CLOSE, Cmd.OPEN) == (13, 18, 20)
    assert [int(g) for g in Group] == [0, 1, 2, 3, 4, 5, 6, 7]
